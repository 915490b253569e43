"""PID and velocity-controller core: anti-windup, saturation, filtering, stale desired."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import pytest

from autochair.pid.core import (
    PID,
    SAFETY_STOPPED,
    Caps,
    Command,
    Feedforward,
    GapFill,
    VelocityPidCore,
    Verdict,
    effort_to_volts,
)
from autochair.tune.core import ChainModel, Probe, ProbeKind, ProbeState
from autochair_msgs import keys

DT = 1.0 / keys.DRIVE_RATE_HZ  # the PID runs once per odometry sample
HALF_S = round(0.5 / DT)  # samples in 0.5 s


def test_proportional_and_integral() -> None:
    pid = PID(kp=2.0, ki=1.0, kd=0.0, out_min=-10, out_max=10)
    assert pid.update(1.0, 0.0, 0.1) == pytest.approx(2.0 + 0.1)
    assert pid.update(1.0, 0.0, 0.1) == pytest.approx(2.0 + 0.2)


def test_no_derivative_kick_on_setpoint_step() -> None:
    pid = PID(kp=1.0, ki=0.0, kd=5.0, out_min=-100, out_max=100)
    pid.update(0.0, 0.0, 0.01)
    assert pid.update(10.0, 0.0, 0.01) == pytest.approx(10.0)  # only P: D acts on measurement


def test_derivative_on_measurement_is_filtered() -> None:
    pid = PID(kp=1.0, ki=0.0, kd=1.0, out_min=-100, out_max=100, d_filter_n=10)
    pid.update(0.0, 0.0, 0.01)
    out = pid.update(0.0, 0.01, 0.01)  # raw derivative −1 → filtered by α = 0.01/(0.1+0.01)
    assert out == pytest.approx(-0.01 - 1.0 * (0.01 / 0.11), rel=1e-6)


def test_anti_windup_recovers_quickly() -> None:
    pid = PID(kp=0.5, ki=2.0, kd=0.0, out_min=-1, out_max=1)
    for _ in range(1000):  # 10 s saturated against an unreachable setpoint
        assert pid.update(10.0, 0.0, 0.01) == 1.0
    assert pid.integral <= 1.0
    # Once the error reverses the output leaves saturation at once, not after unwinding 10 s.
    assert pid.update(0.0, 1.0, 0.01) < 0.6


def test_output_is_saturated() -> None:
    pid = PID(kp=100.0, ki=0.0, kd=0.0, out_min=-0.5, out_max=0.7)
    assert pid.update(1.0, 0.0, 0.01) == 0.7
    assert pid.update(-1.0, 0.0, 0.01) == -0.5


def test_bumpless_reset() -> None:
    pid = PID(kp=1.0, ki=1.0, kd=1.0, out_min=-1, out_max=1)
    pid.reset(measurement=0.3, output=0.4)
    assert pid.update(0.3, 0.3, 0.01) == pytest.approx(0.4)


def test_dt_must_be_positive() -> None:
    with pytest.raises(ValueError):
        PID(1, 1, 1).update(0, 0, 0.0)


def test_effort_maps_to_thesis_voltage_and_clamps() -> None:
    assert effort_to_volts(0.0) == 2.5
    assert effort_to_volts(0.5) == pytest.approx(3.25)
    assert effort_to_volts(1.0) == 3.9  # 4.0 V clamped to the window
    assert effort_to_volts(-1.0) == 1.1


def cmd(v: float, w: float, t: float, source: str = "autonomy", began: float = 0.0) -> Command:
    """A command stamped at t (s) from a stream begun at `began` (s); the core starts at 0.
    (Both 1 ns later: a stream begun at a stop's instant begins after it, and is stamped no
    earlier than it began.)"""
    return Command(v, w, source, ns(t) + 1, ns(began) + 1)


def ns(t: float) -> int:
    return round(t * 1e9)


def core_(**kw: Any) -> VelocityPidCore:
    """A core as the node makes it, with the e-stop heard as released at t = 0."""
    core = VelocityPidCore(**kw)
    core.set_estop(False, 0.0, 0)
    return core


def drive(core: VelocityPidCore, v: float, w: float, t: float, source: str = "autonomy",
          began: float = 0.0) -> Verdict:
    return core.set_desired(cmd(v, w, t, source, began), t, ns(t))


def test_stale_desired_gives_exact_neutral() -> None:
    core = core_(stale_s=0.3)
    assert drive(core, 0.5, 0.0, 0.0) is Verdict.OK
    out = core.update(0.0, 0.0, DT, 0.1, ns(0.1))
    assert out.active and out.longitudinal_v > 2.5 and out.desired == (0.5, 0.0)
    out = core.update(0.0, 0.0, DT, 0.31, ns(0.31))
    assert not out.active
    assert (out.longitudinal_v, out.angular_v, out.v_effort) == (2.5, 2.5, 0.0)
    assert out.desired == (0.0, 0.0)


def test_stale_is_judged_one_sample_ahead() -> None:
    """A stream that would be stale by the next odometry sample is stale now: neutral no later
    than stale_s after the last command, whatever the sample rate."""
    core = core_(stale_s=0.3)
    drive(core, 0.5, 0.0, 0.0)
    assert core.update(0.0, 0.0, DT, 0.3 - 1.5 * DT, ns(0.3 - 1.5 * DT)).active  # control
    assert not core.update(0.0, 0.0, DT, 0.3 - 0.5 * DT, ns(0.3 - 0.5 * DT)).active
    assert core.stop_reason == "command stream stale"


def test_never_commanded_is_neutral() -> None:
    out = core_().update(0.0, 0.0, DT, 0.1, ns(0.1))
    assert (out.longitudinal_v, out.angular_v, out.active) == (2.5, 2.5, False)


def test_parked_is_exact_neutral_and_integrator_cleared() -> None:
    core = core_()
    for i in range(HALF_S):
        drive(core, 0.5, 0.0, i * DT)
        core.update(0.1, 0.0, DT, i * DT, ns(i * DT))
    assert core.v_pid.integral > 0
    drive(core, 0.0, 0.0, 0.5)
    out = core.update(0.0, 0.0, DT, 0.5, ns(0.5))
    assert (out.longitudinal_v, out.angular_v) == (2.5, 2.5)
    assert core.v_pid.integral == 0.0


def test_non_finite_desired_is_rejected() -> None:
    core = core_()
    assert drive(core, float("nan"), 0.0, 0.0) is Verdict.REJECTED
    assert core.desired(0.0, 0) is None


def test_thesis_gains_are_default() -> None:
    core = VelocityPidCore()
    assert (core.v_pid.kp, core.v_pid.ki, core.v_pid.kd) == (0.90, 1.03, 0.20)
    assert (core.omega_pid.kp, core.omega_pid.ki, core.omega_pid.kd) == (0.72, 1.08, 0.12)


def test_only_the_owner_drives() -> None:
    core = core_()
    assert drive(core, 0.5, 0.0, 0.0, source="teleop") is Verdict.NOT_OWNER
    assert core.desired(0.0, 0) is None
    assert drive(core, 0.5, 0.0, 0.0) is Verdict.OK
    assert core.set_owner("teleop", ns(0.1))
    assert core.desired(0.1, ns(0.1)) is None  # autonomy's last command no longer counts
    # The owner change is a stop: teleop's stream must begin after it (a fresh press).
    assert drive(core, 0.2, 0.1, 0.2, source="teleop") is Verdict.BEFORE_STOP
    assert drive(core, 0.2, 0.1, 0.2, source="teleop", began=0.15) is Verdict.OK
    assert drive(core, 0.9, 0.0, 0.2, source="autonomy", began=0.15) is Verdict.NOT_OWNER
    assert core.desired(0.2, ns(0.2)) == (0.2, 0.1)
    assert not core.set_owner("someone", ns(0.2))


def test_safety_limit_clamps_and_may_be_required() -> None:
    core = core_(require_limit=True, limit_stale_s=0.5)
    drive(core, 1.0, 1.0, 0.0)
    assert core.desired(0.0, 0) is None  # required but never received: a stop
    assert "no fresh safety limit" in core.inhibit(0.0)
    assert core.set_limit(0.3, 0.2, 0.5, 0.0, v_rev_autonomy=0.1)
    assert drive(core, 1.0, 1.0, 0.1, began=0.05) is Verdict.OK
    assert core.desired(0.1, ns(0.1)) == (0.3, 0.3)  # both slowed by one factor (H64)
    drive(core, -1.0, -1.0, 0.2, began=0.05)
    assert core.desired(0.2, ns(0.2)) == (-0.1, -0.1)  # autonomy: the sensed reverse bound
    drive(core, -1.0, -1.0, 0.5, began=0.05)
    assert core.desired(0.51, ns(0.51)) is None  # limit stale
    assert not core.set_limit(float("nan"), 0, 0, 0)


def test_a_limit_delivered_late_is_not_fresh() -> None:
    """H38 at the PID: a limit is judged by its own stamp, not by when it arrived."""
    core = core_(require_limit=True, limit_stale_s=0.5, skew_s=0.1)
    assert core.set_limit(1.0, 0.5, 1.0, 0.0, age_s=0.02)  # positive control
    assert drive(core, 0.5, 0.0, 0.1, began=0.05) is Verdict.OK
    assert core.desired(0.1, ns(0.1)) == (0.5, 0.0)
    for age in (0.51, 3.0, -0.11):  # late (a backlog), or from the future
        assert not core.set_limit(1.0, 0.5, 1.0, 0.4, age_s=age)
    assert drive(core, 0.5, 0.0, 0.55, began=0.05) is Verdict.OK  # the stream goes on
    assert core.desired(0.6, ns(0.6)) is None  # the last fresh limit went stale: a stop
    assert "safety" in core.stop_reason


def test_teleop_reverses_within_the_attended_bound_autonomy_not_at_all() -> None:
    core = core_(require_limit=True)
    core.set_limit(1.0, 0.4, 1.0, 0.0)  # no rear sensor: autonomy may not reverse
    assert drive(core, -0.3, 0.0, 0.0) is Verdict.OK
    assert core.desired(0.0, 0) is None and "safety stop" in core.inhibit(0.0)
    # (what the control service ends its goal on: control/core.py _watch_progress)
    assert core.inhibit(0.0).startswith(SAFETY_STOPPED)
    core.set_limit(0.0, 0.4, 0.0, 0.0)
    assert core.inhibit(0.0) == "the safety monitor says stop"
    core.set_owner("teleop", ns(0.01))
    drive(core, -0.6, 0.0, 0.02, source="teleop", began=0.015)
    assert core.desired(0.02, ns(0.02)) == (-0.4, 0.0)


def test_absolute_caps_whatever_the_source() -> None:
    core = core_(caps=Caps(0.8, 0.3, 0.6))
    drive(core, 2.0, -3.0, 0.0)  # each axis within its cap, on the arc sent (H64)
    assert core.desired(0.0, 0) == pytest.approx((0.4, -0.6))
    core.set_owner("teleop", ns(0.01))
    drive(core, -2.0, 3.0, 0.02, source="teleop", began=0.015)
    assert core.desired(0.02, ns(0.02)) == pytest.approx((-0.3, 0.45))


# --- no unexpected start-up: one test per kind of stop --------------------------------------
def driving_core(**kw: Any) -> VelocityPidCore:
    """A core obeying a stream begun at t = 0, driving at 0.5 m/s until t = 1 s."""
    core = core_(**kw)
    for i in range(2 * HALF_S):
        t = i * DT
        core.set_estop(False, t, ns(t))
        if core.require_limit:
            core.set_limit(1.0, 0.5, 1.0, t, 0.5)
        assert drive(core, 0.5, 0.0, t) is Verdict.OK
        assert core.update(0.4, 0.0, DT, t, ns(t)).active
    return core


def continue_old_stream(core: VelocityPidCore, t0: float) -> list[bool]:
    """The old stream simply goes on (estop released, odometry flowing): is it obeyed?"""
    active = []
    for i in range(HALF_S):
        t = t0 + i * DT
        core.set_estop(False, t, ns(t))
        core.set_limit(1.0, 0.5, 1.0, t, 0.5)
        drive(core, 0.5, 0.0, t)
        active.append(core.update(0.0, 0.0, DT, t, ns(t)).active)
    return active


STOPS: dict[str, Callable[[VelocityPidCore, float], object]] = {
    "estop latch and release": lambda c, t: c.set_estop(True, t, ns(t)),
    "estop service gone": lambda c, t: c.estop_gone(ns(t)),
    "owner change and back": lambda c, t: (c.set_owner("teleop", ns(t)),
                                           c.set_owner("autonomy", ns(t))),
    "gateway lost": lambda c, t: c.stop("gateway lost", ns(t)),
    "safety monitor gone": lambda c, t: c.limit_gone(ns(t)),
    "safety stop": lambda c, t: (c.set_limit(0.0, 0.0, 0.0, t),
                                 c.update(0.4, 0.0, DT, t, ns(t)),
                                 c.set_limit(1.0, 0.5, 1.0, t + 0.01, 0.5)),
    "odometry gap": lambda c, t: c.update(0.0, 0.0, DT, t + 0.5, ns(t + 0.5)),
    "non-finite measurement": lambda c, t: c.update(float("nan"), 0.0, DT, t, ns(t)),
    "chair MCU restarted": lambda c, t: c.update(0.0, 0.0, DT, t, ns(t), link=(1, 0)),
    "serial link renewed": lambda c, t: c.update(0.0, 0.0, DT, t, ns(t), link=(0, 1)),
    "odometry lost": lambda c, t: c.stop("odometry lost", ns(t)),
}


@pytest.mark.parametrize("kind", list(STOPS))
def test_after_a_stop_only_a_stream_begun_later_drives(kind: str) -> None:
    core = driving_core(require_limit=kind in ("safety stop", "safety monitor gone"))
    assert continue_old_stream(driving_core(), 1.0) == [True] * HALF_S  # positive control
    STOPS[kind](core, 1.0)
    assert core.obeying is False and core.stop_reason != "started"
    assert not any(continue_old_stream(core, 1.6))  # the old stream goes on: refused
    t = 2.15  # (the old stream's odometry ran to 2.1 − DT: no gap)
    core.set_estop(False, t, ns(t))
    core.set_limit(1.0, 0.5, 1.0, t, 0.5)
    assert drive(core, 0.5, 0.0, t, began=2.12) is Verdict.OK  # a new act after the stop
    assert core.update(0.0, 0.0, DT, t, ns(t)).active


def test_a_stream_begun_as_the_last_one_went_stale_drives_and_the_last_one_never() -> None:
    """A goal sent just as the previous one's stream fell silent: its stream began after the
    old one's last command, its first command came after the stale stop. Stopped as of the
    stop's instant, that stream was refused for ever (the goal aborted "does not follow")."""
    core = core_(stale_s=0.3)
    assert drive(core, 0.5, 0.0, 0.0) is Verdict.OK  # the old stream's last command, at 0
    assert not core.update(0.0, 0.0, DT, 0.31, ns(0.31)).active
    assert core.stop_reason == "command stream stale"
    assert drive(core, 0.5, 0.0, 0.32) is Verdict.BEFORE_STOP  # the old stream goes on: never
    assert drive(core, 0.5, 0.0, 0.32, began=0.29) is Verdict.OK  # begun since its last word
    assert core.update(0.0, 0.0, DT, 0.32, ns(0.32)).active


