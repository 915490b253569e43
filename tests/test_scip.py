"""SCIP 2.0 codec against byte-exact examples written out by hand (not with the encoder)."""

from __future__ import annotations

import contextlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from autochair.protocol import scip


def sc(body: bytes) -> bytes:
    """The sum char, computed independently of the module under test."""
    total = 0
    for b in body:
        total += b
    return bytes([(total & 0x3F) + 0x30])


def test_known_sum_chars_and_values() -> None:
    # Status lines every SCIP 2.0 trace shows, and the spec's encoding examples.
    assert scip.with_sum(b"00") == b"00P"
    assert scip.with_sum(b"99") == b"99b"
    assert scip.with_sum(b"0E") == b"0Ee"
    assert scip.decode_value(b"CB") == 1234  # 2-char example
    assert scip.decode_value(b"1Dh") == 5432  # 3-char example
    assert scip.encode_value(5432, 3) == b"1Dh"
    assert list(scip.decode_values(b"CB1D0o", 2)) == [1234, 1 * 64 + 20, 63]
    assert list(scip.decode_values(b"1Dh000", 3)) == [5432, 0]


def md_reply_by_hand(values: list[int], ts: int, remaining: str = "00") -> bytes:
    echo = b"MD0044" + b"%04d" % (44 + len(values) - 1) + b"010" + remaining.encode()
    chars = b"".join(bytes([((v >> 12) & 63) + 48, ((v >> 6) & 63) + 48, (v & 63) + 48])
                     for v in values)
    tsc = bytes([((ts >> s) & 63) + 48 for s in (18, 12, 6, 0)])
    lines = [chars[i:i + 64] for i in range(0, len(chars), 64)]
    out = echo + b"\n99b\n" + tsc + sc(tsc) + b"\n"
    out += b"".join(line + sc(line) + b"\n" for line in lines)
    return out + b"\n"


def test_md_scan_with_a_value_straddling_a_line_break() -> None:
    values = [20 + 37 * i for i in range(21)] + [5432, 19, 0, 4000]  # value 22 straddles
    raw = md_reply_by_hand(values, 0xABCDE)
    lines = raw.split(b"\n")
    assert len(lines[3]) == 65 and lines[4][:2] == scip.encode_value(5432, 3)[1:]
    reader = scip.ReplyReader()
    (block,) = reader.feed(raw)
    scan = scip.parse_scan(block, b"MD00440068010", 3)
    assert scan.timestamp_ms == 0xABCDE
    assert scan.values.tolist() == values
    assert scan.remaining == 0


def test_ms_two_char_scan_and_encoder_is_byte_exact() -> None:
    req = scip.ScanRequest("MS", 0, 39, 1, 0, 5)
    vals = np.arange(40) * 100
    chars = b"".join(bytes([((v >> 6) & 63) + 48, (v & 63) + 48]) for v in vals.tolist())
    ts = b"0000"
    want = (b"MS0000003901004\n99b\n" + ts + sc(ts) + b"\n" + chars[:64] + sc(chars[:64])
            + b"\n" + chars[64:] + sc(chars[64:]) + b"\n\n")
    assert scip.encode_scan(req, 4, 0, vals) == want
    scan = scip.parse_scan(want[:-2], b"MS00000039010", 2)
    assert scan.values.tolist() == vals.tolist() and scan.remaining == 4


def test_error_codes_stay_raw_values() -> None:
    raw = md_reply_by_hand([0, 1, 19, 20, 5600], 7)
    scan = scip.parse_scan(raw[:-2], b"MD0044", 3)
    assert scan.values.tolist() == [0, 1, 19, 20, 5600]


def test_bad_sum_in_data_line_is_reported() -> None:
    raw = bytearray(md_reply_by_hand([100] * 30, 7))
    pos = raw.index(b"\n", raw.index(b"99b\n") + 4) + 5  # inside the first data line
    raw[pos] = raw[pos] + 1
    with pytest.raises(scip.SumError, match="bad sum in data line 0"):
        scip.parse_scan(bytes(raw[:-2]), b"MD0044", 3)


