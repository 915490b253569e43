"""Time-optimal point-to-point moves (limits.py `move`), the drive-chain predictor (core.py
ChainAxis) and the minimum-time reference of the control-law suite (bench/min_time.py)."""

from __future__ import annotations

import dataclasses
import itertools
import math

import msgspec
import pytest
from bench.control_eval import scurve_time
from bench.min_time import Limits, min_time

from autochair.control.core import ChainAxis, ControlConfig, ControlCore, OdomSample, Planned
from autochair.control.limits import ComfortLimiter, ComfortLimits, SCurveAxis
from autochair.geometry import wrap_angle as wrap
from autochair.pid.core import PidConfig, make_core
from autochair.tune.lockstep import DT as LDT
from autochair.tune.lockstep import Rig
from autochair_msgs import GoalRequest, Pose2D

DT = 0.02  # the control core's period (50 Hz)


def run_move(axis: SCurveAxis, distance: float, steps: int = 1000) -> tuple[list[float], float]:
    """Values sent while moving `distance` (replanned each step from what is left), and the
    distance covered (the values held over each step, as the chair is commanded)."""
    out, covered = [], 0.0
    for _ in range(steps):
        left = distance - covered
        v = axis.move(max(left, 0.0) if distance > 0 else min(left, 0.0), DT)  # as the core
        covered += v * DT
        out.append(v)
        if v == 0.0 and axis.rate == 0.0:
            break
    return out, covered


@pytest.mark.parametrize("angle", [math.pi / 4, -math.pi / 2, math.pi])
def test_in_place_turn_is_time_optimal_within_the_limits(angle: float) -> None:
    lim = ComfortLimits()
    ax = SCurveAxis(lim.omega_max_radps, lim.omega_acc_max_radps2, lim.omega_jerk_max_radps3)
    ws, covered = run_move(ax, angle)
    t = len(ws) * DT
    best = scurve_time(abs(angle), lim.omega_max_radps, lim.omega_acc_max_radps2,
                       lim.omega_jerk_max_radps3)
    assert covered == pytest.approx(angle, abs=math.radians(0.3))
    assert best <= t <= best + 3 * DT  # the jerk-limited optimum, to the control period
    w = [0.0, *ws]
    acc = [(b - a) / DT for a, b in itertools.pairwise(w)]
    assert max(map(abs, w)) <= lim.omega_max_radps + 1e-9
    assert max(map(abs, acc)) <= lim.omega_acc_max_radps2 + 1e-6
    jerk = [(b - a) / DT for a, b in itertools.pairwise(acc)]
    assert max(map(abs, jerk)) <= lim.omega_jerk_max_radps3 * 1.01
    assert all(x * angle >= 0 for x in ws)  # one-signed: never turns back


def test_a_move_too_short_to_stop_on_brakes_without_turning_back() -> None:
    ax = SCurveAxis(1.2, 1.0, 2.0)
    ax.value, ax.rate = 0.6, 0.5  # accelerating, 5 cm before the point
    ws, covered = run_move(ax, 0.05)
    assert covered > 0.05  # positive control: it cannot stop on it
    assert all(v >= 0.0 for v in ws) and ws[-1] == 0.0 and ax.rate == 0.0
    acc = [(b - a) / DT for a, b in itertools.pairwise([0.6, *ws])]
    assert max(map(abs, acc)) <= 1.0 + 1e-6


def test_limiter_move_brakes_the_axis_without_a_distance() -> None:
    lim = ComfortLimiter()
    lim.reset(0.5, 0.0)
    turned = 0.0
    for _ in range(200):
        v, w = lim.move(None, math.pi / 2 - turned, DT)
        turned += w * DT
        assert v >= -1e-12
    assert lim.at_rest and turned == pytest.approx(math.pi / 2, abs=1e-4)


def chain_response(mean: float, lag: float, cmds: list[float],
                   h: float = 1e-4) -> tuple[float, float]:
    """(motion by the end of the commands, whole motion) of a chair whose velocity follows
    the commands (each held DT, then zero) through the delay and the two lags: a fine
    simulation."""
    delay = mean - 2 * lag
    x1 = x2 = total = t = 0.0
    so_far, t_end = None, len(cmds) * DT
    while t < t_end + delay + 12 * lag:
        if so_far is None and t >= t_end - 1e-12:
            so_far = total
        k = math.floor((t - delay) / DT + 1e-9)
        u = cmds[k] if 0 <= k < len(cmds) else 0.0
        x1 += (u - x1) * h / lag
        x2 += (x1 - x2) * h / lag
        total += x2 * h
        t += h
    assert so_far is not None
    return so_far, total