def test_restarted_core_obeys_nothing_begun_before_it_started() -> None:
    core = core_(start_ns=ns(5.0))
    core.set_estop(False, 5.0, ns(5.0))
    assert drive(core, 0.5, 0.0, 5.0, began=4.0) is Verdict.BEFORE_STOP
    assert drive(core, 0.5, 0.0, 5.0, began=5.0) is Verdict.OK


def test_estop_silent_is_a_stop() -> None:
    core = driving_core()
    assert not core.update(0.4, 0.0, DT, 1.6, ns(1.6)).active  # no e-stop state for 0.6 s
    assert "e-stop silent" in core.inhibit(1.6)


def test_old_and_future_stamps_are_rejected() -> None:
    core = core_(stale_s=0.3, skew_s=0.1)
    now = ns(10.0)
    assert core.set_desired(Command(0.5, 0, "autonomy", now - ns(0.31), 1), 10.0, now) \
        is Verdict.OLD
    assert core.set_desired(Command(0.5, 0, "autonomy", now + ns(0.11), 1), 10.0, now) \
        is Verdict.FUTURE
    assert core.set_desired(Command(0.5, 0, "autonomy", now - ns(0.2), 1), 10.0, now) \
        is Verdict.OK


def obeyed_across_an_estop(t0: float, latched: tuple[float, float], stamps_ahead: float,
                           began: float) -> list[bool]:
    """1.5 s of a stream of 0.5 m/s from t0 (s, the core's clock), the e-stop latched over
    [latched), its commands stamped `stamps_ahead` s on the sender's clock and begun at
    `began` by it: whether the core obeyed it, sample by sample."""
    core, obeyed = core_(), []
    for i in range(3 * HALF_S):
        t = t0 + i * DT
        core.set_estop(latched[0] <= t < latched[1], t, ns(t))
        core.set_limit(1.0, 0.5, 1.0, t, 0.5)
        core.set_desired(cmd(0.5, 0.0, t + stamps_ahead, began=began), t, ns(t))
        obeyed.append(core.update(0.3, 0.0, DT, t, ns(t)).active)
    return obeyed


