"""Gateway core: neutral at start and when stale, clamping, sequence gaps, framing."""

from __future__ import annotations

import pytest

from autochair.gateway.core import GatewayCore
from autochair.protocol import arduino
from autochair.protocol.arduino import Command, FrameDecoder, Telemetry
from autochair_msgs import keys

FRAME_MS = 1000 // keys.DRIVE_RATE_HZ  # the firmware's telemetry period


def decode_one(data: bytes) -> Command:
    (frame,) = FrameDecoder().feed(data)
    assert isinstance(frame, Command)
    return frame


def running(**kw: float) -> GatewayCore:
    """A core whose e-stop service is alive and released."""
    core = GatewayCore(**kw)  # type: ignore[arg-type]
    core.on_estop(False, now_s=0.0)
    core.estop_stale_s = 1e9
    return core


def test_neutral_at_start() -> None:
    core = running()
    out = core.output(now_s=0.0)
    assert (out.longitudinal_v, out.angular_v, out.enable) == (2.5, 2.5, False)
    cmd = decode_one(core.frame(out)[0])
    assert (cmd.longitudinal_mv, cmd.angular_mv, cmd.enable) == (2500, 2500, False)


def test_command_then_stale_after_timeout() -> None:
    core = running(stale_s=0.1)
    assert core.on_command(3.0, 2.0, True, now_s=10.0)
    assert core.output(10.09).reason == "command"
    out = core.output(10.101)
    assert out.reason == "neutral:stale" and (out.longitudinal_v, out.angular_v) == (2.5, 2.5)


def test_ticked_core_is_neutral_no_later_than_the_stale_timeout() -> None:
    """Checked every tick_s, a command is neutral at the last tick before it would be older
    than stale_s (so the timeout holds whatever the tick), and the e-stop heartbeat likewise."""
    core = running(stale_s=0.1, tick_s=0.01)
    assert core.on_command(3.0, 2.0, True, now_s=10.0)
    assert core.output(10.089).reason == "command"  # positive control: still fresh
    assert core.output(10.0905).reason == "neutral:stale"  # the next tick would be 0.1005 s
    core = GatewayCore(estop_stale_s=0.5, tick_s=0.01)
    core.on_estop(False, now_s=0.0)
    core.on_command(3.0, 2.0, True, now_s=0.45)
    assert core.output(0.489).reason == "command"
    assert core.output(0.4905).reason == "neutral:estop_silent"


def test_clamps_to_window() -> None:
    core = running(min_v=1.1, max_v=3.9)
    core.on_command(4.5, 0.2, True, 0.0)
    out = core.output(0.0)
    assert (out.longitudinal_v, out.angular_v, out.clamped) == (3.9, 1.1, True)
    cmd = decode_one(core.frame(out)[0])
    assert (cmd.longitudinal_mv, cmd.angular_mv) == (3900, 1100)
    assert core.clamped == 1


def test_disabled_and_non_finite_commands_are_neutral() -> None:
    core = running()
    core.on_command(3.0, 3.0, False, 0.0)
    assert core.output(0.0).reason == "neutral:disabled"
    assert not core.on_command(float("nan"), 2.5, True, 0.0)
    assert core.rejected == 1


def test_sequence_gaps_are_counted_across_wrap() -> None:
    core = GatewayCore()
    frames = b"".join(arduino.encode(Telemetry(s & 0xFFFF, 0, 0, 0, 0))
                      for s in (65534, 65535, 2, 3))  # 0 and 1 lost across the wrap
    got = core.on_bytes(frames)
    assert [g for _, g in got] == [0, 0, 2, 0]
    assert core.dropped == 2


def test_tx_sequence_and_ack() -> None:
    core = GatewayCore()
    core.on_bytes(arduino.encode(Telemetry(77, 0, 0, 0, 0)))
    _, seq0 = core.frame(core.output(0.0))
    second, seq1 = core.frame(core.output(0.0))
    assert (seq0, seq1) == (0, 1)
    assert decode_one(second).ack_seq == 77


def test_ack_is_the_source_frame_of_the_command() -> None:
    core = running()
    core.on_bytes(arduino.encode(Telemetry(90, 0, 0, 0, 0)))
    core.on_command(3.0, 2.5, True, 0.0, source_seq=88)
    assert decode_one(core.frame(core.output(0.0))[0]).ack_seq == 88


