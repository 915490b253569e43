"""Hokuyo SCIP 2.0 codec (spec C-42-03320B), pure: no I/O, no clock.

Used by the lidar ingest (decode) and by the simulated URG-04LX (encode), so both sides agree
byte for byte. A reply is::

    echo LF  status(2) sum LF  [data-line(<=64) sum LF]...  LF

The sum char of a line is ``(sum(bytes) & 0x3F) + 0x30``. Values are 2, 3 or 4 chars of 6-bit
groups, most significant first, each + 0x30; a value may straddle two data lines, so data lines
are stripped of their sum chars and concatenated before decoding. URG-04LX PP/VV/II lines
(``NAME:value;sum``) compute the sum without the ``;``; newer models include it: both accepted.

Decoding of scan data is vectorised with numpy (one pass over the whole reply, no per-value
Python work). Every malformed input raises a subclass of :class:`ScipError`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

LF = 0x0A
MAX_LINE = 64  # data chars per line, before the sum char

STATUS_TEXT: dict[str, str] = {
    "00": "ok",
    "99": "scan data",
    "01": "start step has non-numeric value",
    "02": "end step has non-numeric value / already on",
    "03": "cluster count has non-numeric value",
    "04": "end step out of range",
    "05": "end step smaller than start step",
    "06": "scan interval has non-numeric value",
    "07": "number of scans has non-numeric value",
    "0A": "command error",
    "0B": "command error",
    "0C": "command error (too long)",
    "0D": "command error",
    "0E": "undefined command",
    "0F": "command error",
    "0G": "command error",
    "0H": "command error",
    "0I": "command error",
}


def status_text(status: str) -> str:
    if status in STATUS_TEXT:
        return STATUS_TEXT[status]
    if status.isdigit() and 50 <= int(status) <= 97:
        return "hardware trouble"
    return "unknown status"


# --- errors ----------------------------------------------------------------------------------
class ScipError(Exception):
    """Any malformed or unexpected SCIP input; the message is one line."""


class SumError(ScipError):
    """A line's sum char does not match its bytes."""


class EchoError(ScipError):
    """The reply does not echo the request it should answer."""


class StatusError(ScipError):
    """The device answered with a status other than the expected ones."""

    def __init__(self, command: str, status: str) -> None:
        self.status = status
        super().__init__(f"{command}: status {status!r} ({status_text(status)})")


class FormatError(ScipError):
    """Lines, lengths or characters not allowed by SCIP 2.0."""


# --- sum and values --------------------------------------------------------------------------
def sum_char(line: bytes) -> int:
    return (sum(line) & 0x3F) + 0x30


def with_sum(line: bytes) -> bytes:
    return line + bytes((sum_char(line),))


def check_line(line: bytes, what: str = "line") -> bytes:
    """A line with its sum char checked and removed."""
    if len(line) < 2:
        raise FormatError(f"{what} too short: {line!r}")
    body = line[:-1]
    if sum_char(body) != line[-1]:
        raise SumError(f"bad sum in {what} {line!r}: want {chr(sum_char(body))!r}")
    return body


def encode_value(value: int, nchars: int) -> bytes:
    if not 0 <= value < 1 << (6 * nchars):
        raise ValueError(f"{value} does not fit in {nchars} SCIP chars")
    return bytes(((value >> (6 * (nchars - 1 - i))) & 0x3F) + 0x30 for i in range(nchars))


def encode_values(values: npt.ArrayLike, nchars: int) -> bytes:
    """Vectorised encoding of non-negative ints (too-large values are an error)."""
    v = np.asarray(values, dtype=np.int64)
    if v.size and (v.min() < 0 or v.max() >= 1 << (6 * nchars)):
        raise ValueError(f"values out of range for {nchars} SCIP chars")
    shifts = 6 * np.arange(nchars - 1, -1, -1, dtype=np.int64)
    chars = ((v[:, None] >> shifts) & 0x3F) + 0x30
    return chars.astype(np.uint8).tobytes()


def decode_value(chars: bytes) -> int:
    out = 0
    for c in chars:
        if not 0x30 <= c < 0x70:
            raise FormatError(f"char {c!r} outside the SCIP value range in {chars!r}")
        out = (out << 6) | (c - 0x30)
    return out