def test_a_stream_begun_after_its_own_stamp_is_refused_so_no_stop_can_be_outlived() -> None:
    """H49: the sender's clock stepped back 5 s mid-stream (or a bug): its stream's start lies
    after its commands' stamps, so it would pass for a stream begun after any stop of the
    next 5 s and drive on through an e-stop latched and released."""
    def run(began: float) -> list[bool]:  # latched at 0.5 s, released at 0.6 s
        return obeyed_across_an_estop(0.0, (0.5, 0.6), stamps_ahead=0.0, began=began)

    honest = run(0.0)  # positive control: begun at 0, the stream drives until the latch
    assert all(honest[:HALF_S - 1]) and not any(honest[HALF_S + 1:])
    assert not any(run(5.0)), "a stream begun 'in the future' outlived the e-stop"
    core = core_()
    assert core.set_desired(Command(0.5, 0.0, "autonomy", ns(1.0), ns(1.0) + 1), 1.0, ns(1.0)) \
        is Verdict.STREAM_AHEAD


def test_a_stream_known_at_a_stop_never_drives_after_it_whatever_the_senders_clock() -> None:
    """H49: a laptop's clock 0.09 s ahead (within the 0.1 s skew allowed): its stream, begun
    0.03 s before a momentary e-stop, claims to have begun 0.06 s after it."""

    def run(ahead: float) -> list[bool]:  # begun at 0.97; latched at 1.0, released a tick on
        return obeyed_across_an_estop(0.97, (1.0 - DT / 2, 1.0 + DT / 2), stamps_ahead=ahead,
                                      began=0.97 + ahead)

    assert any(run(0.0)[:3]) and not any(run(0.0)[3:])  # in sync: driven, then never again
    assert not any(run(0.09)[3:]), "the stream drove on after the release"
    core = core_()  # a new act after the stop, from the laptop ahead, drives
    core.set_estop(True, 1.0, ns(1.0))
    core.set_estop(False, 1.01, ns(1.01))
    core.set_limit(1.0, 0.5, 1.0, 1.2, 0.5)
    assert core.set_desired(cmd(0.5, 0.0, 1.2 + 0.09, began=1.15 + 0.09), 1.2, ns(1.2)) \
        is Verdict.OK