def test_estop_latched_or_silent_holds_neutral() -> None:
    core = GatewayCore(estop_stale_s=0.5)
    core.on_command(3.0, 3.0, True, now_s=0.0)
    assert core.output(0.0).reason == "neutral:estop_silent"  # never heard the e-stop service
    core.on_estop(False, now_s=0.0)
    core.on_command(3.0, 3.0, True, now_s=0.4)
    assert core.output(0.45).reason == "command"
    core.on_command(3.0, 3.0, True, now_s=0.55)
    assert core.output(0.55).reason == "neutral:estop_silent"  # heartbeat 0.55 s old
    core.on_estop(True, now_s=0.6)
    assert core.output(0.6).reason == "neutral:estop"
    core.on_estop(False, now_s=0.7)
    core.on_command(3.0, 3.0, True, now_s=0.7)
    assert core.output(0.7).reason == "command"


def test_estop_service_death_is_immediate() -> None:
    core = GatewayCore(estop_stale_s=0.5)
    core.on_estop(False, now_s=0.0)
    core.on_command(3.0, 3.0, True, now_s=0.0)
    assert core.output(0.01).reason == "command"
    core.on_estop_gone()
    assert core.output(0.01).reason == "neutral:estop_silent"
    core.on_estop(False, now_s=0.02)  # a restarted e-stop service speaks again
    core.on_command(3.0, 3.0, True, now_s=0.02)
    assert core.output(0.02).reason == "command"


@pytest.mark.parametrize("age_s,ok", [(0.0, True), (0.099, True), (-0.05, True),
                                      (0.101, False), (-0.11, False), (5.0, False)])
def test_commands_stamped_too_long_ago_or_in_the_future_are_refused(age_s: float,
                                                                    ok: bool) -> None:
    core = running(stale_s=0.1, skew_s=0.1)
    assert core.on_command(3.0, 2.5, True, 1.0, age_s=age_s) is ok
    assert (core.output(1.0).reason == "command") is ok
    assert core.rejected_age == (0 if ok else 1)


def test_link_writes_on_change_and_keepalive_and_reopens_a_silent_port() -> None:
    core = running(keepalive_s=0.02, rx_stall_s=2.0)
    core.link_up(0.0)
    out = core.due(0.0)
    assert out is not None and out.reason == "neutral:startup"
    assert core.sent(out, 0.0) == (True, False, True)  # a new reason, a normal one, reported
    assert core.due(0.01) is None  # unchanged, keepalive not yet due
    assert core.due(0.02) == out  # keepalive (the firmware neutralises after 200 ms)
    assert core.sent(out, 0.02) == (False, False, False)  # the same frame: not reported again
    assert core.sent(out, 0.1) == (False, False, True)  # ... until report_s later
    core.on_command(3.0, 2.5, True, now_s=0.03)
    cmd = core.due(0.03)
    assert cmd is not None and cmd.reason == "command"  # changed: written at once
    core.sent(cmd, 0.03)
    stale = core.due(0.2)
    assert stale is not None and core.sent(stale, 0.2) == (True, True, True)  # a fault
    # Telemetry keeps the link; 2 s without any reopens it.
    assert not core.received(3, 1.0) and not core.received(0, 3.0)
    assert core.received(0, 3.01)
    core.link_up(4.0)  # a new link forgets the command and the last output
    assert not core.received(0, 5.0) and core.due(4.0) is not None
    assert core.output(4.0).reason == "neutral:startup"


def test_a_parked_chairs_telemetry_is_passed_on_at_20_hz_and_motion_at_once() -> None:
    core = running(parked_period_s=0.05, hold_s=1.0)
    core.link_up(0.0)
    still = Telemetry(seq=0, t_us=0, left=100, right=200, status=0)

    def frames(t0: float, t1: float, frame: Telemetry = still) -> list[float]:
        return [t / 1000 for t in range(round(t0 * 1000), round(t1 * 1000), FRAME_MS)
                if core.pass_on(frame, 0, t / 1000)]

    # Positive control: a frame that moved keeps the full rate for hold_s.
    assert core.pass_on(still, 0, 0.0)
    assert len(frames(FRAME_MS / 1000, 1.0)) == 1000 // FRAME_MS - 1  # every frame in the hold
    parked = frames(1.0, 2.0)
    assert 19 <= len(parked) <= 21  # parked: 20 Hz
    # A wheel turning by one count, a lost frame, a status change: passed on at once.
    moved = Telemetry(seq=1, t_us=0, left=101, right=200, status=0)
    assert core.pass_on(moved, 0, 2.001) and core.pass_on(moved, 0, 2.006)
    assert core.pass_on(moved, 3, 3.5)
    # An enabled output (driving) keeps the full rate even while the wheels are still.
    core2 = running(parked_period_s=0.05, hold_s=1.0)
    core2.link_up(0.0)
    core2.on_command(3.0, 2.5, True, now_s=5.0)
    out = core2.due(5.0)
    assert out is not None and out.enable
    core2.sent(out, 5.0)
    assert all(core2.pass_on(still, 0, 5.0 + k * FRAME_MS / 1000) for k in range(40))