def test_chain_prediction_is_the_motion_still_to_come() -> None:
    # a turn braking at the ω̇ limit: where a window of recent commands errs by degrees
    cmds = [min(0.9, 2.8 * DT * k) for k in range(30)] + [0.9 - 2.8 * DT * k
                                                           for k in range(1, 9)]
    so_far, total = chain_response(0.62, 0.15, cmds)
    ax = ChainAxis(0.62, 0.15)
    for u in cmds:
        ax.push(DT, u)
    to_come = sum(ax.future(DT, 200)) * DT
    assert to_come == pytest.approx(total - so_far, abs=math.radians(0.3))
    window = sum(cmds[-round(0.62 / DT):]) * DT  # the old predictor: the last 0.62 s sent
    assert abs(window - (total - so_far)) > math.radians(1.0)  # positive control


def test_the_prediction_moves_old_odometry_on_to_now() -> None:
    """Odometry measured 20 ms before it arrived (its own stamp: through the processes
    ODOM_SLOW against the loop's own timer), or that arrived 20 ms ago, predicts the same pose
    as odometry measured now, plus the command's pickup delay; taken as current it fell short
    by v·age (positive control)."""
    core = ControlCore(ControlConfig())
    v, w = 0.8, 0.3
    for _ in range(100):  # the chain in steady motion
        core._chain[0].push(DT, v)
        core._chain[1].push(DT, w)
    age = 0.02
    fresh = core._predicted(OdomSample(v * age, 0.0, w * age, v, w, 1.0), 1.0)
    for old in (core._predicted(OdomSample(0.0, 0.0, 0.0, v, w, 1.0, age), 1.0),
                core._predicted(OdomSample(0.0, 0.0, 0.0, v, w, 1.0 - age), 1.0)):
        assert math.hypot(old.x - fresh.x, old.y - fresh.y) < 1e-3
        assert abs(wrap(old.yaw - fresh.yaw)) < 1e-4
    blind = core._predicted(OdomSample(0.0, 0.0, 0.0, v, w, 1.0), 1.0)
    assert math.hypot(blind.x - fresh.x, blind.y - fresh.y) > 0.9 * v * age
    core.pickup_delay_s = 0.005
    later = core._predicted(OdomSample(0.0, 0.0, 0.0, v, w, 1.0, age), 1.0)
    moved = math.hypot(later.x - fresh.x, later.y - fresh.y)
    assert moved == pytest.approx(v * 0.005, rel=0.02)


def test_the_odometrys_own_age_is_not_counted_as_staleness() -> None:
    """Freshness is judged by arrival on the control's clock: odometry that arrived 0.25 s
    ago is fresh (timeout 0.3 s) though its stamp says it was 0.1 s old on arrival, so a goal
    is accepted and driven; arrived 0.35 s ago it is refused (positive control)."""
    def core_with(received: float) -> ControlCore:
        core = ControlCore(ControlConfig(), odom_timeout_s=0.3)
        core.on_odom(OdomSample(0.0, 0.0, 0.0, 0.0, 0.0, received, 0.1))
        return core

    core = core_with(9.75)
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(1.0, 0.0, 0.0)]), 10.0).ok
    core.step(10.0, 0.02)
    assert core.active
    reply = core_with(9.65).set_goal(GoalRequest(waypoints=[Pose2D(1.0, 0.0, 0.0)]), 10.0)
    assert not reply.ok and "no fresh odometry" in reply.error