def test_two_streams_on_one_key_are_never_mixed_and_the_older_never_drives_again() -> None:
    """H37: a goal's stream and `autochair drive` (or two teleop laptops) on one key."""
    core = core_(stale_s=0.3)
    older, newer = 1.0, 2.0  # when each stream's deliberate act began
    obeyed = []
    for i in range(10):  # positive control: the older stream alone drives
        t = 3.0 + i * DT
        obeyed.append(drive(core, 0.2, 0.0, t, began=older))
    assert obeyed == [Verdict.OK] * 10
    obeyed = []
    for i in range(10):  # both interleaved: the newer takes over, the older is refused
        t = 3.1 + i * DT
        obeyed.append(drive(core, 0.2, 0.0, t, began=older))
        obeyed.append(drive(core, 0.9, 0.0, t + DT / 2, began=newer))
    assert obeyed[:2] == [Verdict.OK, Verdict.TOOK_OVER]
    assert set(obeyed[2::2]) == {Verdict.SUPERSEDED} and set(obeyed[3::2]) == {Verdict.OK}
    assert core.desired(3.2, ns(3.2)) == pytest.approx((0.9, 0.0))
    # The newer stream ends (its person let go): the older one never drives again.
    assert core.desired(3.6, ns(3.6)) is None and not core.obeying
    assert drive(core, 0.2, 0.0, 3.7, began=older) is Verdict.BEFORE_STOP
    assert drive(core, 0.2, 0.0, 3.8, began=3.75) is Verdict.OK  # a new act drives


