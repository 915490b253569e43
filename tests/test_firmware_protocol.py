"""The firmware's C protocol code (firmware/autochair_arduino/ac_protocol.c) on the host.

Built with the host gcc as a ctypes library and checked byte for byte against the Python
protocol (autochair.protocol.arduino) and the Python firmware emulation
(autochair.sim.chair.firmware).
"""

from __future__ import annotations

import binascii
import ctypes
import random
import re
from pathlib import Path

import pytest
from cobs import cobs
from hypothesis import given, settings
from hypothesis import strategies as st

from autochair.protocol import arduino as proto
from autochair.sim.chair.firmware import Firmware
from autochair_msgs import keys
from tests.firmware_lib import (
    FIRMWARE_DIR,
    Command,
    Frame,
    Fw,
    Rx,
    Telemetry,
    buf,
    build_protocol_lib,
)

# The firmware's telemetry period, read from its config header.
FRAME_US = int(re.search(r"#define AC_FRAME_US (\d+)UL",
                         (FIRMWARE_DIR / "ac_config.h").read_text())[1])  # type: ignore[index]

u16 = st.integers(0, 0xFFFF)
u32 = st.integers(0, 0xFFFFFFFF)
u8 = st.integers(0, 0xFF)


@pytest.fixture(scope="module")
def lib(tmp_path_factory: pytest.TempPathFactory) -> ctypes.CDLL:
    return build_protocol_lib(Path(tmp_path_factory.mktemp("fwlib")))


def c_crc(lib: ctypes.CDLL, data: bytes) -> int:
    return int(lib.ac_crc16(buf(data), len(data)))


def c_telemetry(lib: ctypes.CDLL, t: proto.Telemetry) -> bytes:
    out = buf()
    n = lib.ac_pack_telemetry(ctypes.byref(Telemetry(t.seq, t.t_us, t.left, t.right, t.status)),
                              out)
    return bytes(out[:n])


def c_command(lib: ctypes.CDLL, c: proto.Command) -> bytes:
    out = buf()
    n = lib.ac_pack_command(ctypes.byref(Command(c.seq, c.ack_seq, c.longitudinal_mv,
                                                 c.angular_mv, c.flags)), out)
    return bytes(out[:n])


class CDecoder:
    """The C receiver, fed one byte at a time, returning Python frames."""

    def __init__(self, lib: ctypes.CDLL) -> None:
        self.lib, self.rx, self.frame = lib, Rx(), Frame()
        lib.ac_rx_init(ctypes.byref(self.rx))

    def feed(self, data: bytes) -> list[proto.Frame]:
        out: list[proto.Frame] = []
        for b in data:
            if self.lib.ac_rx_byte(ctypes.byref(self.rx), b, ctypes.byref(self.frame)):
                f = self.frame
                if f.type == proto.TELEMETRY:
                    t = f.tel
                    out.append(proto.Telemetry(t.seq, t.t_us, t.left, t.right, t.status))
                else:
                    c = f.cmd
                    out.append(proto.Command(c.seq, c.ack_seq, c.longitudinal_mv, c.angular_mv,
                                             c.flags))
        return out

    def stats(self) -> dict[str, int]:
        s = self.rx.stats
        return {name: getattr(s, name) for name, _ in s._fields_}


def py_feed_bytewise(data: bytes) -> tuple[list[proto.Frame], dict[str, int]]:
    dec = proto.FrameDecoder()
    out: list[proto.Frame] = []
    for b in data:
        out += dec.feed(bytes([b]))
    s = dec.stats
    return out, {n: getattr(s, n) for n in ("frames", "bad_crc", "bad_cobs", "bad_length",
                                            "unknown_type", "oversize", "garbage_bytes")}


def test_crc_check_value_and_spec_examples(lib: ctypes.CDLL) -> None:
    assert c_crc(lib, b"123456789") == 0x29B1
    # docs/arduino-protocol.md examples, byte exact
    assert c_telemetry(lib, proto.Telemetry(258, 1_000_000, 10000, 0xFFFFFFFF, 3)) == bytes.fromhex(
        "07 01 02 01 40 42 0f 03 10 27 01 08 ff ff ff ff 03 a2 fc 00")
    assert c_command(lib, proto.Command(7, 258, 3100, 2500, 1)) == bytes.fromhex(
        "03 02 07 0a 02 01 1c 0c c4 09 01 96 3b 00")


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=253))
def test_crc_and_cobs_match_python(lib: ctypes.CDLL, data: bytes) -> None:
    assert c_crc(lib, data) == binascii.crc_hqx(data, 0xFFFF)
    out = buf()
    n = lib.ac_cobs_encode(buf(data), len(data), out)
    encoded = bytes(out[:n])
    assert encoded == cobs.encode(data)
    back = buf()
    assert lib.ac_cobs_decode(buf(encoded), len(encoded), back) == len(data)
    assert bytes(back[: len(data)]) == data