def test_predictor_defaults_match_the_chair_under_a_planned_stream() -> None:
    """The chair (the simulated one, through odometry and the PID's inverse of its model)
    trails a planned ramp by the predictor's mean lag (ControlConfig.predict_s), and by far
    less than through the prefilter (positive control: a stream without its plan)."""
    cfg = ControlConfig()
    pcfg = msgspec.structs.replace(PidConfig(), require_safety_limit=False, require_estop=False)

    def lag(planned: bool) -> float:
        rig, ax = Rig(make_core(pcfg)), SCurveAxis(1.2, cfg.limits.a_max_mps2,
                                                   cfg.limits.jerk_max_mps3)
        lags = []
        for k in range(round(1.6 / LDT)):
            if k % 2 == 0:  # the control service's 50 Hz
                r0 = ax.rate
                v = ax.step(1.2, 2 * LDT)
                out = Planned(v, 0.0, (ax.rate, 0.0), ((ax.rate - r0) / (2 * LDT), 0.0))
            st = rig.sense()
            rig.act(k * LDT, st.v, st.omega, out if planned else (out[0], out[1]))
            if ax.rate == ax.amax and rig.chair.v > 0.05:  # the constant-acceleration part
                lags.append((ax.value - rig.chair.v) / ax.rate)
        assert len(lags) > 20
        return sum(lags[-10:]) / 10

    assert lag(True) == pytest.approx(cfg.predict_s, abs=0.05)
    assert lag(False) > cfg.predict_s + 0.25


def test_in_place_turn_on_a_lagging_chair_lands_without_reversal() -> None:
    """A chair that follows each command through the predictor's own chain (delay + two lags):
    the turn arrives in about the optimum plus the chain's lag, ω one-signed, within 3°."""
    cfg = ControlConfig()
    core = ControlCore(cfg)
    axes = (ChainAxis(cfg.predict_s, cfg.predict_lag_s),
            ChainAxis(cfg.predict_omega_s, cfg.predict_lag_s))
    x = y = yaw = 0.0
    goal = math.radians(-45)
    core.on_odom(OdomSample(0, 0, 0, 0, 0, 0.0))
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(0.0, 0.0, goal)]), 0.0).ok
    t, ws = 0.0, []
    while core.active and t < 10:
        core.on_odom(OdomSample(x, y, yaw, axes[0].x2, axes[1].x2, t))
        w0 = axes[1].x2
        for ax, u in zip(axes, core.step(t) or (0.0, 0.0), strict=True):
            ax.push(DT, u)
        x += axes[0].x2 * math.cos(yaw) * DT
        y += axes[0].x2 * math.sin(yaw) * DT
        yaw = wrap(yaw + 0.5 * (w0 + axes[1].x2) * DT)  # (as the predictor integrates)
        ws.append(axes[1].x2)
        t += DT
    best = scurve_time(abs(goal), cfg.omega_max_radps, cfg.omega_acc_max_radps2,
                       cfg.omega_jerk_max_radps3)
    assert core.state == "arrived", core.reason
    assert abs(wrap(goal - yaw)) <= math.radians(3) and math.hypot(x, y) < 0.01
    assert max(ws) <= 1e-6  # one-signed
    assert min(ws) < -0.5  # (positive control: it did turn)
    assert t <= best + cfg.predict_omega_s + 1.0, t


# --- the minimum-time reference (bench/min_time.py) ----------------------------------------
def test_min_time_of_a_straight_line_is_the_jerk_limited_bound() -> None:
    r = min_time((0, 0, 0), (1.0, 0, 0), n=24, coarse=12)
    assert r.ok
    assert r.time_s == pytest.approx(scurve_time(1.0, 1.2, 1.0, 2.0), rel=0.02)


def test_min_time_of_an_in_place_turn_is_the_rotational_bound() -> None:
    r = min_time((0, 0, 0), (0, 0, math.radians(-45)), n=24, coarse=12)
    assert r.ok
    assert r.time_s == pytest.approx(scurve_time(math.pi / 4, 0.9, 2.8, 7.7), rel=0.03)


def test_min_time_forward_only_versus_reversing() -> None:
    """0.5 m straight back: reversing allowed, the straight-line bound; forward only, the chair
    must turn round (at least a full turn of heading, ≥ 2π/ω_max = 7 s)."""
    reversing = dataclasses.replace(Limits.of(), v_min=-1.2)
    back = min_time((0, 0, 0), (-0.5, 0, 0), reversing, n=24, coarse=12)
    assert back.ok and back.time_s == pytest.approx(scurve_time(0.5, 1.2, 1.0, 2.0), rel=0.03)
    fwd = min_time((0, 0, 0), (-0.5, 0, 0))
    assert fwd.ok and fwd.time_s >= 2 * math.pi / 0.9