def test_non_finite_measurement_does_not_poison_the_integrators() -> None:
    core = driving_core()
    core.update(float("inf"), 0.0, DT, 1.0, ns(1.0))
    assert math.isfinite(core.v_pid.integral) and core.v_pid.integral == 0.0
    out = core.update(0.0, 0.0, float("nan"), 1.0 + DT, ns(1.0 + DT))
    assert (out.longitudinal_v, out.angular_v) == (2.5, 2.5)


# --- feed-forward, saturation, tuning probes (autochair tune) ---------------------------------

MODEL = ChainModel(1.85, 0.05, 0.36, 0.36, 0.37)


def test_saturation_is_decided_in_the_core() -> None:
    core = core_(v_gains=(5.0, 0.0, 0.0))
    drive(core, 1.0, 0.0, 0.0)
    out = core.update(0.0, 0.0, DT, DT, ns(DT))
    assert out.saturated and out.longitudinal_v == pytest.approx(3.9)
    gentle = core_(v_gains=(0.1, 0.0, 0.0))  # positive control: far from the window's edge
    drive(gentle, 1.0, 0.0, 0.0)
    assert not gentle.update(0.0, 0.0, DT, DT, ns(DT)).saturated


def test_feedforward_holds_the_model_effort_and_feedback_only_trims() -> None:
    """On a chair that is exactly the model, the feed-forward alone holds the setpoint: the
    feedback sees no error (its reference is the model's own response)."""
    core = core_(v_gains=(0.5, 0.7, 0.1), v_model=MODEL)
    ff = Feedforward(MODEL, core.prefilter_s)  # a twin: the "chair" is the model itself
    y = 0.0
    out = None
    for i in range(1, 12 * HALF_S):  # 6 s
        t = i * DT
        core.set_estop(False, t, ns(t))
        drive(core, 0.5, 0.0, t)
        out = core.update(y, 0.0, DT, t, ns(t))
        y = ff.reference(out.v_effort, DT)
    assert out is not None and out.active
    assert y == pytest.approx(0.5, abs=1e-3)
    assert out.v_effort == pytest.approx(MODEL.effort_for(0.5), abs=1e-3)
    assert abs(core.v_pid.integral) < 1e-3  # the integrator had nothing to do


def test_the_prefilter_is_governed_by_the_effort_window() -> None:
    """Where the inverse would leave the effort window, the prefilter advances only as far as
    the window allows (it does not run ahead of a saturated chair); inside it, nothing changes."""
    free, governed = Feedforward(MODEL, 0.15), Feedforward(MODEL, 0.15)
    u_free = [free.effort(0.5, DT) for _ in range(HALF_S)]
    u_gov = [governed.effort(0.5, DT, -0.9, 0.9) for _ in range(HALF_S)]
    assert max(u_free) > 1.0  # positive control: the plain inverse asks for more than 0.9
    assert max(u_gov) == pytest.approx(0.9) and u_gov[0] == pytest.approx(0.9)
    assert governed._x2 < free._x2  # the governed reference waits for the chair
    for _ in range(12 * HALF_S):  # ... and still arrives, at the effort that holds 0.5
        u = governed.effort(0.5, DT, -0.9, 0.9)
    assert governed._x2 == pytest.approx(0.5, abs=1e-3) and u == pytest.approx(
        MODEL.effort_for(0.5), abs=1e-3)
    small, plain = Feedforward(MODEL, 0.15), Feedforward(MODEL, 0.15)
    assert [small.effort(0.05, DT, -0.9, 0.9) for _ in range(HALF_S)] == \
        [plain.effort(0.05, DT) for _ in range(HALF_S)]  # inside the window: the same