@settings(max_examples=300, deadline=None)
@given(st.binary(min_size=1, max_size=64).map(lambda b: b.replace(b"\x00", b"\x01")))
def test_cobs_decode_rejects_what_python_rejects(lib: ctypes.CDLL, chunk: bytes) -> None:
    out = buf()
    n = lib.ac_cobs_decode(buf(chunk), len(chunk), out)
    try:
        expected = cobs.decode(chunk)
    except cobs.DecodeError:
        assert n == -1
    else:
        assert bytes(out[:n]) == expected


@settings(max_examples=300, deadline=None)
@given(u16, u32, u32, u32, u8)
def test_telemetry_c_to_python_and_back(lib: ctypes.CDLL, seq: int, t_us: int, left: int,
                                        right: int, status: int) -> None:
    frame = proto.Telemetry(seq, t_us, left, right, status)
    wire = c_telemetry(lib, frame)
    assert len(wire) == proto._TELEMETRY.size + 4 == 20
    assert wire == proto.encode(frame)
    assert proto.FrameDecoder().feed(wire) == [frame]
    assert CDecoder(lib).feed(proto.encode(frame)) == [frame]


@settings(max_examples=300, deadline=None)
@given(u16, u16, u16, u16, u8)
def test_command_python_to_c_and_back(lib: ctypes.CDLL, seq: int, ack: int, lmv: int, amv: int,
                                      flags: int) -> None:
    frame = proto.Command(seq, ack, lmv, amv, flags)
    assert CDecoder(lib).feed(proto.encode(frame)) == [frame]
    wire = c_command(lib, frame)
    assert len(wire) == 14 and wire == proto.encode(frame)
    assert proto.FrameDecoder().feed(wire) == [frame]


def _noisy_stream(rng: random.Random, n: int) -> tuple[bytes, list[proto.Frame]]:
    """Frames of both types mixed with every kind of damage the decoders must survive."""
    out = bytearray()
    sent: list[proto.Frame] = []
    for i in range(n):
        frame: proto.Frame
        if rng.random() < 0.5:
            frame = proto.Telemetry(i, rng.getrandbits(32), rng.getrandbits(32),
                                    rng.getrandbits(32), rng.getrandbits(8))
        else:
            frame = proto.Command(i, rng.getrandbits(16), rng.randint(0, 5000),
                                  rng.randint(0, 5000), rng.getrandbits(8))
        wire = bytearray(proto.encode(frame))
        damage = rng.random()
        if damage < 0.1:  # flipped bit: CRC (or COBS) must reject it
            wire[rng.randrange(len(wire) - 1)] ^= 1 << rng.randrange(8)
            wire = bytearray(wire.replace(b"\x00", b"\x01")[:-1] + b"\x00")
        elif damage < 0.15:  # truncated: glued to the next frame
            wire = wire[: rng.randrange(1, len(wire) - 1)]
        elif damage < 0.25:  # garbage without a delimiter in front
            wire = bytearray(rng.randbytes(rng.randint(1, 12)).replace(b"\x00", b"\x55")) + wire
        elif damage < 0.3:  # long run without any delimiter (oversize)
            wire = bytearray(rng.randbytes(rng.randint(60, 140)).replace(b"\x00", b"\x07")) + wire
        elif damage < 0.35:  # random bytes with delimiters, and idle delimiters
            wire = bytearray(rng.randbytes(rng.randint(1, 30))) + b"\x00\x00" + wire
        else:
            sent.append(frame)
        out += wire
    return bytes(out), sent


@pytest.mark.parametrize("seed", range(5))
def test_garbage_resync_matches_python(lib: ctypes.CDLL, seed: int) -> None:
    rng = random.Random(seed)
    stream, clean = _noisy_stream(rng, 400)
    c_dec = CDecoder(lib)
    c_frames = c_dec.feed(stream)
    py_frames, py_stats = py_feed_bytewise(stream)
    assert c_frames == py_frames
    assert c_dec.stats() == py_stats
    # every undamaged frame survives the damage around it, except those eaten by an oversize run
    assert set(clean) - set(c_frames) == set() or py_stats["oversize"] > 0
    assert len(set(clean) & set(c_frames)) >= 0.9 * len(clean)
    assert py_stats["bad_crc"] + py_stats["bad_cobs"] + py_stats["oversize"] > 0


