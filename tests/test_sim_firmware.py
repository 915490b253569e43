"""Firmware emulation: boot neutral, 200 ms watchdog, command window, seq/clock wrap."""

from __future__ import annotations

import itertools

from autochair.protocol import arduino as proto
from autochair.sim.chair.firmware import Firmware
from autochair_msgs import keys

DT = 1.0 / keys.DRIVE_RATE_HZ  # the telemetry period


def cmd(seq: int, lmv: int, amv: int, enable: bool = True) -> bytes:
    return proto.encode(proto.Command(seq, 0, lmv, amv, proto.FL_ENABLE if enable else 0))


def telemetry(wire: bytes) -> proto.Telemetry:
    frames = proto.FrameDecoder().feed(wire)
    assert len(frames) == 1 and isinstance(frames[0], proto.Telemetry)
    return frames[0]


def test_neutral_with_boot_flag_for_first_second() -> None:
    fw = Firmware()
    t = 0.0
    while t < 0.99:
        fw.receive(cmd(1, 3500, 1500), t)  # host commands during boot are not applied
        tel = telemetry(fw.tick(t, 0, 0))
        assert tel.status & proto.ST_BOOT
        assert fw.output_volts == (2.5, 2.5)
        t += DT
    t = 1.0
    fw.receive(cmd(2, 3500, 1500), t)
    tel = telemetry(fw.tick(t, 0, 0))
    assert not tel.status & proto.ST_BOOT
    assert tel.status & proto.ST_OUTPUT_ENABLED
    assert fw.output_volts == (3.5, 1.5)


def test_watchdog_returns_to_neutral_after_200ms() -> None:
    fw = Firmware()
    fw.receive(cmd(1, 3000, 2600), 1.0)
    fw.tick(1.0, 0, 0)
    assert fw.output_volts == (3.0, 2.6)
    tel = telemetry(fw.tick(1.2, 0, 0))  # exactly 200 ms: still alive
    assert fw.output_volts == (3.0, 2.6) and not tel.status & proto.ST_HOST_TIMEOUT
    tel = telemetry(fw.tick(1.205, 0, 0))
    assert fw.output_volts == (2.5, 2.5)
    assert tel.status & proto.ST_HOST_TIMEOUT and not tel.status & proto.ST_OUTPUT_ENABLED
    fw.tick(1.21, 0, 0)
    assert fw.counters.host_timeouts == 1  # counted once per loss, not per tick
    fw.receive(cmd(2, 2000, 2500), 1.3)
    tel = telemetry(fw.tick(1.3, 0, 0))
    assert fw.output_volts == (2.0, 2.5) and not tel.status & proto.ST_HOST_TIMEOUT


def test_garbage_does_not_feed_the_watchdog() -> None:
    fw = Firmware()
    fw.receive(cmd(1, 3000, 2500), 1.0)
    fw.tick(1.0, 0, 0)
    bad = bytearray(cmd(2, 3000, 2500))
    bad[3] ^= 0x40
    for i in range(1, 60):
        fw.receive(bytes(bad) + b"\x13\x37junk\x00", 1.0 + i * DT)
        fw.tick(1.0 + i * DT, 0, 0)
    assert fw.output_volts == (2.5, 2.5)
    assert fw.counters.host_bad_frames >= 59 and fw.counters.host_frames == 1


def test_out_of_window_rejected_and_neutral() -> None:
    fw = Firmware()
    fw.receive(cmd(1, 3000, 2500), 1.0)
    fw.tick(1.0, 0, 0)
    for lmv, amv in ((1099, 2500), (2500, 3901), (4000, 1000), (0, 65535)):
        fw.receive(cmd(2, 3000, 2500), 1.01)  # valid first, then the bad one
        fw.receive(cmd(3, lmv, amv), 1.01)
        tel = telemetry(fw.tick(1.01, 0, 0))
        assert fw.output_volts == (2.5, 2.5)
        assert tel.status & proto.ST_CMD_REJECTED and not tel.status & proto.ST_OUTPUT_ENABLED
    assert fw.counters.rejected_commands == 4
    for lmv, amv in ((1100, 3900), (3900, 1100)):  # edges are valid
        fw.receive(cmd(4, lmv, amv), 1.02)
        tel = telemetry(fw.tick(1.02, 0, 0))
        assert fw.output_volts == (lmv / 1000, amv / 1000)
        assert not tel.status & proto.ST_CMD_REJECTED


def test_enable_flag_clear_means_neutral() -> None:
    fw = Firmware()
    fw.receive(cmd(1, 3000, 3000), 1.0)
    fw.receive(cmd(2, 3000, 3000, enable=False), 1.0)
    tel = telemetry(fw.tick(1.0, 0, 0))
    assert fw.output_volts == (2.5, 2.5) and not tel.status & proto.ST_OUTPUT_ENABLED
    assert not tel.status & proto.ST_HOST_TIMEOUT  # the host is alive, just not driving


def test_seq_clock_and_counter_wrap() -> None:
    fw = Firmware(seq_start=0xFFFE, clock_offset_us=0xFFFFFFFF - 7000)
    tels = [telemetry(fw.tick(i * DT, -1 - i, 2**32 + i)) for i in range(4)]
    assert [t.seq for t in tels] == [0xFFFE, 0xFFFF, 0, 1]
    assert proto.seq_gap(tels[1].seq, tels[2].seq) == 0
    us = [t.t_us for t in tels]
    assert us[0] > us[1] or us[1] > us[2]  # the 32-bit clock wrapped in here
    assert all(proto.wrap_delta(a, b) == round(DT * 1e6) for a, b in itertools.pairwise(us))
    assert tels[0].left == 0xFFFFFFFF and tels[1].left == 0xFFFFFFFE
    assert tels[0].right == 0 and tels[3].right == 3
    assert proto.wrap_delta(tels[0].left, tels[3].left) == -3


def test_telemetry_frame_sent_to_firmware_is_counted_bad() -> None:
    fw = Firmware()
    fw.receive(proto.encode(proto.Telemetry(1, 2, 3, 4, 0)), 1.0)
    assert fw.counters.host_bad_frames == 1 and fw.counters.host_frames == 0