def test_the_sample_that_starts_a_drive_advances_one_period() -> None:
    """A parked chair's samples come every 50 ms (the gateway idles the chain): the sample
    that starts a drive carries that as its dt, but its output acts for one period. The
    first outputs are those of a drive started on a 10 ms sample (measured through the
    processes before: the 0.5 step settled in 1.6-1.8 s instead of 1.16 s)."""
    def first_efforts(first_dt: float, period_s: float = DT) -> list[float]:
        core = core_(v_model=MODEL, period_s=period_s)
        out = []
        for i in range(20):
            t = 0.1 + i * DT
            core.set_estop(False, t, ns(t))
            drive(core, 0.5, 0.0, t)
            out.append(core.update(0.0, 0.0, first_dt if i == 0 else DT, t, ns(t)).v_effort)
        return out

    assert first_efforts(0.05) == pytest.approx(first_efforts(DT))
    # positive control: without the bound the prefilter leaves the window's edge sooner
    assert sum(first_efforts(0.05, 1.0)) < sum(first_efforts(DT)) - 0.05


def test_without_a_model_the_loop_is_the_thesis_pid() -> None:
    plain, modelled = core_(), core_(v_model=MODEL)
    for core in (plain, modelled):
        drive(core, 0.5, 0.0, 0.0)
    a = plain.update(0.0, 0.0, DT, DT, ns(DT)).v_effort
    b = modelled.update(0.0, 0.0, DT, DT, ns(DT)).v_effort
    assert a == pytest.approx(0.9 * 0.5 + 1.03 * 0.5 * DT)  # Kp·e + Ki·e·dt
    assert b != pytest.approx(a)  # positive control: the model changes the first output


def test_a_stale_stream_aborts_a_probe_and_stops() -> None:
    core = driving_core()
    assert core.start_probe(Probe(ProbeKind.RELAY, "longitudinal", 0.2), 1.0) == ""
    out = core.update(0.5, 0.0, DT, 1.0 + DT, ns(1.0 + DT))
    assert out.active and out.probe == "relay longitudinal"
    for i in range(2, HALF_S):  # e-stop and odometry fresh, no command for 0.5 s
        t = 1.0 + i * DT
        core.set_estop(False, t, ns(t))
        out = core.update(0.5, 0.0, DT, t, ns(t))
    assert not out.active and out.longitudinal_v == 2.5
    assert core.probe is not None and core.probe.is_(ProbeState.ABORTED)
    assert "stale" in core.probe.reason


def test_a_limit_that_leaves_only_a_creep_of_turn_is_a_safety_stop() -> None:
    """H03: a goal curving gently (ω 0.01 rad/s) meets a person ahead: the monitor's forward
    bound goes to 0 and the chair stands (turning 0.6°/s). It was no stop because ω was not
    zero, so when the person walked away the old stream drove on at 0.5 m/s by itself."""
    def run(w: float) -> tuple[list[tuple[float, float] | None], list[bool]]:
        core = driving_core(require_limit=True)
        held = []
        for i in range(HALF_S):  # the person ahead: forward bound 0, turning free
            t = 1.0 + i * DT
            core.set_estop(False, t, ns(t))
            core.set_limit(0.0, 0.5, 1.0, t, 0.5)
            drive(core, 0.5, w, t)
            held.append(core.desired(t, ns(t)))
            core.update(0.0, w, DT, t, ns(t))
        after = []
        for i in range(HALF_S):  # the person gone: the same stream goes on
            t = 1.5 + i * DT
            core.set_estop(False, t, ns(t))
            core.set_limit(1.0, 0.5, 1.0, t, 0.5)
            drive(core, 0.5, w, t)
            after.append(core.update(0.0, w, DT, t, ns(t)).active)
        return held, after

    held, after = run(0.01)
    assert held[0] is None and not any(after)  # a stop: the old stream never drives again
    # Positive control: a visible turn in place (0.3 rad/s) is motion the limit allows, not a
    # stop; the stream drives on (the chair never stood still).
    held, after = run(0.3)
    assert held[0] == (0.0, 0.3) and all(after)


def test_the_output_tells_the_feed_forward_from_the_feedback() -> None:
    """PidOutput.feedforward (a lockstep trace's; not on the wire: at 100 Hz its two fields
    cost 10 MB an hour of driving, measured, and the recorded desired velocity and the
    model give it again): on a chair that is the model the effort is the
    feed-forward alone; on one that does not move the feedback adds to it (positive
    control); an axis without a model has none."""
    def run(follows: bool, model: ChainModel | None) -> list[tuple[float, float]]:
        core = core_(v_model=model, v_gains=(0.5, 0.7, 0.1))
        twin = Feedforward(MODEL, core.prefilter_s)
        y, rows = 0.0, []
        for i in range(1, 3 * HALF_S):
            t = i * DT
            core.set_estop(False, t, ns(t))
            core.set_desired(Command(0.3, 0.0, "autonomy", ns(t), 1), t, ns(t))
            out = core.update(y, 0.0, DT, t, ns(t))
            rows.append((out.v_effort, out.feedforward[0]))
            if follows:
                y = twin.reference(out.v_effort, DT)
        return rows

    same = run(True, MODEL)
    assert max(abs(e - f) for e, f in same) < 1e-6 and max(f for _, f in same) > 0.1
    stuck = run(False, MODEL)
    assert max(e - f for e, f in stuck) > 0.05
    assert all(f == 0.0 for _, f in run(False, None))