class CFirmware:
    def __init__(self, lib: ctypes.CDLL, seq_start: int = 0) -> None:
        self.lib, self.fw = lib, Fw()
        lib.ac_fw_init(ctypes.byref(self.fw), seq_start)

    def receive(self, data: bytes, now_us: int) -> None:
        for b in data:
            self.lib.ac_fw_rx_byte(ctypes.byref(self.fw), b, now_us & 0xFFFFFFFF)

    def watch(self, now_us: int) -> None:
        self.lib.ac_fw_watch(ctypes.byref(self.fw), now_us & 0xFFFFFFFF)

    def tick(self, now_us: int, left: int, right: int, extra: int = 0) -> bytes:
        out = buf()
        n = self.lib.ac_fw_tick(ctypes.byref(self.fw), now_us & 0xFFFFFFFF, left & 0xFFFFFFFF,
                                right & 0xFFFFFFFF, extra, out)
        return bytes(out[:n])

    @property
    def mv(self) -> tuple[int, int]:
        return self.fw.longitudinal_mv, self.fw.angular_mv


def cmd(seq: int, lmv: int, amv: int, enable: bool = True) -> bytes:
    return proto.encode(proto.Command(seq, seq, lmv, amv, proto.FL_ENABLE if enable else 0))


@pytest.mark.parametrize("seed", range(4))
def test_firmware_rules_match_python_emulation(lib: ctypes.CDLL, seed: int) -> None:
    """Random host traffic with silences; C and Python must emit identical telemetry bytes."""
    rng = random.Random(seed)
    c_fw, py_fw = CFirmware(lib, seq_start=65530), Firmware(seq_start=65530)
    left = right = 0
    host_seq = 0
    silent_until = 0
    for k in range(1, 6 * keys.DRIVE_RATE_HZ):  # 6 s of frame ticks
        t_tick = k * FRAME_US
        if t_tick > silent_until and rng.random() < 0.01:
            silent_until = t_tick + rng.randint(50_000, 400_000)  # host goes quiet
        if t_tick > silent_until and rng.random() < 0.8:
            # off the tick grid, so no event lands exactly on the 200 ms boundary
            t_rx = t_tick - rng.randint(1, FRAME_US - 1)
            r = rng.random()
            if r < 0.7:
                data = cmd(host_seq, rng.randint(1100, 3900), rng.randint(1100, 3900))
            elif r < 0.8:
                data = cmd(host_seq, rng.randint(0, 5000), rng.randint(0, 5000))
            elif r < 0.85:
                data = cmd(host_seq, 3000, 2000, enable=False)
            elif r < 0.9:  # a telemetry frame echoed back at us: valid CRC, wrong direction
                data = proto.encode(proto.Telemetry(1, 2, 3, 4, 5))
            elif r < 0.95:
                data = rng.randbytes(rng.randint(1, 30))
            else:  # command split across two reads
                whole = cmd(host_seq, 2600, 2400)
                c_fw.receive(whole[:5], t_rx - 100)
                py_fw.receive(whole[:5], (t_rx - 100) / 1e6)
                data = whole[5:]
            host_seq += 1
            c_fw.receive(data, t_rx)
            py_fw.receive(data, t_rx / 1e6)
        if rng.random() < 0.5:  # the mid-frame watchdog check (the board's Timer1 compare B)
            t_mid = t_tick - FRAME_US // 2 + rng.randint(-1, 1)
            c_fw.watch(t_mid)
            py_fw.watch(t_mid / 1e6)
            assert c_fw.mv == (py_fw.longitudinal_mv, py_fw.angular_mv)
        left += rng.randint(-40, 200)
        right -= rng.randint(-40, 200)
        c_wire = c_fw.tick(t_tick, left, right)
        py_wire = py_fw.tick(t_tick / 1e6, left, right)
        assert c_wire == py_wire, f"tick {k}"
        assert c_fw.mv == (py_fw.longitudinal_mv, py_fw.angular_mv)
    c = c_fw.fw.counters
    p = py_fw.counters
    for name in ("host_frames", "host_bad_frames", "host_timeouts", "rejected_commands",
                 "telemetry_frames"):
        assert getattr(c, name) == getattr(p, name), name
    assert p.host_timeouts > 0 and p.rejected_commands > 0 and p.host_bad_frames > 0


def _status(wire: bytes) -> int:
    (frame,) = proto.FrameDecoder().feed(wire)
    assert isinstance(frame, proto.Telemetry)
    return frame.status