def decode_values(data: bytes | npt.NDArray[np.uint8], nchars: int) -> npt.NDArray[np.int64]:
    """Vectorised decoding of concatenated (sum-stripped) data chars."""
    a = np.frombuffer(data, dtype=np.uint8) if isinstance(data, bytes) else data
    if a.size % nchars:
        raise FormatError(f"{a.size} data chars is not a multiple of {nchars}")
    if a.size and (a.min() < 0x30 or a.max() > 0x6F):
        raise FormatError("char outside the SCIP value range in data")
    g = a.reshape(-1, nchars).astype(np.int64)
    out = g[:, 0] - 0x30
    for i in range(1, nchars):
        out <<= 6
        out += g[:, i] - 0x30
    return out


def split_data(values_chars: bytes) -> list[bytes]:
    """Concatenated data chars to data lines of <= 64 chars (sum chars added)."""
    return [with_sum(values_chars[i:i + MAX_LINE])
            for i in range(0, len(values_chars), MAX_LINE)]


def strip_data_lines(block: bytes | memoryview, what: str = "data") -> npt.NDArray[np.uint8]:
    """Data lines joined by LF (no trailing LF): check every sum, return the joined chars.

    Vectorised: a fast path views full 64-char lines as a (rows, 66) array; anything else goes
    through line bounds from the LF positions and sums by ``np.add.reduceat``.
    """
    buf = np.frombuffer(bytes(block) + b"\n", dtype=np.uint8)  # every line now ends in LF
    if buf.size == 1:
        return buf[:0]
    row = MAX_LINE + 2
    rows = (buf.size - 1) // row  # the last line is handled as the tail, even if full
    head = buf[:rows * row].reshape(rows, row)
    tail = buf[rows * row:]
    if (head[:, row - 1] == LF).all() and tail.size >= 3 and np.count_nonzero(tail == LF) == 1:
        sums = (head[:, :MAX_LINE].sum(axis=1, dtype=np.int64) & 0x3F) + 0x30
        tail_sum = (int(tail[:-2].sum(dtype=np.int64)) & 0x3F) + 0x30
        if (sums == head[:, MAX_LINE]).all() and tail_sum == tail[-2]:
            return np.concatenate([head[:, :MAX_LINE].reshape(-1), tail[:-2]])
    return _strip_general(buf, what)


def _strip_general(buf: npt.NDArray[np.uint8], what: str) -> npt.NDArray[np.uint8]:
    ends = np.flatnonzero(buf == LF)  # buf ends in LF, so every line has one
    starts = np.empty_like(ends)
    starts[0] = 0
    starts[1:] = ends[:-1] + 1
    lengths = ends - starts  # chars before the LF, sum char included
    if lengths.min() < 2 or lengths.max() > MAX_LINE + 1:
        bad = int(np.flatnonzero((lengths < 2) | (lengths > MAX_LINE + 1))[0])
        raise FormatError(f"{what} line {bad} has {int(lengths[bad])} chars (want 2..65)")
    sum_pos = ends - 1
    totals = np.add.reduceat(buf, starts, dtype=np.int64)  # line + sum char + LF
    sums = ((totals - buf[sum_pos] - LF) & 0x3F) + 0x30
    bad_sum = sums != buf[sum_pos]
    if bad_sum.any():
        i = int(np.flatnonzero(bad_sum)[0])
        line = bytes(buf[starts[i]:ends[i]])
        raise SumError(f"bad sum in {what} line {i} {line[:70]!r}")
    keep = np.ones(buf.size, dtype=bool)
    keep[ends] = False
    keep[sum_pos] = False
    return buf[keep]


# --- requests --------------------------------------------------------------------------------
def encode_request(command: str, params: str = "", tag: str = "") -> bytes:
    text = command + params + (";" + tag if tag else "")
    if not text.isascii() or "\n" in text or len(text) > 64:
        raise ValueError(f"bad SCIP request {text!r}")
    return text.encode() + b"\n"


def md_params(start: int, end: int, cluster: int = 1, interval: int = 0, count: int = 0) -> str:
    """Parameters of MD/MS/GD...: start 4, end 4, cluster 2 [, interval 1, count 2]."""
    return f"{start:04d}{end:04d}{cluster:02d}{interval:01d}{count:02d}"