def ramp_with_a_gap(gap_from: float | None, gap_s: float = 0.08, a: float = 1.0,
                    until: float = 0.8) -> list[tuple[float, float]]:
    """A goal's plan at `a` m/s² as the control sends it (50 Hz, stamped when sent) to a core
    whose chair is its model (the feed-forward alone drives it). From `gap_from` the samples
    wait `gap_s` while the commands come on (the gateway or odometry descheduled); then the
    waiting samples are worked through at once, the newest command in force. (the sample's
    time, the feed-forward on it) of each sample."""
    core = core_(v_gains=(0.5, 0.7, 0.1), v_model=MODEL)
    twin = Feedforward(MODEL, core.prefilter_s)
    y, u = 0.0, 0.0
    waiting: list[float] = []
    rows: list[tuple[float, float]] = []
    for i in range(1, round(until / DT)):
        t = i * DT
        core.set_estop(False, t, ns(t))
        if i % 2 == 0:
            core.set_desired(Command(a * t, 0.0, "autonomy", ns(t), 1), t, ns(t))
        waiting.append(t)
        if gap_from is None or not gap_from <= t < gap_from + gap_s:
            for taken in waiting:
                u = core.update(y, 0.0, DT, t, ns(t)).feedforward[0]
                rows.append((taken, u))
            waiting = []
        y = twin.reference(u, DT)  # (while the samples wait, the chair holds its effort)
    return rows


def test_a_gap_in_the_command_stream_gives_the_plan_late_never_harder() -> None:
    """The samples stall 80 ms under a goal's ramp: the first one after meets a command 80 ms
    on. Taken at once, that step is a feed-forward kick (the model inverse's r̈ term) the plan
    never asked for (1.15 m/s² at the chair in lockstep after three 40 ms stalls; the hazard
    test's 1.03-1.12 under load). Each sample's feed-forward stays within the smooth plan's
    around the same sample (its staircase: each 20 ms command is a small kick of its own)."""
    smooth = ramp_with_a_gap(None)
    peak = {t: max(u for _, u in smooth[max(k - 1, 0):k + 2]) for k, (t, _) in enumerate(smooth)}
    over = max(u - peak[t] for t, u in ramp_with_a_gap(0.4))
    # (the straight line across the gap runs above the staircase by half a command's step on
    # every other sample: 0.0002 effort more, later, than the plan's own 20 ms steps gave)
    assert over <= 0.001, f"{over:.3f} more effort than the smooth plan"
    # Positive control: without the gap the stream is taken as it comes (bit for bit).
    assert ramp_with_a_gap(0.4, 0.0) == smooth