def test_boot_second_is_neutral(lib: ctypes.CDLL) -> None:
    fw = CFirmware(lib)
    fw.receive(cmd(1, 3500, 1500), 990_000)
    st = _status(fw.tick(995_000, 0, 0))
    assert fw.mv == (2500, 2500) and st & proto.ST_BOOT
    assert not st & proto.ST_HOST_TIMEOUT  # boot-time frames do count as host contact
    fw.receive(cmd(2, 3500, 1500), 1_000_000)
    st = _status(fw.tick(1_000_000, 0, 0))
    assert fw.mv == (3500, 1500) and st == proto.ST_OUTPUT_ENABLED


def test_watchdog_fires_after_exactly_200ms(lib: ctypes.CDLL) -> None:
    fw = CFirmware(lib)
    fw.receive(cmd(1, 3000, 2000), 2_000_000)
    assert _status(fw.tick(2_000_000, 0, 0)) == proto.ST_OUTPUT_ENABLED
    assert _status(fw.tick(2_200_000, 0, 0)) == proto.ST_OUTPUT_ENABLED  # 200 ms: still ok
    assert fw.mv == (3000, 2000)
    st = _status(fw.tick(2_200_001, 0, 0))  # 200 ms + 1 µs: neutral
    assert fw.mv == (2500, 2500) and st == proto.ST_HOST_TIMEOUT
    assert fw.fw.counters.host_timeouts == 1
    fw.receive(cmd(2, 3100, 2500), 2_300_000)  # the next valid enabled command resumes
    assert _status(fw.tick(2_300_000, 0, 0)) == proto.ST_OUTPUT_ENABLED


def test_watchdog_checked_between_frames(lib: ctypes.CDLL) -> None:
    """The board checks the watchdog in mid-frame too (ac_fw_watch): neutral 200 ms after the
    last host frame without waiting for the next telemetry tick."""
    fw = CFirmware(lib)
    fw.receive(cmd(1, 3000, 2000), 2_000_000)
    fw.tick(2_000_000, 0, 0)
    fw.watch(2_200_000)
    assert fw.mv == (3000, 2000)  # positive control: exactly 200 ms is still fresh
    fw.watch(2_200_001)
    assert fw.mv == (2500, 2500) and fw.fw.counters.host_timeouts == 1
    assert _status(fw.tick(2_205_000, 0, 0)) == proto.ST_HOST_TIMEOUT
    assert fw.fw.counters.host_timeouts == 1  # one transition, however often it is checked


def test_frame_period_is_the_key_tables_drive_rate() -> None:
    """AC_FRAME_US (ac_config.h) and keys.DRIVE_RATE_HZ say the same rate, and Timer1's TOP
    (2 counts per µs) fits its 16 bits."""
    assert FRAME_US * keys.DRIVE_RATE_HZ == 1_000_000
    assert FRAME_US * 2 - 1 <= 0xFFFF


def test_watchdog_across_clock_wrap(lib: ctypes.CDLL) -> None:
    fw = CFirmware(lib)
    fw.tick(1_000_000, 0, 0)  # past boot
    t0 = 0xFFFFFFFF - 50_000  # the µs clock wraps 50 ms after this command
    fw.receive(cmd(1, 3000, 2000), t0)
    assert _status(fw.tick(t0 + 150_000, 0, 0)) == proto.ST_OUTPUT_ENABLED
    assert _status(fw.tick(t0 + 250_000, 0, 0)) == proto.ST_HOST_TIMEOUT
    # A host silent for a whole clock period (~71.6 min) must not look fresh when the clock
    # comes round to the old timestamp, and boot must not come back either.
    for t in range(t0 + 250_000, t0 + (1 << 32) + 100_000, 60_000_000):
        assert _status(fw.tick(t, 0, 0)) == proto.ST_HOST_TIMEOUT
    assert _status(fw.tick(t0 + (1 << 32) + 10, 0, 0)) == proto.ST_HOST_TIMEOUT
    assert fw.mv == (2500, 2500)


def test_out_of_window_rejected_and_encoder_fault_passes_through(lib: ctypes.CDLL) -> None:
    fw = CFirmware(lib)
    fw.tick(1_000_000, 0, 0)
    fw.receive(cmd(1, 3000, 2000), 1_001_000)
    fw.receive(cmd(2, 3901, 2500), 1_002_000)
    st = _status(fw.tick(1_005_000, 0, 0))
    assert fw.mv == (2500, 2500) and st == proto.ST_CMD_REJECTED
    fw.receive(cmd(3, 1100, 3900), 1_006_000)
    st = _status(fw.tick(1_010_000, 0, 0, proto.ST_ENCODER_FAULT))
    assert fw.mv == (1100, 3900) and st == proto.ST_OUTPUT_ENABLED | proto.ST_ENCODER_FAULT
    assert _status(fw.tick(1_015_000, 0, 0)) == proto.ST_OUTPUT_ENABLED  # per-frame, not latched