@dataclass(frozen=True)
class ScanRequest:
    """An MD/MS request decoded (also what the simulator parses)."""

    command: str  # "MD" (3-char values) or "MS" (2-char)
    start: int
    end: int
    cluster: int
    interval: int
    count: int
    tag: str = ""

    @property
    def nchars(self) -> int:
        return 3 if self.command == "MD" else 2

    @property
    def size(self) -> int:
        """Values in one scan: one per cluster of the steps start..end (cluster 00 is 1)."""
        return (self.end - self.start) // (self.cluster or 1) + 1

    def echo(self, remaining: int | None = None) -> bytes:
        """Echo line; scan blocks carry the remaining scan count in place of `count`."""
        n = self.count if remaining is None else remaining
        text = self.command + md_params(self.start, self.end, self.cluster, self.interval, n)
        return (text + (";" + self.tag if self.tag else "")).encode()

    @classmethod
    def parse(cls, line: bytes) -> ScanRequest:
        text, _, tag = line.decode("ascii", "replace").partition(";")
        if len(text) != 15 or text[:2] not in ("MD", "MS") or not text[2:].isdigit():
            raise FormatError(f"not an MD/MS request: {line[:40]!r}")
        return cls(text[:2], int(text[2:6]), int(text[6:10]), int(text[10:12]),
                   int(text[12:13]), int(text[13:15]), tag)


# --- replies ---------------------------------------------------------------------------------
@dataclass
class Reply:
    echo: bytes
    status: str  # "00", "99", ... ("0"/"E" for a SCIP 1.1 status, which has no sum)
    lines: list[bytes] = field(default_factory=list)  # raw lines after the status (sums kept)
    skipped: int = 0  # garbage bytes before the echo


def _is_status_line(line: bytes) -> bool:
    if len(line) == 3:
        return sum_char(line[:2]) == line[2]
    return line in (b"0", b"E")  # SCIP 1.1 status (no sum)


def parse_reply(block: bytes, expect_echo: bytes | Iterable[bytes]) -> Reply:
    """One reply block (everything before its LF LF): find the echo, check the status sum.

    `expect_echo` is the exact echo wanted, or a tuple of accepted echo prefixes. Garbage before
    the echo (line noise, a stale reply's tail) is skipped and counted in `skipped`; a block
    with a well-formed status line but another echo raises EchoError.
    """
    prefixes = (expect_echo,) if isinstance(expect_echo, bytes) else tuple(expect_echo)
    lines = block.split(b"\n")
    skipped = 0
    for i in range(len(lines) - 1):
        line = lines[i]
        if _is_status_line(lines[i + 1]):
            for p in prefixes:
                at = line.rfind(p)
                if at < 0 or (isinstance(expect_echo, bytes) and at + len(p) != len(line)):
                    continue
                status_line = lines[i + 1]
                status = (status_line[:2] if len(status_line) == 3 else status_line).decode(
                    "ascii", "replace")
                return Reply(line[at:], status, lines[i + 2:], skipped + at)
        skipped += len(line) + 1
    if len(lines) >= 2 and _is_status_line(lines[1]):
        raise EchoError(f"wrong echo {lines[0][:40]!r}, want {prefixes[0][:40]!r}")
    if len(lines) >= 2 and len(lines[1]) == 3:
        raise SumError(f"bad sum in status line {lines[1]!r} of reply {lines[0][:40]!r}")
    raise FormatError(f"no SCIP reply in {len(block)} bytes: {block[:40]!r}")


def expect_status(reply: Reply, command: str, *ok: str) -> None:
    if reply.status not in ok:
        raise StatusError(command, reply.status)


def parse_info(reply: Reply) -> dict[str, str]:
    """PP/VV/II lines ``NAME:value;sum`` to a dict (sum with or without the ``;``)."""
    out: dict[str, str] = {}
    for line in reply.lines:
        if len(line) < 3 or line[-2:-1] != b";":
            raise FormatError(f"bad info line {line[:70]!r}")
        body = line[:-2]
        if sum_char(body) != line[-1] and sum_char(line[:-1]) != line[-1]:
            raise SumError(f"bad sum in info line {line[:70]!r}")
        name, sep, value = body.decode("ascii", "replace").partition(":")
        if not sep:
            raise FormatError(f"info line without ':' {line[:70]!r}")
        out[name] = value
    return out


def encode_info(items: dict[str, str], include_semicolon: bool = False) -> list[bytes]:
    lines = []
    for k, v in items.items():
        body = f"{k}:{v}".encode()
        s = sum_char(body + b";") if include_semicolon else sum_char(body)
        lines.append(body + b";" + bytes((s,)))
    return lines


