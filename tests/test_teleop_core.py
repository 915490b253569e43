"""The teleop core with synthetic input streams (pure: times passed in, no Zenoh, no tty).

Pad, terminal keys, window keys and Foxglove's Teleop panel go through the same rules: a held
input drives continuously, letting go stops it, a new press is a new command stream, the ramp
never steps the velocity, and a stop the person did not make needs a fresh press.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import pytest

from autochair.commands.teleop_core import (
    PadConfig,
    Teleop,
    TeleopConfig,
    TeleopLimits,
    keys_request,
    parse_twist,
    slew,
    stick,
    twist_units,
)
from autochair.runtime.config import load_section

RATE = 20.0
PERIOD = 1.0 / RATE
PAD = PadConfig()
HELD = {PAD.enable_button}


def fresh(limits: TeleopLimits | None = None, scale: float = 0.5) -> Teleop:
    """A core whose command loop has been ticking (idle) before the test's inputs, as the
    real loop does from its start."""
    core = Teleop(limits or TeleopLimits(), scale=scale)
    assert core.tick(-PERIOD, True) is None
    return core


def ticks(t0: float, t1: float) -> list[float]:
    n = round((t1 - t0) * RATE)
    return [t0 + i * PERIOD for i in range(n + 1)]


def steps(out: list[tuple[float, tuple[float, float] | None]]) -> list[tuple[float, float, float]]:
    """(dt, |Δv|, |Δω|) between consecutive commands while sending."""
    got = [(t, c) for t, c in out if c is not None]
    return [(t1 - t0, abs(c1[0] - c0[0]), abs(c1[1] - c0[1]))
            for (t0, c0), (t1, c1) in itertools.pairwise(got)]


def test_steady_stick_with_enable_held_is_a_continuous_command() -> None:
    core = fresh(TeleopLimits())
    out = []
    for t in ticks(0.0, 3.0):  # the stick held steady: the same state, sampled every tick
        core.pad(PAD, {"lefty": -1.0, "leftx": 0.0}, HELD, t)
        out.append((t, core.tick(t, link_ok=True)))
    assert all(c is not None and c[0] > 0 for _, c in out[1:]), "a gap in the command"
    assert core.presses == 1  # one hold, one stream
    assert out[-1][1] == pytest.approx((0.6 * PAD.scale, 0.0))  # ramped up to the target
    # The ramp: no step beyond accel·dt.
    assert max(dv for _, dv, _ in steps(out)) <= 0.6 * PERIOD + 1e-9


def test_enable_released_stops_within_one_period() -> None:
    core = fresh(TeleopLimits())
    for t in ticks(0.0, 1.0):
        core.pad(PAD, {"lefty": -0.8}, HELD, t)
        assert core.tick(t, True)
    released = 1.0 + PERIOD
    core.pad(PAD, {"lefty": -0.8}, set(), released)  # the stick still pushed, enable let go
    assert core.tick(released, True) == (0.0, 0.0)  # the very sample that saw the release
    assert core.tick(released + PERIOD, True) is None  # then silence: the chair's timeout holds
    assert core.deadman_stops == 1
    # Holding the stick without enable never drives.
    for t in ticks(released + PERIOD, 2.0):
        core.pad(PAD, {"lefty": -1.0}, set(), t)
        assert core.tick(t, True) is None


def test_pad_stops_when_it_stops_reporting() -> None:
    """A hung or unplugged pad reader: the last sample goes stale after the deadman."""
    core = fresh(TeleopLimits(deadman_s=0.25))
    core.pad(PAD, {"lefty": -1.0}, HELD, 0.0)
    out = {round(t, 2): core.tick(t, True) for t in ticks(0.0, 0.5)}
    assert out[0.2] is not None and out[0.25] == (0.0, 0.0) and out[0.3] is None


def test_keyboard_600ms_first_repeat_then_30hz_is_continuous_and_stops_by_03s() -> None:
    core = fresh(TeleopLimits())
    presses = [0.2, *[0.8 + i / 30 for i in range(45)]]  # press, 600 ms, then 30 Hz repeats
    last = presses[-1]
    out: list[tuple[float, tuple[float, float] | None]] = []
    pending = list(presses)
    for t in ticks(0.0, 3.0):
        while pending and pending[0] <= t:
            core.key("w", 1.0, 0.0, pending.pop(0))
        out.append((t, core.tick(t, True)))
    during = [c for t, c in out if presses[0] <= t <= last]
    assert during and all(c is not None and c[0] > 0 for c in during), \
        "stop-go: a zero or a gap before the first repeat"
    assert core.presses == 1
    stop_t = next(t for t, c in out if t > last and c == (0.0, 0.0))
    assert stop_t - last <= 0.3, f"stopped {stop_t - last:.3f} s after the last repeat"
    assert all(c is None for t, c in out if t > stop_t)


def test_a_key_tap_drives_only_for_the_first_repeat_window() -> None:
    core = fresh(TeleopLimits(first_repeat_s=0.7))
    core.key("w", 1.0, 0.0, 0.0)
    out = [(t, core.tick(t, True)) for t in ticks(0.0, 1.0)]
    stop_t = next(t for t, c in out if c == (0.0, 0.0))
    assert all(c is not None for t, c in out if t < stop_t)
    assert 0.7 - 1e-9 <= stop_t <= 0.7 + PERIOD + 1e-9


def test_a_different_key_continues_the_stream_and_space_stops_at_once() -> None:
    core = fresh(TeleopLimits(accel_mps2=math.inf, omega_accel_radps2=math.inf,
                               decel_mps2=math.inf, omega_decel_radps2=math.inf))
    core.scale = 1.0
    core.key("w", 1.0, 0.0, 0.0)
    assert core.tick(0.0, True) == (0.6, 0.0)
    core.key("a", 0.0, 1.0, 0.5)  # another key: the terminal repeats this one now
    assert core.tick(0.5, True) == (0.0, 0.8)
    assert core.tick(1.1, True) == (0.0, 0.8)  # its own first-repeat window
    assert core.presses == 1
    core.release("terminal")  # space
    assert core.tick(1.15, True) == (0.0, 0.0)


def test_window_keys_combine_and_stop_on_release() -> None:
    assert keys_request({"w", "a"}) == (1.0, 1.0)
    assert keys_request({"w", "s"}) == (0.0, 0.0)
    assert keys_request({"t"}) is None and keys_request(set()) is None
    core = fresh(TeleopLimits())
    v, w = keys_request({"w"}) or (0.0, 0.0)
    for t in ticks(0.0, 1.0):
        core.hold("window", v, w, t, True)
        assert core.tick(t, True) is not None
    core.hold("window", 0.0, 0.0, 1.05, False)  # key-up
    assert core.tick(1.05, True) == (0.0, 0.0)


def test_ramp_never_steps_and_reversal_passes_through_zero() -> None:
    lim = TeleopLimits()
    core = fresh(lim, scale=1.0)
    out = []
    for t in ticks(0.0, 4.0):
        v = 1.0 if t < 2.0 else -1.0  # full forward, then full reverse, enable held
        core.pad(PAD, {"lefty": -v}, HELD | {PAD.turbo_button}, t)
        out.append((t, core.tick(t, True)))
    vs = [c[0] for _, c in out if c is not None]
    assert max(vs) == pytest.approx(0.6) and min(vs) == pytest.approx(-0.3)  # turbo = caps
    for dt, dv, _ in steps(out):
        assert dv <= lim.decel_mps2 * dt + 1e-9
    after = [c[0] for t, c in out if t >= 2.0 and c is not None]
    assert all(b <= a for a, b in itertools.pairwise(after))  # down through zero
    assert core.presses == 1


def test_slew_rates() -> None:
    assert slew(0.0, 1.0, 0.5, 1.0, 0.1) == pytest.approx(0.05)
    assert slew(0.5, 0.0, 0.5, 1.0, 0.1) == pytest.approx(0.4)  # slowing: the faster rate
    # A reversal: 0.05 s to slow to zero, then 0.05 s speeding up the other way.
    assert slew(0.05, -1.0, 0.5, 1.0, 0.1) == pytest.approx(-0.025)
    assert slew(0.6, -0.3, math.inf, math.inf, 0.05) == -0.3  # no ramp: straight there
    assert slew(0.0, -1.0, 0.5, 1.0, 0.1) == pytest.approx(-0.05)
    assert slew(0.3, 0.35, 0.5, 1.0, 0.1) == pytest.approx(0.35)
    assert slew(0.2, 1.0, math.inf, 1.0, 0.0) == 1.0


def test_dead_zone_is_continuous() -> None:
    assert stick(0.1, 0.15) == 0.0 and stick(-0.15, 0.15) == 0.0
    assert stick(0.16, 0.15) == pytest.approx(0.01 / 0.85)  # just outside: just above zero
    assert stick(1.0, 0.15) == 1.0 and stick(-1.0, 0.15) == -1.0
    assert stick(-1.0, 0.15, invert=True) == 1.0  # SDL: stick up is negative
    assert stick(math.nan, 0.15) == 0.0


def test_turbo_stays_within_the_caps() -> None:
    core = fresh(TeleopLimits(max_v_mps=0.6, max_omega_radps=0.8, accel_mps2=math.inf,
                               omega_accel_radps2=math.inf))
    core.pad(PAD, {"lefty": -1.0, "leftx": -1.0}, HELD, 0.0)
    assert core.tick(0.0, True) == pytest.approx((0.3, 0.4))  # scale 0.5
    core.pad(PAD, {"lefty": -5.0, "leftx": -5.0}, HELD | {PAD.turbo_button}, 0.05)
    assert core.tick(0.05, True) == pytest.approx((0.6, 0.8))  # turbo: the caps, no more


def test_estop_button_stops_and_needs_a_fresh_press() -> None:
    core = fresh(TeleopLimits())
    for t in ticks(0.0, 0.5):
        core.pad(PAD, {"lefty": -1.0}, HELD, t)
        core.tick(t, True)
    core.pad(PAD, {"lefty": -1.0}, HELD | {PAD.estop_button}, 0.55)
    assert core.estop_presses == 1
    assert core.tick(0.55, True) == (0.0, 0.0)
    for t in ticks(0.6, 1.5):  # e-stop button held, then let go; enable held all along
        core.pad(PAD, {"lefty": -1.0}, HELD | ({PAD.estop_button} if t < 1.0 else set()), t)
        assert core.tick(t, True) is None, "drove on after the e-stop without a new press"
    assert core.estop_presses == 1 and core.waiting_for_release  # one press, one e-stop
    core.pad(PAD, {}, set(), 1.55)  # enable let go ...
    assert core.tick(1.55, True) is None
    core.pad(PAD, {"lefty": -1.0}, HELD, 1.6)  # ... and pressed again: a new stream
    assert core.tick(1.6, True) is not None and core.presses == 2


def test_link_loss_stops_and_a_press_held_through_it_does_not_restart() -> None:
    core = fresh(TeleopLimits())
    for t in ticks(0.0, 0.5):
        core.pad(PAD, {"lefty": -1.0}, HELD, t)
        assert core.tick(t, True) is not None
    core.pad(PAD, {"lefty": -1.0}, HELD, 0.55)
    assert core.tick(0.55, link_ok=False) == (0.0, 0.0) and core.link_stops == 1
    for t in ticks(0.6, 1.5):  # the link returns at 1.0; the enable is held throughout
        core.pad(PAD, {"lefty": -1.0}, HELD, t)
        assert core.tick(t, link_ok=t >= 1.0) is None
    core.pad(PAD, {}, set(), 1.55)
    core.tick(1.55, True)
    core.pad(PAD, {"lefty": -1.0}, HELD, 1.6)
    assert core.tick(1.6, True) is not None and core.presses == 2


def test_a_press_made_while_the_link_is_down_does_not_drive_when_it_returns() -> None:
    core = fresh(TeleopLimits())
    for t in ticks(0.0, 1.0):  # pressed at 0 while the link is down, returns at 0.5
        core.pad(PAD, {"lefty": -1.0}, HELD, t)
        assert core.tick(t, link_ok=t >= 0.5) is None
    assert core.waiting_for_release and core.presses == 0
    core.pad(PAD, {}, set(), 1.05)
    core.tick(1.05, True)
    core.pad(PAD, {"lefty": -1.0}, HELD, 1.1)
    assert core.tick(1.1, True) is not None and core.presses == 1


def test_panel_stream_drives_from_its_second_message_and_stops_after_it_ends() -> None:
    core = fresh(TeleopLimits(), scale=1.0)
    sent = [round(0.1 + i * PERIOD, 3) for i in range(30)]  # 20 Hz, 1.5 s
    out: list[tuple[float, tuple[float, float] | None]] = []
    pending = list(sent)
    for t in ticks(0.0, 2.5):
        while pending and pending[0] <= t + 1e-9:
            core.message("panel:1", 1.0, 0.0, pending.pop(0))
        out.append((round(t, 3), core.tick(t, True)))
    first = next(t for t, c in out if c is not None)
    assert first == sent[1]  # a lone message never drives: the second confirms the rate
    assert all(c is not None and c[0] > 0 for t, c in out if first < t <= sent[-1])
    stop_t = next(t for t, c in out if c == (0.0, 0.0))
    assert 0 < stop_t - sent[-1] <= 0.3
    assert core.presses == 1


def test_a_slow_panel_never_lurches() -> None:
    core = fresh(TeleopLimits(), scale=1.0)
    for i in range(5):  # the panel's 1 Hz: every message alone
        core.message("panel:1", 1.0, 0.0, float(i))
        assert core.tick(float(i), True) is None
    assert core.presses == 0


def test_each_new_hold_is_a_new_stream() -> None:
    core = fresh(TeleopLimits(), scale=1.0)
    for hold in (0.0, 2.0):
        for t in ticks(hold, hold + 0.5):
            core.message("panel:1", 0.5, 0.0, t)
            core.tick(t, True)
        assert core.tick(hold + 1.0, True) == (0.0, 0.0)
    assert core.presses == 2 and core.deadman_stops == 2


def test_twist_conversion_is_clamped_to_the_limits() -> None:
    lim = TeleopLimits(max_v_mps=0.6, max_omega_radps=0.8)
    assert twist_units(0.3, 0.4, lim) == pytest.approx((0.5, 0.5))
    assert twist_units(1.0, -5.0, lim) == (1.0, -1.0)  # the panel's default 1 m/s: the cap
    assert twist_units(-0.15, 0.0, lim) == pytest.approx((-0.5, 0.0))  # reverse: half
    assert parse_twist(b'{"linear":{"x":0.3,"y":0,"z":0},"angular":{"x":0,"y":0,"z":-1}}') \
        == (0.3, -1.0)
    for bad in (b"nope", b'{"linear":{"x":"fast"},"angular":{"z":0}}', b'{"linear":{}}',
                b'{"linear":{"x":1e999},"angular":{"z":0}}', b"[]",
                b'{"linear":{"x":true},"angular":{"z":0}}'):
        assert parse_twist(bad) is None, bad


def test_config_defaults_file_and_errors(tmp_path: Path) -> None:
    cfg = TeleopConfig().validate()
    assert cfg.pad.enable_button == "leftshoulder" and cfg.pad.estop_button == "b"
    assert cfg.first_repeat_s == 0.7 and cfg.limits().deadman_s == cfg.deadman_s
    f = tmp_path / "laptop.toml"
    f.write_text("[teleop]\nmax_v_mps = 0.4\n[teleop.pad]\nenable_button = \"a\"\n"
                 "dead_zone = 0.2\n")
    cfg = load_section(TeleopConfig, "teleop", str(f), ["pad.axis_omega=rightx"]).validate()
    assert (cfg.max_v_mps, cfg.pad.enable_button, cfg.pad.dead_zone, cfg.pad.axis_omega) == \
        (0.4, "a", 0.2, "rightx")
    for bad, msg in ((TeleopConfig(deadman_s=0), "deadman_s"),
                     (TeleopConfig(pad=PadConfig(enable_button="lb")), "enable_button"),
                     (TeleopConfig(pad=PadConfig(axis_v="y")), "axis_v"),
                     (TeleopConfig(pad=PadConfig(estop_button="leftshoulder")), "three"),
                     (TeleopConfig(pad=PadConfig(turbo_scale=1.5)), "turbo_scale"),
                     (TeleopConfig(rate_hz=2.0), "rate_hz")):
        with pytest.raises(ValueError, match=msg):
            bad.validate()


def test_the_commands_refuse_a_bad_teleop_config_in_one_line(
        capsys: pytest.CaptureFixture[str]) -> None:
    from autochair.cli import main

    assert main(["teleop", "--set", "pad.enable_button=lb"]) == 2
    assert "[teleop.pad] enable_button must be one of" in capsys.readouterr().err
    assert main(["foxglove", "--deadman", "0"]) == 2
    assert "[teleop] deadman_s must be > 0" in capsys.readouterr().err