def test_gap_fill_follows_a_gap_along_the_stream_and_catches_up_where_it_is_flat() -> None:
    """The reference across a gap (GapFill): one period at once, the rest on the samples'
    clock; behind by what the gap left while the stream rises; caught up over its flat part;
    slowing never held back."""
    ref = GapFill()
    stream = ns(0.0)
    v = [ref.step((0.02 * k, 0.0), ns(0.02 * k), stream, DT)[0] for k in range(1, 6)]
    assert v == pytest.approx([0.02, 0.04, 0.06, 0.08, 0.10])  # within the period: as it comes
    # The stream 0.1 s on at 1 m/s² (a stall of its sender): one period (0.02) at once, then
    # 0.01 per 10 ms sample of the 0.1 s step of 0.1 (its straight line), not 0.1 at once.
    got = [ref.step((0.2, 0.0), ns(0.2), stream, DT)[0]]
    got += [ref.step((0.2, 0.0), ns(0.2), stream, DT)[0] for _ in range(3)]
    assert got == pytest.approx([0.12, 0.13, 0.14, 0.15])
    # The stream rises on at its own pace: the reference stays behind by what is left (0.05)
    for k in range(1, 4):
        got = [ref.step((0.2 + 0.02 * k, 0.0), ns(0.2 + 0.02 * k), stream, DT)[0]]
        got += [ref.step((0.2 + 0.02 * k, 0.0), ns(0.2 + 0.02 * k), stream, DT)[0]]
        assert got[-1] == pytest.approx(0.2 + 0.02 * k - 0.05)
    # ... and catches it up where it is flat, at the gap's own slope (no new lag)
    flat = [ref.step((0.26, 0.0), ns(0.26 + 0.02 * (k // 2)), stream, DT)[0]
            for k in range(2, 8)]
    assert flat == pytest.approx([0.22, 0.23, 0.24, 0.25, 0.26, 0.26])
    # Slowing is taken at once, whatever the lag: a gap down, and the way through zero
    ref.step((0.5, 0.0), ns(0.5), stream, DT)
    assert ref.step((0.1, -0.2), ns(0.7), stream, DT) == pytest.approx((0.1, -0.02))
    assert ref.step((-0.3, 0.0), ns(0.9), stream, DT)[0] == pytest.approx(-0.3 * 0.02 / 0.2)


def test_a_streams_first_command_a_stall_after_its_start_does_not_lunge() -> None:
    """The control stalled 170 ms after a goal was accepted (the stream's start): its first
    command carried the plan 0.17 s on (0.02 m/s, usually ~0.001), the first volts 2.66
    (through the processes; the hazard test allows 2.5 ± 0.1). A stream's first command at
    its start (a deliberate step, `autochair drive`) is taken whole."""
    def first_volts(first_after: float) -> float:
        core = core_(v_model=MODEL)
        t0 = 1.0
        core.update(0.0, 0.0, DT, t0 - DT, ns(t0 - DT))  # obeying nothing
        t = t0 + first_after
        core.set_estop(False, t, ns(t))
        assert core.set_desired(Command(0.02, 0.0, "autonomy", ns(t), ns(t0)), t, ns(t)) \
            is Verdict.OK
        out = core.update(0.0, 0.0, DT, t + 0.005, ns(t + 0.005))
        assert out.active
        return out.longitudinal_v

    assert abs(first_volts(0.17) - 2.5) < 0.1
    assert first_volts(0.0) > 2.5 + 0.1  # positive control: the same step at once


@pytest.mark.parametrize("bad_dt", [float("nan"), float("inf"), -DT, 2.0])
def test_a_sample_with_an_absurd_dt_leaves_the_reference_finite(bad_dt: float) -> None:
    """A sample whose dt is not a time is skipped (neutral); the reference the next samples
    follow is not advanced by it (a NaN there would reach the volts)."""
    core = core_(v_model=MODEL)
    outs = []
    for i, dt in enumerate([DT, DT, bad_dt, DT, DT]):
        t = 0.1 + i * DT
        core.set_estop(False, t, ns(t))
        drive(core, 0.5, 0.2, t)
        outs.append(core.update(0.0, 0.0, dt, t, ns(t)))
    assert not outs[2].active
    assert all(math.isfinite(v) for o in outs for v in (o.longitudinal_v, o.angular_v))
    assert outs[4].active and outs[4].longitudinal_v > 2.6


def test_a_commands_age_is_taken_at_its_first_use() -> None:
    """PidStatus.command_age_s: how old a command was when a loop step first followed it (the
    control service moves its prediction on by it); a second step on the same command does
    not age it again."""
    core = core_()
    assert drive(core, 0.5, 0.0, 0.1) is Verdict.OK
    core.update(0.0, 0.0, 0.01, 0.112, ns(0.112))
    assert core.command_age_s == pytest.approx(0.012, abs=1e-6)
    core.update(0.0, 0.0, 0.01, 0.122, ns(0.122))
    assert core.command_age_s == pytest.approx(0.012, abs=1e-6)  # (the same command)
    assert drive(core, 0.5, 0.0, 0.12) is Verdict.OK
    core.update(0.0, 0.0, 0.01, 0.125, ns(0.125))
    assert core.command_age_s == pytest.approx(0.005, abs=1e-6)


@pytest.mark.parametrize(("limit", "sent", "kept"), [
    ((1.0, 0.35), (0.5, 0.9), (0.5 * 0.35 / 0.9, 0.35)),  # the turn-rate bound
    ((0.2, 1.0), (0.5, 0.3), (0.2, 0.12)),  # the forward bound
    ((1.0, 0.35), (0.0, 0.9), (0.0, 0.35)),  # a turn in place: only ω to bound
    ((0.0, 1.0), (0.5, 0.3), (0.0, 0.3)),  # forward blocked: the turn the limit allows (H03)
])
def test_a_limited_arc_keeps_its_radius(limit: tuple[float, float],
                                        sent: tuple[float, float],
                                        kept: tuple[float, float]) -> None:
    """H64: the monitor bounds |ω| (0.35 rad/s while it cannot see the chair's rear) and v.
    Each clamped alone, an arc of radius 0.56 m sent at (0.5, 0.9) was driven at (0.5, 0.35),
    radius 1.43 m: wide of the turn the planner checked, into the wall it avoided (nav_eval
    --monitor: 7 contacts). Now both axes slow by one factor and the radius stays."""
    core = driving_core(require_limit=True)
    t = 1.0
    core.set_limit(limit[0], 0.5, limit[1], t, 0.5)
    drive(core, *sent, t)
    got = core.desired(t, ns(t))
    assert got == pytest.approx(kept)


def test_an_arc_whose_turn_is_bounded_to_zero_is_a_safety_stop() -> None:
    """H64 with H03: an arc (0.5, 0.3) under a turn bound of 0 (the monitor: turning blocked)
    is slowed to 0 on both axes to keep its arc: the chair stands, so it is a stop, and the old
    stream does not drive on when the bound re-opens. Positive control: a turn bound of 0.1
    leaves a slower arc, motion the limit allows."""
    def run(w_bound: float) -> tuple[tuple[float, float] | None, bool]:
        core = driving_core(require_limit=True)
        t = 1.0
        core.set_limit(1.0, 0.5, w_bound, t, 0.5)
        drive(core, 0.5, 0.3, t)
        held = core.desired(t, ns(t))
        core.update(0.5, 0.3, DT, t, ns(t))
        t += DT
        core.set_limit(1.0, 0.5, 1.0, t, 0.5)  # the bound re-opens; the same stream goes on
        drive(core, 0.5, 0.3, t)
        return held, core.update(0.5, 0.3, DT, t, ns(t)).active

    held, after = run(0.0)
    assert held is None and not after
    held, after = run(0.1)
    assert held == pytest.approx((0.5 / 3, 0.1)) and after