def test_bad_sum_in_timestamp_and_status() -> None:
    raw = md_reply_by_hand([100] * 3, 7)
    with pytest.raises(scip.SumError, match="timestamp"):
        ts_at = raw.index(b"99b\n") + 4
        bad = raw[:ts_at] + b"1" + raw[ts_at + 1:]
        scip.parse_scan(bad[:-2], b"MD0044", 3)
    with pytest.raises(scip.SumError, match="status"):
        scip.parse_reply(b"QT\n00Q", b"QT")


def test_wrong_echo() -> None:
    with pytest.raises(scip.EchoError, match="wrong echo"):
        scip.parse_reply(b"PP\n00P", b"QT")


def test_unexpected_status() -> None:
    reply = scip.parse_reply(b"MD0044072501000\n0Ee", b"MD0044072501000")
    with pytest.raises(scip.StatusError, match="undefined command"):
        scip.expect_status(reply, "MD", "00")


def test_garbage_between_replies_is_skipped() -> None:
    good = b"QT\n00P\n\n"
    scan = md_reply_by_hand([300, 400], 9)
    stream = b"\x00\xff\x13junk" + good + b"\n\nrubbish\n\n" + b"\xfe" + scan
    reader = scip.ReplyReader()
    blocks = [b for i in range(0, len(stream), 7) for b in reader.feed(stream[i:i + 7])]
    assert len(blocks) == 3
    qt = scip.parse_reply(blocks[0], b"QT")
    assert qt.status == "00" and qt.skipped == 7
    with pytest.raises(scip.FormatError):
        scip.parse_reply(blocks[1], b"QT")
    assert scip.parse_scan(blocks[2], b"MD0044", 3).values.tolist() == [300, 400]


def test_pp_reply_urg04lx_sum_without_semicolon() -> None:
    body = [b"DMIN:20", b"DMAX:5600", b"ARES:1024", b"AMIN:44", b"AMAX:725", b"AFRT:384",
            b"SCAN:600"]
    raw = b"PP\n00P\n" + b"".join(b + b";" + sc(b) + b"\n" for b in body)
    reply = scip.parse_reply(raw.rstrip(b"\n"), b"PP")
    info = scip.parse_info(reply)
    assert info["DMAX"] == "5600" and info["AFRT"] == "384" and len(info) == 7
    # Newer models include the ';' in the sum: also accepted.
    info2 = scip.parse_info(scip.Reply(b"PP", "00", [b"DMIN:23;" + sc(b"DMIN:23;")]))
    assert info2 == {"DMIN": "23"}
    with pytest.raises(scip.SumError):
        scip.parse_info(scip.Reply(b"PP", "00", [b"DMIN:20;5"]))


def test_request_encoding() -> None:
    assert scip.encode_request("MD", scip.md_params(44, 725, 1, 0, 0)) == b"MD0044072501000\n"
    assert scip.encode_request("VV", tag="x1") == b"VV;x1\n"
    with pytest.raises(ValueError):
        scip.encode_request("MD\n")


def test_long_data_line_rejected() -> None:
    line = b"0" * 65
    with pytest.raises(scip.FormatError, match="66 chars"):
        scip.strip_data_lines(line + sc(line))


EXPECTED = (scip.ScipError,)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.binary(max_size=200), max_size=10))
def test_random_bytes_only_raise_documented_errors(chunks: list[bytes]) -> None:
    reader = scip.ReplyReader(max_buffer=4096)
    for chunk in chunks:
        for block in reader.feed(chunk):
            with contextlib.suppress(*EXPECTED):
                scip.parse_scan(block, b"MD", 3)
            with contextlib.suppress(*EXPECTED):
                scip.parse_info(scip.parse_reply(block, b"PP"))
            with contextlib.suppress(*EXPECTED):
                scip.parse_reply(block, (b"MD", b"MS"))


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=300), st.integers(0, 400))
def test_random_bytes_around_a_scan(noise: bytes, cut: int) -> None:
    """Noise spliced into a valid scan: either the right values or a documented error."""
    good = md_reply_by_hand([1000 + i for i in range(40)], 5)
    data = good[:cut] + noise + good[cut:]
    for block in scip.ReplyReader().feed(data):
        try:
            scan = scip.parse_scan(block, b"MD0044", 3)
        except EXPECTED:
            continue
        assert scan.values.size == 40  # (a block cut short by a spliced LF: a FormatError)