def encode_reply(echo: bytes, status: str, lines: Iterable[bytes] = ()) -> bytes:
    """A whole reply: echo, status + sum, lines (already with sums), ending LF LF."""
    head = echo + b"\n" + (with_sum(status.encode()) if len(status) == 2 else status.encode())
    body = b"".join(b"\n" + line for line in lines)
    return head + body + b"\n\n"


@dataclass(frozen=True)
class Scan:
    echo: bytes
    remaining: int  # scans still to come (0 forever / last)
    timestamp_ms: int  # 24-bit device clock
    values: npt.NDArray[np.int64]  # raw values (mm; < DMIN are error codes)


def _counted(echo: bytes, values: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
    """`values` if there are as many as the echo's start, end and cluster ask for: a block cut
    short (a lost or spliced LF ends it early) is a FormatError, not a shorter scan."""
    want = ScanRequest.parse(echo).size
    if values.size != want:
        raise FormatError(f"scan has {values.size} values, its echo asks for {want}")
    return values


def parse_scan(block: bytes, prefix: bytes, nchars: int) -> Scan:
    """One MD/MS scan block: echo starting with `prefix`, status 99, timestamp, data."""
    # Fast path for a clean block; anything unusual (garbage, other status) takes the general one.
    e = block.find(b"\n")
    s = block.find(b"\n", e + 1)
    t = block.find(b"\n", s + 1)
    if (e >= 15 and block.startswith(prefix) and block[e + 1:s] == b"99b" and t == s + 6
            and b"\n" not in block[:e]):
        ts = check_line(block[s + 1:t], "timestamp")
        values = decode_values(strip_data_lines(memoryview(block)[t + 1:]), nchars)
        rem = block[13:15]
        return Scan(block[:e], int(rem) if rem.isdigit() else 0, decode_value(ts),
                    _counted(block[:e], values))
    reply = parse_reply(block, (prefix,))
    if reply.status != "99":
        raise StatusError(reply.echo[:2].decode("ascii", "replace"), reply.status)
    if len(reply.echo) < 15:
        raise EchoError(f"short scan echo {reply.echo!r}")
    if not reply.lines:
        raise FormatError("scan without timestamp")
    ts = check_line(reply.lines[0], "timestamp")
    if len(ts) != 4:
        raise FormatError(f"timestamp has {len(ts)} chars")
    # Data lines are contiguous in `block`: slice them out once for the vectorised pass.
    data = b"\n".join(reply.lines[1:])
    values = decode_values(strip_data_lines(data), nchars)
    rem = reply.echo[13:15]  # MD/MS echo: the remaining-scan count replaces the count field
    return Scan(reply.echo, int(rem) if rem.isdigit() else 0, decode_value(ts),
                _counted(reply.echo, values))


def encode_scan(req: ScanRequest, remaining: int, timestamp_ms: int,
                values: npt.ArrayLike) -> bytes:
    """A scan block as the device sends it (status 99)."""
    ts = with_sum(encode_value(timestamp_ms & 0xFFFFFF, 4))
    return encode_reply(req.echo(remaining), "99",
                        [ts, *split_data(encode_values(values, req.nchars))])


class ReplyReader:
    """Incremental reader: bytes in, complete reply blocks out (split at LF LF).

    Leading LFs (stray empty lines) are dropped so a garbage LF cannot shift the framing; a
    buffer that grows past `max_buffer` without a terminator is discarded (counted).
    """

    def __init__(self, max_buffer: int = 1 << 16) -> None:
        self._buf = bytearray()
        self.max_buffer = max_buffer
        self.discarded = 0

    def feed(self, data: bytes) -> list[bytes]:
        self._buf += data
        out: list[bytes] = []
        while True:
            while self._buf[:1] == b"\n":
                del self._buf[:1]
            end = self._buf.find(b"\n\n")
            if end < 0:
                break
            out.append(bytes(self._buf[:end]))
            del self._buf[:end + 2]
        if len(self._buf) > self.max_buffer:
            self.discarded += len(self._buf)
            self._buf.clear()
        return out

    def clear(self) -> None:
        self._buf.clear()


def angles_rad(steps: npt.ArrayLike, afrt: int, ares: int) -> npt.NDArray[np.float64]:
    return (np.asarray(steps, dtype=np.float64) - afrt) * (2.0 * math.pi / ares)
