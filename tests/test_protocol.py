"""The Arduino frame protocol: round trips, resynchronisation, error counting, fuzzing."""

from __future__ import annotations

import random

from hypothesis import given, settings
from hypothesis import strategies as st

from autochair.protocol import arduino as proto

TEL = proto.Telemetry(seq=65535, t_us=0xFFFFFFFF, left=0, right=123456789, status=0x1F)
CMD = proto.Command(seq=7, ack_seq=65534, longitudinal_mv=3900, angular_mv=1100,
                    flags=proto.FL_ENABLE)


def test_round_trip_both_types() -> None:
    for frame in (TEL, CMD, proto.Telemetry(0, 0, 0, 0, 0), proto.Command(0, 0, 0, 0, 0)):
        wire = proto.encode(frame)
        assert wire.endswith(b"\x00") and wire.count(0) == 1
        dec = proto.FrameDecoder()
        assert dec.feed(wire) == [frame]
        assert dec.stats.bad_frames == 0 and dec.stats.garbage_bytes == 0


def test_byte_by_byte_feed() -> None:
    dec = proto.FrameDecoder()
    out: list[proto.Frame] = []
    for b in proto.encode(TEL) + proto.encode(CMD):
        out += dec.feed(bytes([b]))
    assert out == [TEL, CMD]


def test_resync_after_random_garbage() -> None:
    rng = random.Random(1)
    dec = proto.FrameDecoder()
    got: list[proto.Frame] = []
    sent = []
    for i in range(200):
        frame = proto.Telemetry(i, i * 5000, i * 3, i * 4, 0)
        sent.append(frame)
        junk = bytes(rng.randrange(256) for _ in range(rng.randrange(0, 80)))
        got += dec.feed(junk + b"\x00" + proto.encode(frame))
    assert got == sent


def test_garbage_glued_to_frame_without_delimiter() -> None:
    dec = proto.FrameDecoder()
    for junk in (b"\x01", b"\x05\x07\x09", bytes(range(1, 30))):
        assert dec.feed(junk + proto.encode(CMD)) == [CMD]
    assert dec.stats.garbage_bytes == 1 + 3 + 29


def test_crc_corruption_counted() -> None:
    dec = proto.FrameDecoder()
    wire = bytearray(proto.encode(TEL))
    wire[5] ^= 0x01  # a data byte, not a COBS code byte: CRC must catch it
    assert dec.feed(bytes(wire)) == []
    assert dec.stats.bad_crc == 1 and dec.stats.bad_frames == 1
    assert dec.feed(proto.encode(TEL)) == [TEL]  # next frame fine


def test_oversize_run_without_delimiter_dropped() -> None:
    dec = proto.FrameDecoder()
    assert dec.feed(b"\x01" * (proto.MAX_FRAME + 1)) == []
    assert dec.stats.oversize == 1
    assert dec.feed(proto.encode(TEL)) == [TEL]


def test_wrap_helpers() -> None:
    assert proto.seq_gap(65535, 0) == 0 and proto.seq_gap(10, 13) == 2
    assert proto.wrap_delta(0xFFFFFFF0, 0x10) == 0x20
    assert proto.wrap_delta(0x10, 0xFFFFFFF0) == -0x20


@settings(max_examples=300, deadline=None)
@given(st.lists(st.binary(max_size=200), max_size=10))
def test_any_bytes_never_raise(chunks: list[bytes]) -> None:
    dec = proto.FrameDecoder()
    for c in chunks:
        for f in dec.feed(c):
            assert isinstance(f, proto.Telemetry | proto.Command)


telemetry = st.builds(proto.Telemetry, st.integers(0, 0xFFFF), st.integers(0, 0xFFFFFFFF),
                      st.integers(0, 0xFFFFFFFF), st.integers(0, 0xFFFFFFFF),
                      st.integers(0, 0xFF))
command = st.builds(proto.Command, st.integers(0, 0xFFFF), st.integers(0, 0xFFFF),
                    st.integers(0, 0xFFFF), st.integers(0, 0xFFFF), st.integers(0, 0xFF))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.binary(max_size=100), telemetry | command), min_size=1,
                max_size=8),
       st.binary(max_size=100))
def test_frames_between_delimited_garbage_recovered(
        items: list[tuple[bytes, proto.Frame]], tail: bytes) -> None:
    dec = proto.FrameDecoder()
    got: list[proto.Frame] = []
    for junk, frame in items:
        got += dec.feed(junk + b"\x00" + proto.encode(frame))
    got += dec.feed(tail + b"\x00")
    frames = [f for _, f in items]
    # Every frame is recovered in order; garbage can (rarely) also decode as a valid frame.
    it = iter(got)
    assert all(any(g == f for g in it) for f in frames)
