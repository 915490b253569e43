"""The chair ↔ host serial protocol (spec: docs/arduino-protocol.md).

Frame on the wire: COBS(body ‖ CRC-16) ‖ 0x00, where body = type byte + little-endian fields and
the CRC is CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF; avr-libc `_crc_xmodem_update` seeded
with 0xFFFF) of body, sent little-endian. The 0x00 delimiter makes resynchronisation trivial:
after garbage, the decoder drops bytes up to the next 0x00 and the CRC rejects what is left.
"""

from __future__ import annotations

import binascii
import struct
from dataclasses import dataclass, field

from cobs import cobs

TELEMETRY = 0x01  # chair → host
COMMAND = 0x02  # host → chair

_TELEMETRY = struct.Struct("<BHIIIB")  # type, seq, t_us, left, right, status
_COMMAND = struct.Struct("<BHHHHB")  # type, seq, ack_seq, longitudinal_mv, angular_mv, flags
MAX_FRAME = 64  # longest encoded frame we accept before declaring garbage
# COBS of body + CRC: one overhead byte (frames are far below 254 bytes).
_ENCODED_SIZES = (_TELEMETRY.size + 3, _COMMAND.size + 3)

# Telemetry status bits.
ST_OUTPUT_ENABLED = 0x01  # joystick output follows host commands (else neutral)
ST_HOST_TIMEOUT = 0x02  # no valid host frame for 200 ms: output forced neutral
ST_BOOT = 0x04  # first second after reset
ST_ENCODER_FAULT = 0x08
ST_CMD_REJECTED = 0x10  # last command was outside the valid window and was not applied

# Command flags.
FL_ENABLE = 0x01


def crc16(data: bytes) -> int:
    return binascii.crc_hqx(data, 0xFFFF)


@dataclass(frozen=True, slots=True)
class Telemetry:
    seq: int  # u16
    t_us: int  # u32 MCU clock
    left: int  # u32 raw counter
    right: int  # u32 raw counter
    status: int  # u8


@dataclass(frozen=True, slots=True)
class Command:
    seq: int  # u16
    ack_seq: int  # u16: last telemetry seq the host had seen (for round-trip tracing)
    longitudinal_mv: int  # u16 millivolts
    angular_mv: int  # u16 millivolts
    flags: int  # u8

    @property
    def enable(self) -> bool:
        return bool(self.flags & FL_ENABLE)


Frame = Telemetry | Command


def _wrap(body: bytes) -> bytes:
    encoded: bytes = cobs.encode(body + struct.pack("<H", crc16(body)))
    return encoded + b"\x00"


def encode(frame: Frame) -> bytes:
    if isinstance(frame, Telemetry):
        body = _TELEMETRY.pack(TELEMETRY, frame.seq & 0xFFFF, frame.t_us & 0xFFFFFFFF,
                               frame.left & 0xFFFFFFFF, frame.right & 0xFFFFFFFF,
                               frame.status & 0xFF)
    else:
        body = _COMMAND.pack(COMMAND, frame.seq & 0xFFFF, frame.ack_seq & 0xFFFF,
                             frame.longitudinal_mv, frame.angular_mv, frame.flags & 0xFF)
    return _wrap(body)


@dataclass
class DecoderStats:
    frames: int = 0
    bad_crc: int = 0
    bad_cobs: int = 0
    bad_length: int = 0  # right CRC, wrong size for its type
    unknown_type: int = 0
    oversize: int = 0  # no delimiter within MAX_FRAME bytes
    garbage_bytes: int = 0  # bytes discarded in rejected frames

    @property
    def bad_frames(self) -> int:
        return self.bad_crc + self.bad_cobs + self.bad_length + self.unknown_type + self.oversize


@dataclass
class FrameDecoder:
    """Incremental decoder: feed any chunks of bytes, get whole valid frames back."""

    stats: DecoderStats = field(default_factory=DecoderStats)
    _buf: bytearray = field(default_factory=bytearray)

    def feed(self, data: bytes) -> list[Frame]:
        out: list[Frame] = []
        self._buf += data
        while True:
            end = self._buf.find(0)
            if end < 0:
                if len(self._buf) > MAX_FRAME:  # a run with no delimiter: drop all but a tail
                    self.stats.oversize += 1
                    self.stats.garbage_bytes += len(self._buf)
                    self._buf.clear()
                return out
            chunk = bytes(self._buf[:end])
            del self._buf[: end + 1]
            if not chunk:
                continue  # back-to-back delimiters: idle line, not an error
            frame = self._parse(chunk)
            if frame is None:
                # Garbage with no delimiter before a frame glues onto it; frames have fixed
                # encoded sizes, so try the chunk's tail as a frame before giving up on it.
                for size in _ENCODED_SIZES:
                    if len(chunk) > size:
                        frame = self._parse(chunk[-size:], count_errors=False)
                        if frame is not None:
                            self.stats.garbage_bytes += len(chunk) - size
                            break
            if frame is None:
                self.stats.garbage_bytes += len(chunk) + 1
            else:
                self.stats.frames += 1
                out.append(frame)

    def _parse(self, chunk: bytes, count_errors: bool = True) -> Frame | None:
        stats = self.stats if count_errors else DecoderStats()
        if len(chunk) > MAX_FRAME:
            stats.oversize += 1
            return None
        try:
            raw = cobs.decode(chunk)
        except cobs.DecodeError:
            stats.bad_cobs += 1
            return None
        if len(raw) < 3:
            stats.bad_length += 1
            return None
        body, (crc,) = raw[:-2], struct.unpack("<H", raw[-2:])
        if crc16(body) != crc:
            stats.bad_crc += 1
            return None
        kind = body[0]
        if kind == TELEMETRY:
            if len(body) != _TELEMETRY.size:
                stats.bad_length += 1
                return None
            _, seq, t_us, left, right, status = _TELEMETRY.unpack(body)
            return Telemetry(seq, t_us, left, right, status)
        if kind == COMMAND:
            if len(body) != _COMMAND.size:
                stats.bad_length += 1
                return None
            _, seq, ack, lmv, amv, flags = _COMMAND.unpack(body)
            return Command(seq, ack, lmv, amv, flags)
        stats.unknown_type += 1
        return None


def seq_gap(prev: int, seq: int, bits: int = 16) -> int:
    """Frames missing between two sequence numbers (0 when consecutive), wrap-safe."""
    return ((seq - prev) % (1 << bits)) - 1


def wrap_delta(prev: int, cur: int, bits: int = 32) -> int:
    """Signed difference of two N-bit wrapping counters: ((c − p + 2^(N−1)) mod 2^N) − 2^(N−1)."""
    half = 1 << (bits - 1)
    return ((cur - prev + half) % (1 << bits)) - half
