"""Smooth control law: pure law, comfort limiter, goal manager (no processes)."""

from __future__ import annotations

import copy
import dataclasses
import itertools
import math
from collections.abc import Callable

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import autochair.control.core as core_mod
from autochair.control.core import ControlConfig, ControlCore, DriveGates, OdomSample
from autochair.control.law import Gains, braking_speed, egocentric, park_kuipers
from autochair.control.limits import ComfortLimiter, ComfortLimits, SCurveAxis
from autochair.geometry import compose, inverse
from autochair.geometry import wrap_angle as wrap
from autochair.nav import planner
from autochair.nav.field import Footprint, NavField
from autochair.nav.mpepc import MpepcParams, Person
from autochair.nav.planner import compute
from autochair_msgs import GoalRequest, Pose2D

DT = 0.005
# The plants here follow the command itself (at once or through a lag): no PID prefilter for
# the command to lead (ControlConfig.lead, which the real drive chain has).
NO_LEAD = ControlConfig(lead=False)


# --- law --------------------------------------------------------------------------------------
def test_wrap_is_half_open() -> None:
    assert wrap(math.pi) == pytest.approx(math.pi)
    assert wrap(-math.pi) == pytest.approx(math.pi)
    assert wrap(3 * math.pi / 2) == pytest.approx(-math.pi / 2)


def test_egocentric_uses_atan2_for_a_goal_behind() -> None:
    # atan((0-0)/(-2-0)) = 0 would put this goal straight ahead; it is behind (δ = ±π).
    r, theta, delta = egocentric(0, 0, 0, -2, 0, 0)
    assert r == 2
    assert abs(delta) == pytest.approx(math.pi)
    assert abs(theta) == pytest.approx(math.pi)


def test_law_matches_reference_formula_and_has_no_fudge() -> None:
    g = Gains()
    out = park_kuipers(0, 0, 0.3, 3, 1, 0.5, g)
    alpha = math.atan2(1, 3)
    th, de = 0.5 - alpha, 0.3 - alpha
    kappa = -(1 / math.hypot(3, 1)) * (g.k2 * (de - math.atan(-g.k1 * th))
                                       + (1 + g.k1 / (1 + (g.k1 * th) ** 2)) * math.sin(de))
    v = min(g.vmax_mps * math.hypot(3, 1) / g.r_thresh_m, g.vmax_mps / (1 + g.beta * kappa**2))
    assert out.kappa_1pm == pytest.approx(kappa)
    assert out.v_mps == pytest.approx(v)
    assert out.omega_radps == pytest.approx(kappa * v)  # ω = κ·v, not 4·κ·v


def test_braking_speed_is_consistent_with_the_stop_distance() -> None:
    a, j = 1.0, 2.0
    for d in (0.01, 0.1, 0.5, 2.0):
        v = braking_speed(d, a, j)
        t = v / a + a / j if v >= a * a / j else 2 * math.sqrt(v / j)
        assert v * t / 2 == pytest.approx(d, rel=1e-6)


# --- pure convergence (kinematic plant with a first-order lag) -------------------------------
def drive(start: tuple[float, float, float], goal: tuple[float, float, float],
          lag_s: float = 0.1, timeout_s: float = 60.0) -> dict[str, float]:
    """Run the core against a unicycle whose velocities lag the commands."""
    x, y, yaw = start
    v = w = 0.0
    # The pose prediction horizon is matched to the plant's lag, as it should be on a chair.
    core = ControlCore(ControlConfig(predict_s=lag_s, predict_omega_s=lag_s, lead=False))
    core.on_odom(OdomSample(x, y, yaw, 0, 0, 0.0))
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(*goal)]), 0.0).ok
    t, arrived_t, k = 0.0, -1.0, 0
    cmd = (0.0, 0.0)
    omegas: list[tuple[float, float]] = []  # (distance to goal, ω)
    blocked = 0.0  # time spent in the blocked state
    while t < timeout_s:
        core.on_odom(OdomSample(x, y, yaw, v, w, t))
        if k % 4 == 0:  # control at 50 Hz, plant at 200 Hz
            out = core.step(t)
            cmd = out if out is not None else (0.0, 0.0)
            blocked += 4 * DT * (core.state == "blocked")
        v += (cmd[0] - v) * (1 - math.exp(-DT / lag_s))
        w += (cmd[1] - w) * (1 - math.exp(-DT / lag_s))
        x += v * math.cos(yaw + w * DT / 2) * DT
        y += v * math.sin(yaw + w * DT / 2) * DT
        yaw = wrap(yaw + w * DT)
        omegas.append((math.hypot(goal[0] - x, goal[1] - y), w))
        t += DT
        k += 1
        if not core.active and arrived_t < 0:
            arrived_t = t
        if arrived_t >= 0 and t - arrived_t > 1.0:
            break
    # ω sign reversals once within 0.5 m of the goal (for good, not just passing by)
    last_far = max((i for i, (r, _) in enumerate(omegas) if r > 0.5), default=0)
    sign, rev = 0, 0
    for _, wi in omegas[last_far:]:
        if abs(wi) > 0.05:
            s = 1 if wi > 0 else -1
            rev += bool(sign and s != sign)
            sign = s
    return {"state_ok": float(core.state == "arrived"), "t": arrived_t,
            "pos": math.hypot(goal[0] - x, goal[1] - y),
            "yaw": abs(wrap(goal[2] - yaw)), "rev": rev, "blocked_s": blocked}


GRID = [(gx, gy, math.radians(gyaw)) for gx, gy in
        [(3, 0), (-3, 0), (0, 3), (0, -3), (2, 2), (-2, -2), (1, 0), (-1, 0), (0, 1), (0.4, 0.4)]
        for gyaw in (0, 90, 180, -90)]


@pytest.mark.parametrize("goal", GRID, ids=lambda g: f"{g[0]},{g[1]},{math.degrees(g[2]):.0f}")
def test_converges_from_a_grid_of_start_poses(goal: tuple[float, float, float]) -> None:
    r = drive((0.0, 0.0, 0.0), goal)
    assert r["state_ok"], f"did not arrive: {r}"
    assert r["pos"] <= 0.05 and r["yaw"] <= math.radians(3.0), r
    # No ω sign reversal near the goal, except the one S-bend the geometry forces: when
    # turning to face the goal and then to the goal yaw go opposite ways (a lateral offset
    # at the same yaw cannot be removed with ω of one sign, short of a full circle).
    bearing = math.atan2(goal[1], goal[0])
    s1, s2 = bearing, wrap(goal[2] - bearing)
    forced = abs(s1) > 0.02 and abs(s2) > 0.02 and (s1 > 0) != (s2 > 0)
    # MPEPC (forward only) may turn in place first and then drive the law's curve, whose
    # first bend goes the other way, when the goal is within 1 m (changed with issue 12).
    forced = forced or math.hypot(goal[0], goal[1]) <= 1.0
    assert r["rev"] <= (1 if forced else 0), f"ω oscillates on the final approach: {r}"


@pytest.mark.parametrize("goal", [(-2.0, 0.0, 0.0), (-2.0, 0.0, math.pi), (0.0, 2.0, 0.0),
                                  (0.0, -2.0, 0.0), (0.0, 0.5, 0.0)],
                         ids=["behind", "behind-uturn", "left", "right", "left-near"])
def test_goals_behind_and_beside_the_chair(goal: tuple[float, float, float]) -> None:
    r = drive((0.0, 0.0, 0.0), goal)
    assert r["state_ok"] and r["pos"] <= 0.05 and r["yaw"] <= math.radians(3.0), r
    assert r["t"] < 30.0, r


@pytest.mark.parametrize("goal", [(-0.5, 0.0, 0.0), (0.0, 0.1, 0.0), (0.0, -0.2, 0.0),
                                  (-0.3, 0.1, 0.0), (0.0, 0.3, 0.0)],
                         ids=["behind-0.5", "aside-0.1", "aside-right-0.2", "behind-aside",
                              "aside-0.3"])
def test_short_manoeuvres_in_open_space_arrive_and_are_never_blocked(
        goal: tuple[float, float, float]) -> None:
    # A goal a few decimetres behind or beside the chair at its own yaw needs turn, drive,
    # turn (forward only). Standing still at the goal's yaw once looked cheapest to MPEPC (its
    # heading term switched to |goal yaw − yaw| within 1 m of the goal), so these goals ended
    # "blocked by an obstacle" in open space (bench control_eval, issue 12).
    r = drive((0.0, 0.0, 0.0), goal)
    assert r["state_ok"] and r["pos"] <= 0.05 and r["yaw"] <= math.radians(3.0), r
    assert r["blocked_s"] == 0.0 and r["t"] < 20.0, r


def test_straight_goal_does_not_overshoot() -> None:
    for d in (0.3, 1.0, 2.0, 5.0):
        core = ControlCore(NO_LEAD)
        x = v = 0.0
        core.on_odom(OdomSample(0, 0, 0, 0, 0, 0.0))
        assert core.set_goal(GoalRequest(waypoints=[Pose2D(d, 0, 0)]), 0.0).ok
        t, peak = 0.0, 0.0
        while core.active and t < 30:
            core.on_odom(OdomSample(x, 0, 0, v, 0, t))
            out = core.step(t)
            v = out[0] if out else 0.0
            x += v * 0.02
            peak = max(peak, x)
            t += 0.02
        assert core.state == "arrived"
        assert peak <= d + 0.005, f"overshot {d} m by {peak - d:.3f} m"


# --- limiter ----------------------------------------------------------------------------------
def check_axis(values: list[float], dts: list[float], vmax: float, amax: float,
               jmax: float) -> None:
    tol = 1e-6
    rates = [(values[i + 1] - values[i]) / dts[i] for i in range(len(dts))]
    assert max(abs(x) for x in values) <= vmax + tol
    assert max(abs(a) for a in rates) <= amax + tol
    jerks = [(rates[i + 1] - rates[i]) / dts[i + 1] for i in range(len(rates) - 1)]
    if jerks:
        assert max(abs(j) for j in jerks) <= jmax + 1e-3, max(abs(j) for j in jerks)


targets = st.lists(st.tuples(st.floats(-2, 2), st.floats(-2, 2), st.integers(1, 80)),
                   min_size=1, max_size=12)


@settings(max_examples=150, deadline=None)
@given(targets, st.sampled_from([0.005, 0.02, 0.05]))
def test_limits_never_exceeded(seq: list[tuple[float, float, int]], dt: float) -> None:
    lim = ComfortLimits()
    limiter = ComfortLimiter(lim)
    vs, ws = [0.0], [0.0]
    for v_t, w_t, n in seq:
        for _ in range(n):
            v, w = limiter.step(v_t, w_t, dt)
            vs.append(v)
            ws.append(w)
    dts = [dt] * (len(vs) - 1)
    check_axis(vs, dts, lim.v_max_mps, lim.a_max_mps2, lim.jerk_max_mps3)
    check_axis(ws, dts, lim.omega_max_radps, lim.omega_acc_max_radps2,
               lim.omega_jerk_max_radps3)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.floats(-1.5, 1.5), st.floats(0.002, 0.05)), min_size=2,
                max_size=300))
def test_axis_limits_hold_with_jittery_dt(seq: list[tuple[float, float]]) -> None:
    ax = SCurveAxis(1.2, 1.0, 2.0)
    values, dts = [0.0], []
    for target, dt in seq:
        values.append(ax.step(target, dt))
        dts.append(dt)
    # with varying dt the jerk bound holds against the later step's dt
    check_axis(values, dts, 1.2, 1.0, 2.0)


@given(st.floats(0.01, 1.2), st.floats(-1.0, 1.0), st.sampled_from([0.005, 0.02]))
def test_axis_reaches_a_reachable_target_without_overshoot(target: float, start_rate: float,
                                                           dt: float) -> None:
    ax = SCurveAxis(1.2, 1.0, 2.0)
    ax.reset(0.0, 0.0)
    for _ in range(round(10 / dt)):
        ax.step(target, dt)
        assert ax.value <= target + 1e-9
    assert ax.value == target and ax.rate == 0.0


def test_limiter_keeps_curvature_while_v_ramps() -> None:
    limiter = ComfortLimiter()
    for _ in range(20):
        v, w = limiter.step(1.0, 0.5, 0.02)  # κ = 0.5 1/m
        if v > 0.05:
            assert w / v == pytest.approx(0.5, rel=0.35)


# --- goal manager -----------------------------------------------------------------------------
def fresh_core(cfg: ControlConfig | None = None) -> ControlCore:
    core = ControlCore(cfg or NO_LEAD)
    core.on_odom(OdomSample(0, 0, 0, 0, 0, 0.0))
    return core


@pytest.mark.parametrize("req,needle", [
    (GoalRequest(waypoints=[]), "no waypoints"),
    (GoalRequest(waypoints=[Pose2D(math.nan, 0, 0)]), "not finite"),
    (GoalRequest(waypoints=[Pose2D(1, 0, math.inf)]), "not finite"),
    (GoalRequest(waypoints=[Pose2D(1, 0, 0)], tolerance_m=0.0), "tolerance_m"),
    (GoalRequest(waypoints=[Pose2D(1, 0, 0)], tolerance_rad=-1.0), "tolerance_rad"),
    (GoalRequest(waypoints=[Pose2D(1, 0, 0)], vmax_mps=5.0), "exceeds"),
])
def test_invalid_goals_are_rejected_with_a_reason(req: GoalRequest, needle: str) -> None:
    core = fresh_core()
    reply = core.set_goal(req, 0.0)
    assert not reply.ok and needle in reply.error
    assert core.state == "idle" and core.counters["rejected_goals"] == 1


def test_idle_publishes_nothing_and_cancel_without_goal() -> None:
    core = fresh_core()
    assert core.step(0.0) is None and core.step(0.02) is None
    reply = core.cancel(0.02)
    assert reply.ok and reply.goal_id == 0 and "no active goal" in reply.error


def test_stale_odometry_aborts_and_brakes_within_limits() -> None:
    core = fresh_core()
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(5, 0, 0)]), 0.0).ok
    t, vs = 0.0, []
    while t < 2.0:  # drive with fresh odometry
        core.on_odom(OdomSample(0.5 * t, 0, 0, 0.5, 0, t))
        out = core.step(t)
        assert out is not None
        vs.append(out[0])
        t += 0.02
    assert vs[-1] > 0.3
    while core.step(t) is not None:  # odometry stops arriving
        vs.append(core.limiter.v.value)
        t += 0.02
        assert t < 10.0
    assert core.state == "aborted" and "stale odometry" in core.reason
    assert vs[-1] == 0.0
    check_axis(vs, [0.02] * (len(vs) - 1), 1.2, 1.0, 2.0)


def test_the_plan_steps_by_the_schedule_and_freshness_by_the_clock() -> None:
    """Through the processes the loop's thread wakes 0-15 ms late: stepped by the schedule
    (`dt`, Node.due) the plan's acceleration is smooth; taken from the wake-up times it
    chattered (positive control). Stale odometry is still judged on the real clock."""
    rng = np.random.default_rng(3)

    def accel(scheduled: bool) -> list[float]:
        core = fresh_core()
        assert core.set_goal(GoalRequest(waypoints=[Pose2D(5, 0, 0)]), 0.0).ok
        x, vs = 0.0, []
        for k in range(60):
            woke = 0.02 * k + float(rng.uniform(0.0, 0.015))
            out = core.step(woke, 0.02 if scheduled and k else None) or (0.0, 0.0)
            x += out[0] * 0.02
            core.on_odom(OdomSample(x, 0, 0, out[0], 0, woke))
            vs.append(out[0])
        return [float(b - a) / 0.02 for a, b in itertools.pairwise(vs)]

    smooth, chatter = accel(True), accel(False)
    jerk = [abs(b - a) / 0.02 for a, b in itertools.pairwise(smooth)]
    assert max(jerk) <= 2.0 + 1e-6  # the plan's own jerk limit, tick to tick
    assert max(abs(b - a) / 0.02 for a, b in itertools.pairwise(chatter)) > 5.0
    core, t = driving()
    core.step(t + 0.5, 0.02)  # half a second late: the odometry is stale, whatever dt says
    assert core.state == "aborted" and "stale odometry" in core.reason


def test_cancel_brakes_then_publishes_a_burst_of_zeros_then_nothing() -> None:
    core = fresh_core()
    core.set_goal(GoalRequest(waypoints=[Pose2D(5, 0, 0)]), 0.0)
    t = 0.0
    for _ in range(100):
        core.on_odom(OdomSample(0, 0, 0, 0, 0, t))
        core.step(t)
        t += 0.02
    assert core.cancel(t).ok and core.state == "cancelled"
    outs = []
    while (out := core.step(t)) is not None:
        core.on_odom(OdomSample(0, 0, 0, 0, 0, t))
        outs.append(out)
        t += 0.02
        assert len(outs) < 1000
    zeros = [o for o in outs if o == (0.0, 0.0)]
    assert len(zeros) >= 0.5 / 0.02 - 1  # the stop burst
    assert outs[-1] == (0.0, 0.0)


def test_waypoints_are_passed_without_stopping_and_status_counts_down() -> None:
    # The chair below follows at once: so must the predictor (with the default 0.62 s chain
    # model on an instant chair the time-optimal final turn over-predicts and limit-cycles).
    core = fresh_core(INSTANT)
    wps = [Pose2D(2, 0, 0), Pose2D(4, 1, math.pi / 4), Pose2D(5, 3, math.pi / 2)]
    assert core.set_goal(GoalRequest(waypoints=wps), 0.0).ok
    x = y = yaw = v = w = 0.0
    t = 0.0
    speeds_mid, dist = [], []
    while core.active and t < 60:
        core.on_odom(OdomSample(x, y, yaw, v, w, t))
        out = core.step(t)
        assert out is not None
        v, w = out
        s = core.status()
        dist.append(s.distance_left_m)
        if s.waypoint_index == 1 and math.hypot(x - 2, y) < 0.6:
            speeds_mid.append(v)
        x += v * math.cos(yaw) * 0.02
        y += v * math.sin(yaw) * 0.02
        yaw = wrap(yaw + w * 0.02)
        t += 0.02
    assert core.state == "arrived"
    assert speeds_mid and min(speeds_mid) > 0.3, "stopped at an intermediate waypoint"
    assert dist[0] == pytest.approx(2 + math.hypot(2, 1) + math.hypot(1, 2), rel=1e-6)
    assert dist[-1] < 0.05


def test_bad_config_is_refused() -> None:
    with pytest.raises(ValueError, match="rate_hz"):
        ControlCore(ControlConfig(rate_hz=10))
    with pytest.raises(ValueError, match="a_max_mps2"):
        ControlCore(ControlConfig(a_max_mps2=0))


# --- stops the chair did not ask for ----------------------------------------------------------
def driving(cfg: ControlConfig | None = None, until: float = 2.0) -> tuple[ControlCore, float]:
    """A core driving a goal 5 m ahead with a chair that follows at the commanded speed."""
    core = fresh_core(cfg)
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(5, 0, 0)]), 0.0).ok
    t, x = 0.0, 0.0
    while t < until:
        out = core.step(t) or (0.0, 0.0)
        x += out[0] * 0.02
        core.on_odom(OdomSample(x, 0, 0, out[0], 0, t))
        t += 0.02
    assert core.active
    return core, t


def test_estop_latch_aborts_the_goal_and_refuses_new_ones_until_released() -> None:
    core, t = driving()
    core.on_estop(True, t)
    assert core.state == "aborted" and "e-stop" in core.reason
    reply = core.set_goal(GoalRequest(waypoints=[Pose2D(5, 0, 0)]), t)
    assert not reply.ok and "e-stop is latched" in reply.error
    core.on_estop(False, t)
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(5, 0, 0)]), t).ok


def test_owner_change_aborts_the_goal() -> None:
    core, t = driving()
    core.on_owner("autonomy", t)
    assert core.active  # positive control: a repeated claim changes nothing
    core.on_owner("teleop", t)
    assert core.state == "aborted" and "teleop" in core.reason
    assert "hand it back" in core.set_goal(GoalRequest(waypoints=[Pose2D(1, 0, 0)]), t).error


def test_a_new_goal_after_a_stop_starts_from_the_measured_velocity() -> None:
    core, t = driving()
    assert core.limiter.v.value > 0.5
    core.on_estop(True, t)
    core.on_estop(False, t)  # the chair was held at neutral: it is at rest now
    core.on_odom(OdomSample(2.0, 0, 0, 0.0, 0, t))
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(6, 0, 0)]), t).ok
    out = core.step(t + 0.02)
    assert out is not None and out[0] < 0.01  # from rest, not from the old 0.5+ m/s


def test_a_chair_that_does_not_follow_aborts_the_goal() -> None:
    core = fresh_core(ControlConfig(follow_timeout_s=2.0, lead=False))
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(5, 0, 0)]), 0.0).ok
    t = 0.0
    while core.active and t < 10:
        core.step(t)
        core.on_odom(OdomSample(0, 0, 0, 0.0, 0, t))  # the chair stays at rest
        t += 0.02
    assert core.state == "aborted" and "does not follow" in core.reason
    assert "velocity PID" not in core.reason  # (positive control for the PID's word below)
    assert 2.0 < t < 3.0


def test_a_chair_that_does_not_follow_names_what_the_pid_said() -> None:
    """The PID refuses a stream it once took for stale, for good (no unexpected start-up): the
    abort names its reason, not a guess."""
    core = fresh_core(ControlConfig(follow_timeout_s=2.0, lead=False))
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(5, 0, 0)]), 0.0).ok
    t = 0.0
    while core.active and t < 10:
        core.step(t)
        core.on_odom(OdomSample(0, 0, 0, 0.0, 0, t))
        core.gates.pid_inhibit = "stopped (command stream stale): waiting for a command begun " \
                                 "after the stop"
        t += 0.02
    assert "does not follow" in core.reason and "the velocity PID: stopped (command stream " \
        "stale)" in core.reason, core.reason


def test_a_stop_the_pid_latched_for_the_monitor_ends_the_goal_once_the_chair_stands() -> None:
    """H73's residual: a turn bound of ~0 for one scan latches the PID's safety stop (it hears
    the limit first); lifted by the next scan before the chair stood, the core took it for a
    slow-down and went on commanding, and the goal ended 2 s later, "does not follow". The PID
    says it has latched (PidStatus.inhibit, read by the node into gates.pid_inhibit): once the
    chair stands the goal ends at once, naming the monitor. Positive control: the same word
    left over from before the goal (the PID never said it obeyed this goal's stream) ends it
    only as "does not follow", after follow_timeout_s."""
    latched = "stopped (safety stop): waiting for a command begun after the stop"

    def run(obeyed: bool) -> tuple[ControlCore, float]:
        core = fresh_core(ControlConfig(follow_timeout_s=2.0, lead=False))
        assert core.set_goal(GoalRequest(waypoints=[Pose2D(5, 0, 0)]), 0.0).ok
        core.gates.pid_inhibit = "" if obeyed else latched
        t, k = 0.0, 0
        while core.active and t < 10:
            core.step(t)
            core.on_odom(OdomSample(0, 0, 0, 0.0, 0, t))
            core.gates.pid_inhibit = "" if obeyed and k < 15 else latched
            if k == 13:  # one scan bars the turn, the next lifts it
                core.on_limit(1.2, 0.0, "free fwd 3.00 m rev inf m turn 0.00 rad", t)
                core.on_limit(1.2, 1.0, "clear", t + 0.01)
            t, k = t + 0.02, k + 1
        return core, t

    core, t = run(True)
    assert core.state == "aborted" and t < 1.0, (core.reason, t)
    assert core.reason.startswith("the safety monitor stopped the chair (free fwd 3.00 m rev "
                                  "inf m turn 0.00 rad)"), core.reason
    core, t = run(False)
    assert "does not follow" in core.reason and t > 2.0, (core.reason, t)


def test_a_chair_that_does_not_follow_names_the_monitors_block() -> None:
    """The monitor bars forward motion (the chair within its stop margin of something ahead),
    the PID stops the stream: the abort says what the monitor saw, not only a guess. (Its
    limit allowed turning, so it is no "stop" that would refuse goals: nav_eval --monitor.)
    Session 29 (H76): the core plans v under the forward bound, so a bound of 0 that meets a
    commanded drive is the stop it is for the PID, and the goal ends once the chair stands,
    naming the monitor, not 2 s later as "does not follow"."""
    def run(block: bool) -> ControlCore:
        core = fresh_core(ControlConfig(follow_timeout_s=2.0, lead=False))
        assert core.set_goal(GoalRequest(waypoints=[Pose2D(5, 0, 0)]), 0.0).ok
        t = 0.0
        while core.active and t < 10:
            core.on_limit(0.0 if block and t > 0.5 else 1.2, 0.35, "free fwd 0.10 m", t)
            core.step(t)
            core.on_odom(OdomSample(0, 0, 0, 0.0, 0, t))
            t += 0.02
        return core

    assert "does not follow" in run(False).reason  # positive control: never bounded to 0
    assert "safety monitor" not in run(False).reason
    assert "the safety monitor stopped the chair (free fwd 0.10 m)" in run(True).reason


def test_a_goal_the_drive_chain_would_not_obey_is_refused_at_once_naming_why() -> None:
    """The PID refuses a stream begun while the e-stop is silent or the safety monitor's limit
    (required while it runs) is missing, stale or says stop, and never takes it back: such a
    goal is refused at once with the cause, not taken to end "does not follow" 2 s later."""
    goal = GoalRequest(waypoints=[Pose2D(5, 0, 0)])

    def core_at(t: float) -> ControlCore:
        core = fresh_core()
        core.gates = DriveGates(estop_s=0.5, limit_s=0.5)
        core.on_odom(OdomSample(0, 0, 0, 0.0, 0, t))
        return core

    core = core_at(10.0)
    assert "e-stop is silent" in core.set_goal(goal, 10.0).error  # never heard
    core.on_estop(False, 10.0)
    assert core.set_goal(goal, 10.0).ok  # positive control: no monitor in this stack
    core = core_at(10.0)
    core.on_estop(False, 9.4)
    assert "e-stop is silent" in core.set_goal(goal, 10.0).error  # heard 0.6 s ago
    core.on_estop(False, 10.0)
    core.gates.monitor_up = True  # the monitor runs: its limit is required
    assert "no fresh limit" in core.set_goal(goal, 10.0).error
    core.on_limit(0.0, 0.0, "no scan yet", 10.0)
    assert "says stop (no scan yet)" in core.set_goal(goal, 10.0).error
    core.on_limit(0.0, 0.5, "close ahead", 10.0)  # a turn is allowed: the PID takes a stream
    assert core.set_goal(goal, 10.0).ok
    core = core_at(10.0)
    core.on_estop(False, 10.0)
    core.on_limit(1.0, 1.0, "", 9.0)  # the monitor was seen, then fell silent
    assert "no fresh limit" in core.set_goal(goal, 10.0).error
    # A goal taken, whose drive chain then stops obeying: the abort says what held it.
    core = core_at(0.0)
    core.on_estop(False, 0.0)
    assert core.set_goal(goal, 0.0).ok
    t = 0.0
    while core.active and t < 10:
        core.step(t)
        core.on_odom(OdomSample(0, 0, 0, 0.0, 0, t))  # at rest: the e-stop heartbeat stopped
        t += 0.02
    assert "does not follow" in core.reason and "e-stop is silent" in core.reason, core.reason


def test_a_goal_without_progress_aborts() -> None:
    core = fresh_core(ControlConfig(no_progress_s=3.0, lead=False))
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(5, 0, 0)]), 0.0).ok
    t = 0.0
    while core.active and t < 20:
        out = core.step(t) or (0.0, 0.0)
        # the chair moves (so it "follows") but circles instead of approaching
        core.on_odom(OdomSample(0.1 * math.sin(t), 0.1 * math.cos(t), t, out[0], 0.3, t))
        t += 0.02
    assert core.state == "aborted" and "no progress for 3 s" in core.reason


def circling(planned: Callable[[planner.PlanResult, float], planner.PlanResult], until_s: float,
             monkeypatch: pytest.MonkeyPatch) -> tuple[ControlCore, float]:
    """A 5 m goal (no_progress_s 3 s) whose chair circles where it is, following its
    commands but never nearer, each plan passed through `planned(result, t)`, until the goal
    ends or `until_s`: the core, and the time then."""
    t = 0.0
    monkeypatch.setattr(core_mod, "compute", lambda req: planned(planner.compute(req), t))
    core = fresh_core(ControlConfig(no_progress_s=3.0, lead=False))
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(5, 0, 0)]), 0.0).ok
    while core.active and t < until_s:
        out = core.step(t) or (0.0, 0.0)
        core.on_odom(OdomSample(0.1 * math.sin(t), 0.1 * math.cos(t), t, out[0], 0.3, t))
        t += 0.02
    return core, t


@pytest.mark.parametrize("manoeuvring", [True, False])
def test_progress_on_the_goals_lattice_counts_as_progress(manoeuvring: bool,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """A chair on the lattice's stages round a jamb (turned away from the goal, then onto the
    door) gets no nearer on the 2-D distance for a while, but its lattice cost-to-go falls:
    that is progress (live, office A from the hallway was aborted half-way through such
    stages). Positive control: the lattice cost standing still, "no progress"."""
    core, _ = circling(lambda res, t: dataclasses.replace(
        res, lattice_left=9.0 - (0.2 * t if manoeuvring else 0.0)), 10.0, monkeypatch)
    if manoeuvring:
        assert core.active, core.reason
    else:
        assert core.state == "aborted" and "no progress for 3 s" in core.reason


@pytest.mark.parametrize("case", ["longer", "flicker", "standing"])
def test_a_new_map_that_shows_the_way_longer_rebases_progress(
        case: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """At 2 s a new map that has seen the whole room (the old one none of it) shows the way
    5 m longer (a wall where unseen space counted free): progress along it is progress,
    though the old map's shorter way is never beaten (laser map, office A to B: "no
    progress" 15 s after the first turn showed the office's back wall). Positive controls:
    on the new map standing still, "no progress"; a map flickering between the two every
    0.5 s (a door seen shut and open) re-bases once, on its first new sight, so the goal
    still ends."""
    fields: dict[bool, NavField] = {}

    def planned(res: planner.PlanResult, t: float) -> planner.PlanResult:
        new = t >= 2.0 and (case != "flicker" or int(t / 0.5) % 2 == 0)
        if new not in fields:  # (one object per map; the new one has seen every cell)
            fld = fields[new] = copy.copy(res.field)
            fld.map = dataclasses.replace(fld.map, unknown=np.full(fld.map.occupied.shape,
                                                                   not new))
        fld = fields[new]
        left = 9.0 - 0.2 * t if t < 2.0 else {
            "longer": 14.0 - 0.2 * (t - 2.0), "standing": 14.0, "flicker": 8.6 + 5.0 * new}[case]
        return dataclasses.replace(res, field=fld, lattice_left=left)

    core, t = circling(planned, 30.0, monkeypatch)
    if case == "longer":
        assert core.active, core.reason
    else:
        assert core.state == "aborted" and "no progress for 3 s" in core.reason, core.reason
        assert t < 2.0 + 3.0 * 3, t


def test_goals_beyond_the_maximum_distance_are_refused() -> None:
    core = fresh_core(ControlConfig(max_goal_distance_m=10.0, lead=False))
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(9, 0, 0)]), 0.0).ok
    reply = core.set_goal(GoalRequest(waypoints=[Pose2D(1, 0, 0), Pose2D(10, 5, 0)]), 0.0)
    assert not reply.ok and "waypoint 1 is 11.2 m away" in reply.error


def test_mpepc_drives_forward_only_even_to_a_goal_just_behind() -> None:
    # (Replaces the reverse-approach test: MPEPC made the reverse heuristic unnecessary.)
    core = fresh_core()
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(-1, 0, 0)]), 0.0).ok
    vs, ws = [], []
    for k in range(150):
        core.on_odom(OdomSample(0, 0, 0, 0, 0, k * 0.02))
        v, w = core.step(k * 0.02) or (0.0, 0.0)
        vs.append(v)
        ws.append(w)
    assert max(abs(w) for w in ws) > 0.1  # positive control: it does manoeuvre
    assert min(vs) >= 0.0


def test_turns_are_planned_within_the_monitors_turn_rate_bound() -> None:
    def peak_omega(cap: float | None) -> float:
        core = fresh_core()
        if cap is not None:
            core.on_limit(1.0, cap, "", 0.0)
        assert core.set_goal(GoalRequest(waypoints=[Pose2D(0, 0, math.pi / 2)]), 0.0).ok
        peak = 0.0
        for k in range(200):
            core.on_odom(OdomSample(0, 0, 0, 0, 0, k * 0.02))
            peak = max(peak, abs((core.step(k * 0.02) or (0.0, 0.0))[1]))
        return peak

    assert peak_omega(None) > 0.5  # positive control: the comfort limit (0.9 × 0.6)
    assert peak_omega(0.35) == pytest.approx(0.35, abs=1e-9)


@pytest.mark.parametrize("goal", [(2.0, 1.5, math.pi / 2), (3.0, 1.0, 0.0),
                                  (0.0, 0.0, math.pi / 2), (1.5, -1.5, -math.pi / 2)])
def test_mpepc_predicts_turns_within_the_monitors_turn_rate_bound(
        goal: tuple[float, float, float]) -> None:
    """H65: the limiter turns within the monitor's |ω| bound (slowing v to keep the curve), so
    MPEPC's rollouts must too, or the plan's timing is not the chair's: it planned an S-turn
    past a crossing person at 1.2 m/s that the capped chair drove at 0.6, its rear left on the
    person's line (nav_eval --monitor seed 2). Each goal's plan turns at over 0.5 rad/s
    without the bound (positive control) and within 0.35 with it."""
    def predicted_peak(cap: float | None) -> float:
        core = fresh_core()
        core.people = [Person(-3.0, 3.0)]  # (the bound is planned with where people are)
        if cap is not None:
            core.on_limit(1.0, cap, "", 0.0)
        assert core.set_goal(GoalRequest(waypoints=[Pose2D(*goal)]), 0.0).ok
        req = core.plan_request(0.0)
        assert req is not None
        plan = compute(req).plan
        assert plan is not None
        yaw = np.unwrap(np.concatenate([[0.0], plan.path[:, 2]]))
        return float(np.abs(np.diff(yaw)).max() / MpepcParams().dt_s)

    assert predicted_peak(None) > 0.5
    assert predicted_peak(0.35) <= 0.35 + 1e-6


def test_mpepc_plans_with_the_monitors_standing_turn_rate_bound() -> None:
    """The monitor's |ω| bound drops below its standing 0.35 rad/s near obstacles, for as long
    as the chair is close; the limiter obeys every drop, but MPEPC plans with the largest
    bound of the last PLAN_OMEGA_WINDOW_S (planned with, the drops made it predict crawling
    turns and stand: clutter's far side lost). A bound held that long is planned with; no
    monitor: the comfort limit."""
    core = fresh_core()
    core.people = [Person(-3.0, 3.0)]
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(2.0, 1.5, math.pi / 2)]), 0.0).ok

    def planned_omega(t: float) -> float:
        core.on_odom(OdomSample(0, 0, 0, 0, 0, t))
        req = core.plan_request(t)
        assert req is not None
        return req.law.omega_max_radps

    assert planned_omega(0.0) == NO_LEAD.omega_max_radps  # (positive control: no monitor)
    core.on_limit(1.0, 0.35, "clear", 0.5)
    core.on_limit(1.0, 0.04, "turn 0.04 rad", 0.6)
    assert core.limiter.lim.omega_max_radps == 0.04  # (the limiter: every bound)
    assert planned_omega(1.0) == 0.35
    for k in range(7, 70):
        core.on_limit(1.0, 0.04, "turn 0.04 rad", k * 0.1)
    assert planned_omega(7.0) == 0.04
    core.people = []  # no one moving: the bound retimes the path only, not planned with
    assert planned_omega(7.5) == NO_LEAD.omega_max_radps


# --- goals in map (nav/frames.py), the stale-plan stop --------------------------------------
INSTANT = ControlConfig(predict_s=0.02, predict_omega_s=0.02, lead=False)  # follows at once


def run_unicycle(core: ControlCore, t: float, until: float, pose: list[float],
                 on_tick: Callable[[float], None] | None = None) -> float:
    """Step the core against a chair that follows at the commanded speed (50 Hz)."""
    while t < until and core.active:
        if on_tick is not None:
            on_tick(t)
        out = core.step(t) or (0.0, 0.0)
        pose[2] = wrap(pose[2] + out[1] * 0.02)
        pose[0] += out[0] * math.cos(pose[2]) * 0.02
        pose[1] += out[0] * math.sin(pose[2]) * 0.02
        core.on_odom(OdomSample(pose[0], pose[1], pose[2], out[0], out[1], t))
        t += 0.02
    return t


def test_a_goal_in_map_is_refused_without_a_tracking_localization() -> None:
    core = fresh_core()
    req = GoalRequest(waypoints=[Pose2D(2, 0, 0)], frame_id="map")
    reply = core.set_goal(req, 0.0)
    assert not reply.ok and "needs localization: no localization heard" in reply.error
    core.on_correction((0.0, 0.0, 0.0))
    core.on_loc_state("lost", 0.0)
    assert "localization is lost" in core.set_goal(req, 0.0).error
    core.on_loc_state("tracking", 0.0)
    assert core.set_goal(req, 0.0).ok  # positive control


def test_a_goal_in_map_ends_where_the_correction_puts_it() -> None:
    """Odometry has drifted: map → odom is (0.5, -0.3, 5°). The chair must stop at the map
    goal's place in odom, not at the map goal's numbers."""
    corr = (0.5, -0.3, math.radians(5))
    core = fresh_core(INSTANT)
    core.on_correction(corr)
    core.on_loc_state("tracking", 0.0)
    goal = (2.5, 0.0, 0.0)
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(*goal)], frame_id="map"), 0.0).ok
    pose = [0.0, 0.0, 0.0]
    run_unicycle(core, 0.0, 40.0, pose, lambda t: core.on_loc_state("tracking", t))
    assert core.state == "arrived"
    want = compose(inverse(corr), goal)
    assert math.hypot(pose[0] - want[0], pose[1] - want[1]) < 0.05
    assert abs(wrap(pose[2] - want[2])) < math.radians(3)
    assert math.hypot(pose[0] - goal[0], pose[1] - goal[1]) > 0.3  # not the raw numbers


def driving_to_a_map_goal(blocked_abort_s: float) -> tuple[ControlCore, list[float], float]:
    """A core driving to (6, 0) in `map` under a tracking localization for 2 s (asserted: the
    positive control of the tests that then take the localization away)."""
    core = fresh_core(ControlConfig(blocked_abort_s=blocked_abort_s, predict_s=0.02,
                                    predict_omega_s=0.02, lead=False))
    core.on_correction((0.0, 0.0, 0.0))
    core.on_loc_state("tracking", 0.0)
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(6, 0, 0)], frame_id="map"), 0.0).ok
    pose = [0.0, 0.0, 0.0]
    t = run_unicycle(core, 0.0, 2.0, pose, lambda t: core.on_loc_state("tracking", t))
    assert core.state == "driving" and core.limiter.v.value > 0.3
    return core, pose, t


def test_lost_localization_stops_a_map_goal_then_it_resumes_or_aborts() -> None:
    core, pose, tracking = driving_to_a_map_goal(6.0)
    t = run_unicycle(core, tracking, tracking + 2.0, pose,
                     lambda t: core.on_loc_state("lost", t))
    assert core.state == "blocked" and core.reason == "localization: localization is lost, " \
                                                      "not tracking"
    assert core.limiter.at_rest  # braked to rest within the comfort limits
    x_stop = pose[0]
    t = run_unicycle(core, t, t + 2.0, pose, lambda t: core.on_loc_state("tracking", t))
    assert core.active and core.state != "blocked" and pose[0] > x_stop + 0.1  # resumed
    run_unicycle(core, t, t + 8.0, pose, lambda t: core.on_loc_state("lost", t))
    assert core.state == "aborted" and "localization is lost" in core.reason


@pytest.mark.parametrize("jump", [(0.5, 0.0, 0.0), (0.0, 0.0, math.radians(10))])
def test_a_map_goal_is_not_resumed_on_a_place_refound_elsewhere(
        jump: tuple[float, float, float]) -> None:
    """H33 / ISO 14118: localization lost, then tracking again with a correction 0.5 m or 10°
    from where it was lost (the chair stood still: a look-alike place?). The goal is aborted
    with the reason and the chair stays at rest; positive controls: the same correction, or one
    within 0.1 m / 2°, resumes (as in the test above)."""
    def refound(corr: tuple[float, float, float]) -> tuple[ControlCore, float]:
        core, pose, t = driving_to_a_map_goal(6.0)
        t = run_unicycle(core, t, t + 2.0, pose, lambda t: core.on_loc_state("lost", t))
        assert core.state == "blocked" and core.limiter.at_rest
        x_stop = pose[0]
        core.on_correction(corr)
        run_unicycle(core, t, t + 2.0, pose, lambda t: core.on_loc_state("tracking", t))
        return core, pose[0] - x_stop

    core, went = refound((0.1, 0.0, math.radians(2)))
    assert core.active and went > 0.1  # positive control: about where it was lost, resumed
    core, went = refound(jump)
    assert core.state == "aborted" and "re-found the chair" in core.reason
    assert "send the goal again" in core.reason and went == 0.0


def test_a_stale_plan_stops_the_chair_until_a_new_one_comes() -> None:
    core = fresh_core(INSTANT)
    core.inline_planning = False  # as in the node: plans come from a thread
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(6, 0, 0)]), 0.0).ok
    pose, t = [0.0, 0.0, 0.0], 0.0

    def planner(now: float) -> None:
        req = core.plan_request(now)
        if req is not None and now < 3.0:  # the planning thread starves after 3 s
            core.on_plan(compute(req), now)

    t = run_unicycle(core, 0.0, 3.0, pose, planner)
    assert core.final and core.limiter.v.value > 0.3  # control: driving on fresh plans
    run_unicycle(core, t, 6.0, pose, planner)  # (the final approach too needs fresh plans)
    assert core.active and core.limiter.at_rest  # stopped: the plan is 3 s old
    assert core.counters["stale_plan_stops"] > 0 and pose[0] < 5.8


def _post_field(posts: np.ndarray) -> object:
    from autochair.nav.field import Footprint, GridMap, NavField

    room = np.array([[-1.0, -3.0, 6.0, -3.0], [6.0, -3.0, 6.0, 3.0], [6.0, 3.0, -1.0, 3.0],
                     [-1.0, 3.0, -1.0, -3.0]])
    return NavField(GridMap.from_shapes(room, posts), Footprint())


# A post 0.7 m out at 45° from (2, 0): outside the body at 0° and at 90°, inside at 45°.
POST = np.array([[2.0 + 0.7 / math.sqrt(2), 0.7 / math.sqrt(2), 0.04]])


def test_an_in_place_turn_is_checked_over_its_whole_sweep() -> None:
    """H40 (the navigation suite's final turn touched a bench): the core's own in-place turn
    is refused where the body would sweep over something that neither end pose touches."""
    core = fresh_core(INSTANT)
    here = OdomSample(2.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    core.on_field(_post_field(np.zeros((0, 3))))  # type: ignore[arg-type]
    assert core._room_to_turn(here, math.pi / 2)  # positive control: no post
    core.on_field(_post_field(POST))  # type: ignore[arg-type]
    fld = core.field
    ends = np.array([0.0, math.pi / 2])  # the turn's start and end poses are clear
    assert fld is not None and min(fld.footprint_clearance(2.0, 0.0, ends)) > 0.1
    assert not core._room_to_turn(here, math.pi / 2)  # the sweep crosses the post
    assert core._room_to_turn(here, -math.pi / 2)  # the other way round is clear


def test_a_goal_whose_final_turn_would_hit_a_post_ends_without_turning() -> None:
    def run(posts: np.ndarray) -> tuple[ControlCore, float]:
        core = fresh_core(INSTANT)
        core.on_field(_post_field(posts))  # type: ignore[arg-type]
        core.on_odom(OdomSample(2.0, 0.0, 0.0, 0.0, 0.0, 0.0))
        assert core.set_goal(GoalRequest(waypoints=[Pose2D(2.0, 0.0, math.pi / 2)]), 0.0).ok
        pose, turned = [2.0, 0.0, 0.0], 0.0
        t = 0.0
        while t < 25.0 and core.active:
            t = run_unicycle(core, t, t + 0.02, pose)
            turned = max(turned, pose[2])
        return core, turned

    free, turned = run(np.zeros((0, 3)))
    assert free.state == "arrived" and turned > math.radians(87)  # positive control
    core, turned = run(POST)
    assert turned < math.radians(3), f"turned {math.degrees(turned):.0f}° into the post"
    assert core.state == "aborted" and core.reason, core.reason


def test_the_law_approach_near_the_goal_is_checked_over_its_sweep() -> None:
    """The final approach between the tolerance and 0.1 m of the goal runs the law at its ω
    floor, a spin about a point within r of the axle (it swung a chair 14° on beside a wall in
    the navigation suite): checked like an in-place turn (H40) over every yaw between the
    chair's, the bearing to the goal and the goal's, with room for the last r."""
    core = fresh_core(INSTANT)
    here = OdomSample(2.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    left = Pose2D(2.0, 0.07, math.pi / 2)  # 7 cm to the left, facing left
    core.on_field(_post_field(np.zeros((0, 3))))  # type: ignore[arg-type]
    assert core._room_to_approach(here, left, 0.07)  # positive control: no post
    core.on_field(_post_field(POST))  # type: ignore[arg-type]
    assert core._room_to_turn(here, 0.0, 0.0, 0.07)  # where the chair stands is clear
    assert not core._room_to_approach(here, left, 0.07)  # turning left crosses the post
    right = Pose2D(2.0, -0.07, -math.pi / 2)
    assert core._room_to_approach(here, right, 0.07)  # the other way round is clear


def test_a_non_finite_correction_stops_a_map_goal_like_a_lost_localization() -> None:
    """H33: a NaN or inf `map` → `odom` correction made every waypoint NaN; the planner raised
    on every control step (no command, the goal "driving" for ever). Unknown is unsafe: it is
    a localization that cannot be trusted — blocked at rest, aborted after blocked_abort_s."""
    core, pose, t = driving_to_a_map_goal(3.0)  # positive control: driving
    core.on_correction((math.nan, 0.0, 0.0))
    t = run_unicycle(core, t, t + 2.0, pose, lambda t: core.on_loc_state("tracking", t))
    assert core.state == "blocked" and "correction is not finite" in core.reason
    assert core.limiter.at_rest
    reply = core.set_goal(GoalRequest(waypoints=[Pose2D(3, 0, 0)], frame_id="map"), t)
    assert not reply.ok and "needs localization: its map → odom correction is not finite" \
        in reply.error
    core.on_correction((0.0, 0.0, math.inf))
    run_unicycle(core, t, t + 4.0, pose, lambda t: core.on_loc_state("tracking", t))
    assert core.state == "aborted" and "not finite" in core.reason


def test_a_chair_stopped_short_beside_the_goal_drives_its_straight_final() -> None:
    """Stopped 7 cm short of the goal and 3.5 cm beside its line (beyond the capture radius,
    within the tolerance), next to a post: the law's approach would swing the body round into
    the post and is refused (H40), so the chair stood there (the navigation suite's tight
    goals; measured). MPEPC hands over the straight final it has checked (Mpepc
    .final_heading): the chair drives straight onto the goal's along-track point, no turn."""
    def run(posts: np.ndarray) -> tuple[ControlCore, list[float], float]:
        core = fresh_core(INSTANT)
        core.on_field(_post_field(posts))  # type: ignore[arg-type]
        core.on_odom(OdomSample(2.0, 0.0, 0.0, 0.0, 0.0, 0.0))
        assert core.set_goal(GoalRequest(waypoints=[Pose2D(*goal)]), 0.0).ok
        pose, turned, t = [2.0, 0.0, 0.0], 0.0, 0.0
        while t < 20.0 and core.active:
            t = run_unicycle(core, t, t + 0.02, pose)
            turned = max(turned, abs(pose[2]))
        return core, pose, turned

    goal = (2.07, 0.035, 0.0)
    post = np.array([[2.0 + 0.78 * math.cos(0.87), 0.78 * math.sin(0.87), 0.04]])  # at 50°
    core = fresh_core(INSTANT)
    core.on_field(_post_field(post))  # type: ignore[arg-type]
    here = OdomSample(2.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert not core._room_to_approach(here, Pose2D(*goal), 0.078)  # the law's sweep: the post
    free, _, _ = run(np.zeros((0, 3)))
    assert free.state == "arrived"  # positive control: no post
    core, pose, turned = run(post)
    assert core.state == "arrived", core.reason
    assert turned < math.radians(1) and math.hypot(pose[0] - 2.07, pose[1] - 0.035) <= 0.05


def _handed_the_goal(posts: np.ndarray, goal: tuple[float, float, float],
                     rz: tuple[float, float], turn: Callable[[SCurveAxis], None]
                     ) -> ControlCore:
    """A core at rest at (2, 0, 0) by `posts`, its ω axis set by `turn`, then MPEPC hands the
    goal over (a plan whose target (r, θ) takes it); stepped once."""
    from autochair.nav.mpepc import Plan
    from autochair.nav.planner import PlanResult

    core = fresh_core(INSTANT)
    core.inline_planning = False
    core.on_field(_post_field(posts))  # type: ignore[arg-type]
    core.on_odom(OdomSample(2.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(*goal)]), 0.0).ok
    turn(core.limiter.w)
    plan = Plan((*rz, 0.0, 0.15), goal, 0.15, 0.0, 0.0, 1.0, 1.0, np.zeros((1, 3)), True, 0.1,
                0.0, 1)
    core.on_plan(PlanResult(core.goal_id, core.index, core.field, None, plan), 0.0)  # type: ignore[arg-type]
    core.step(0.0)
    return core


def test_the_straight_final_is_driven_off_the_wide_line_while_a_turn_only_creeps_out() -> None:
    """As above, but the turn that lined the chair up is still creeping out (|ω| < 0.01
    rad/s, its move not ended) when MPEPC hands the goal over: MPEPC counts that as at rest
    (Mpepc.final_heading's straight), the core did not (capture radius, not final_line) and
    ran the law or refused it, and at office B's desk the two alternated till "no progress"
    (nav_eval seed 7). Now the core drives the straight final too (its swing: lateral_stop)."""
    goal = (2.07, 0.035, 0.0)
    post = np.array([[2.0 + 0.78 * math.cos(0.87), 0.78 * math.sin(0.87), 0.04]])

    def handed_over(creep: float) -> ControlCore:
        def creeping(w: SCurveAxis) -> None:
            if creep:
                w.move(creep, 0.02)  # the turn's last creep
                assert w.moving and 0.0 < abs(w.value) < 0.01
        return _handed_the_goal(post, goal, (0.078, 0.46), creeping)

    at_rest = handed_over(0.0)
    assert at_rest.final and at_rest.straight  # positive control: from rest
    creeping = handed_over(0.0005)
    assert creeping.final and creeping.straight
    assert "approaches_refused" not in creeping.counters


def test_a_straight_final_whose_turn_still_swings_on_has_the_swing_checked() -> None:
    """H66: the straight final began with ω at 0.36 rad/s and rising (the law had been
    steering): the limiter braking it jerk-limited turned the chair 14° on over its 12 cm
    "straight" (the old estimate, ω·|ω|/2ω̇, read 1.3°), and the body touched the cabinet beside
    the goal (nav_eval seed 7, "behind the cabinet", found with a change to the final moves).
    Now the swing is the limiter's own braking, and a swing the body's turn cannot make
    clear of the map is no straight final."""
    fp, goal = Footprint(), (2.12, 0.0, 0.0)
    post = np.array([[2.0 + fp.front_m + 0.06, fp.half_width_m + 0.17, 0.04]])  # front left

    def handed_over(posts: np.ndarray, turning: bool) -> ControlCore:
        def speeding_up(w: SCurveAxis) -> None:
            if turning:
                w.reset(0.36, 1.2)  # left, and still speeding up
        core = _handed_the_goal(posts, goal, (0.12, 0.0), speeding_up)
        assert core.final
        return core

    assert handed_over(post, False).straight  # positive control: at rest, straight on
    assert handed_over(np.zeros((0, 3)), True).straight  # the swing alone is no bar
    turning = handed_over(post, True)
    assert not turning.straight  # the body's swing towards the post: no straight final
    assert math.radians(8) < turning._turn_swing() < math.radians(15)  # ω·|ω|/2ω̇: 1.3°
    assert (turning.limiter.w.value, turning.limiter.w.rate) == (0.36, 1.2)  # (left as it was)
    # The monitor's |ω| bound at 0 (a turn blocked): the axis is capped, the swing is what it
    # still sends (none), and nothing raises (a copy of an axis capped to 0 did: found in the
    # monitored benchmark before merging).
    turning.on_limit(1.0, 0.0, "turn blocked", 0.0)
    assert turning._turn_swing() == 0.0

ROOM = [[-1.0, -3.0, 6.0, -3.0], [6.0, -3.0, 6.0, 3.0], [6.0, 3.0, -1.0, 3.0],
        [-1.0, 3.0, -1.0, -3.0]]  # walls x0 y0 x1 y1: a 7 × 6 m room


def _drive_plan(plan_z: tuple[float, float, float, float],
                target: tuple[float, float, float], goal: Pose2D, until_s: float,
                start: tuple[float, float, float] = (2.0, 0.0, 0.0), v0: float = 0.0,
                walls: list[list[float]] | None = None, straight_m: float = 0.0,
                watch: Callable[[ControlCore, tuple[float, float]], None] | None = None
                ) -> tuple[ControlCore, list[float], float]:
    """The core at `start` moving at `v0` towards `goal` (in a map of `walls`; None: no map),
    given one MPEPC plan (z, its target, vmax z[3]) re-sent every plan period for `until_s`,
    against a chair that follows at once (50 Hz); the core, the pose reached and the largest
    |ω| sent. `watch`: called with the core and what it sent, every tick."""
    from autochair.nav.field import GridMap, NavField
    from autochair.nav.mpepc import Plan
    from autochair.nav.planner import PlanResult

    core = fresh_core(INSTANT)
    core.inline_planning = False
    if walls is not None:
        core.on_field(NavField(GridMap.from_shapes(np.array(walls), np.zeros((0, 3))),
                               Footprint()))
    core.on_odom(OdomSample(*start, v0, 0.0, 0.0))
    assert core.set_goal(GoalRequest(waypoints=[goal]), 0.0).ok
    plan = Plan(plan_z, target, plan_z[3], 0.0, 0.0, 1.0, 1.0, np.zeros((1, 3)), False,
                math.nan, 0.0, 1, straight_m=straight_m)
    pose, t, spin = list(start), 0.0, 0.0
    while t < until_s and core.active:
        core.on_plan(PlanResult(core.goal_id, core.index, core.field, None, plan), t)  # type: ignore[arg-type]
        for _ in range(25):
            out = core.step(t) or (0.0, 0.0)
            if watch is not None:
                watch(core, out)
            spin = max(spin, abs(out[1]))
            pose[2] = wrap(pose[2] + out[1] * 0.02)
            pose[0] += out[0] * math.cos(pose[2]) * 0.02
            pose[1] += out[0] * math.sin(pose[2]) * 0.02
            core.on_odom(OdomSample(pose[0], pose[1], pose[2], out[0], out[1], t))
            t += 0.02
    return core, pose, spin


def _straight_stage(wall_x: float | None, straight_m: float) -> tuple[ControlCore, list[float],
                                                                        float]:
    """The core at rest at (2, 0, 0) in a room (with a wall across the way at `wall_x`) given
    MPEPC's plan "drive 0.12 m straight and stop" (Mpepc.stage_plan; `straight_m` 0: the same
    target as a law target), re-sent every plan period for 3 s as the planner continues it;
    the pose reached and the largest |ω| sent."""
    walls = ROOM + ([] if wall_x is None else [[wall_x, -0.8, wall_x, 0.8]])
    return _drive_plan((0.12, 0.0, 0.0, 0.15), (2.12, 0.0, 0.0), Pose2D(4.0, 1.5, 0.0), 3.0,
                       walls=walls, straight_m=straight_m)


def test_a_straight_stage_is_driven_onto_its_point_without_steering() -> None:
    """A stage of a tight goal's way in (Mpepc.stage_plan): the core drives the straight
    move itself, time-optimally and without steering (its straight final's move), and stops
    on the point. As a law target that close the chair crept (v ≤ vmax·r/r_thresh) and the
    plans around it predicted it ending a cm or two off (the navigation suite's tight goals,
    aborted; measured)."""
    _, pose, _ = _straight_stage(None, 0.0)  # positive control: the law creeps
    assert pose[0] < 2.12 - 0.03
    core, pose, spin = _straight_stage(None, 0.12)
    assert pose[0] == pytest.approx(2.12, abs=0.005) and abs(pose[1]) < 1e-9 and spin == 0.0
    assert core.limiter.at_rest


def test_a_straight_stage_is_driven_no_faster_than_its_plan_was_evaluated_at() -> None:
    """H67: a straight stage's plan carries the speed MPEPC evaluated it at (people, its stop;
    Plan.vmax_mps); the core's move drives it at most that fast, and still lands on its point.
    Before, the move ran at the goal's top speed: a 1.5 m stage evaluated at 0.4 m/s peaked at
    over 0.9 (positive control: the same stage given 1.2 m/s)."""
    def peak(vmax: float) -> tuple[float, list[float]]:
        sent: list[float] = []
        _, pose, spin = _drive_plan((1.5, 0.0, 0.0, vmax), (1.5, 0.0, 0.0),
                                    Pose2D(4.0, 1.5, 0.0), 6.0, start=(0.0, 0.0, 0.0),
                                    walls=ROOM, straight_m=1.5,
                                    watch=lambda core, out: sent.append(out[0]))
        assert spin == 0.0
        return max(sent), pose

    fast, _ = peak(1.2)
    assert fast > 0.9
    slow, pose = peak(0.4)
    assert 0.38 < slow <= 0.4 + 1e-9
    assert pose[0] == pytest.approx(1.5, abs=0.005)


def test_a_straight_stage_into_an_obstacle_is_refused_by_the_core() -> None:
    """The core rechecks a straight stage's translation (as its straight final's from beside
    the goal's line): a wall 8 cm ahead of the front (the stage would end 4 cm inside it)
    and the chair does not move."""
    front = 2.0 + Footprint().front_m
    core, pose, _ = _straight_stage(front + 0.08, 0.12)
    assert pose == [2.0, 0.0, 0.0] and core.counters.get("straights_refused", 0) > 0
    # positive control: the same wall 20 cm further on leaves room for it
    core, pose, _ = _straight_stage(front + 0.28, 0.12)
    assert pose[0] == pytest.approx(2.12, abs=0.005)


def _rolled_past(wall_y: float | None) -> tuple[ControlCore, float]:
    """The core rolling at 0.2 m/s at (2, 0, 0) in a room (a wall alongside at `wall_y`),
    given MPEPC's in-place plan "turn to 0° at (1.95, 0)": a point the chair has rolled 5 cm
    past (its pose predicted a few cm off), re-sent every plan period for 1.5 s; the largest
    |ω| sent."""
    walls = ROOM + ([] if wall_y is None else [[0.0, wall_y, 4.0, wall_y]])
    core, _, spin = _drive_plan((0.0, 0.0, 0.0, 0.15), (1.95, 0.0, 0.0),
                                Pose2D(4.5, -1.5, 0.0), 1.5, v0=0.2, walls=walls)
    return core, spin


def test_a_chair_rolled_past_an_in_place_plans_point_is_not_spun_round_without_room() -> None:
    """The law towards a point just behind the chair spins it round (MPEPC predicts that, but
    from its predicted pose: one a few cm off swung the body 33° onto a wall, nav_eval seed 7
    with predict_s 0.66). With a wall 0.6 m beside the axle the core brakes instead."""
    core, spin = _rolled_past(None)  # positive control: in the open the law spins it round
    assert spin > 0.3 and not core.counters.get("spins_refused")
    core, spin = _rolled_past(0.6)
    assert spin < 0.05 and core.counters.get("spins_refused", 0) > 0
    assert core.limiter.at_rest


def test_the_prediction_moves_old_odometry_on_by_its_age() -> None:
    """The pose the law acts on is the odometry moved on over the sample's age (stamp to
    arrival, and arrival to now) at its own velocity, then by the chain's pending motion: on
    a loaded CPU the older pose made the straight final brake late (a 3 m goal overshot by
    6-7 cm, recorded live)."""
    core = fresh_core(INSTANT)
    fresh = core._predicted(OdomSample(1.0, 0.0, 0.0, 0.8, 0.0, 5.0), 5.0)
    old = core._predicted(OdomSample(1.0, 0.0, 0.0, 0.8, 0.0, 5.0, age_s=0.05), 5.1)
    assert old.x - fresh.x == pytest.approx(0.8 * 0.15) and old.y == fresh.y == 0.0
    # turning: the arc's chord; at rest nothing moves (positive control of the shift)
    arc = core._predicted(OdomSample(0.0, 0.0, 0.0, 0.5, 1.0, 5.0, age_s=0.1), 5.1)
    assert arc.yaw == pytest.approx(0.2) and arc.y == pytest.approx(0.5 * 0.2 * math.sin(0.1))
    rest = core._predicted(OdomSample(1.0, 0.0, 0.0, 0.0, 0.0, 5.0, age_s=0.1), 5.2)
    assert (rest.x, rest.y, rest.yaw) == (1.0, 0.0, 0.0)
    # a wrong stamp cannot throw the pose far: at most MAX_ODOM_AGE_S
    far = core._predicted(OdomSample(1.0, 0.0, 0.0, 0.8, 0.0, 5.0, age_s=100.0), 5.0)
    assert far.x - fresh.x == pytest.approx(0.8 * 0.3)


def test_a_late_handover_does_not_carry_the_chair_past_its_goal() -> None:
    """Heading for the goal 1 m ahead at 1 m/s, while the plans still name a target beyond it
    (the plan that hands the goal over comes late on a loaded CPU: a forward-only chair
    overshot a goal by 6 cm, which it cannot come back to), the law is capped to a stop on
    the goal at the limiter's full braking."""
    core, pose, _ = _drive_plan((3.0, 0.0, 0.0, 1.2), (3.0, 0.0, 0.0), Pose2D(1.0, 0.0, 0.0),
                                4.0, start=(0.0, 0.0, 0.0), v0=1.0)
    assert core.odom is not None
    x, v = pose[0], core.odom.v
    assert 0.95 < x <= 1.0 + 1e-6 and v < 0.1, (x, v)


# Office B's door (nav_eval "office A (facing in) to office B"): the goal 1.7 m ahead, MPEPC's
# target beside it; the chair on the goal's line, and 0.15 m beside it.
OFFICE_B = Pose2D(12.4, 2.5, math.pi / 2)
BESIDE_B = (12.46, 2.44, 1.67)
OFFICE_B_DOOR = [(12.4, 0.8, math.pi / 2), (12.52, 0.79, math.radians(89.0))]


@pytest.mark.parametrize("start", OFFICE_B_DOOR)
def test_mpepc_predicts_the_cores_braking_for_its_goal(start: tuple[float, float, float]
                                                       ) -> None:
    """Following a plan towards the goal, the core caps v to a stop on it; MPEPC's rollout of
    that plan does too. Without it, it put the chair 6-9 cm further on after 1 s at office B's
    door (at 0.71 m/s with its acceleration-only v, the core at 0.81-0.88, 0.2 m before the
    goal at 1.2 m/s) than the core drives it."""
    from autochair.nav.mpepc import Mpepc
    from autochair.nav.planner import free_field

    goal = (OFFICE_B.x_m, OFFICE_B.y_m, OFFICE_B.yaw_rad)
    mp = Mpepc(free_field([start[:2], goal[:2]], Footprint()), INSTANT.law(0.025))
    z = np.array([[*mp.relative(start, BESIDE_B), 1.2]])
    _, pose, _ = _drive_plan(tuple(z[0]), BESIDE_B, OFFICE_B, 1.0, start=start, v0=0.87)
    k = round(1.0 / mp.p.dt_s) - 1  # (the rollout's pose after 1 s)
    for last, near in ((True, True), (False, False)):  # (not the last waypoint: no cap)
        xs, ys, *_ = mp.simulate(start, 0.87, 0.0, z, goal=goal, last=last)
        off = math.hypot(xs[0, k] - pose[0], ys[0, k] - pose[1])
        assert (off < 0.02) if near else (off > 0.05), (last, off)


@pytest.mark.parametrize("start", OFFICE_B_DOOR)
def test_a_chair_beside_its_goals_line_still_brakes_for_it(start: tuple[float, float, float]
                                                           ) -> None:
    """Speeding up towards office B's goal, on its line or 0.15 m beside it (more than two
    tolerances off, less than it can still steer out at its speed), the plans' target beside
    the goal: v stays within a stop on the goal at the limiter's full braking, and the chair
    does not swing past it. Braked only within 0.1 m of its line, it reached 1.18 m/s 1 m
    before the goal and swung past it to 137° (nav_eval, seed 7: blocked by the desk)."""
    from autochair.geometry import along_lateral
    from autochair.nav.mpepc import Mpepc

    over = [-math.inf]  # the most v went over a stop on the goal

    def watch(core: ControlCore, out: tuple[float, float]) -> None:
        o, lv = core.odom, core.limiter.v
        assert o is not None
        along = along_lateral((o.x, o.y, o.yaw), OFFICE_B.x_m, OFFICE_B.y_m)[0]
        if along > 0.0:
            over[0] = max(over[0], out[0] - braking_speed(along, lv.amax, lv.jmax))

    r, theta, delta = Mpepc.relative(start, BESIDE_B).tolist()
    _, pose, _ = _drive_plan((r, theta, delta, 1.2), BESIDE_B, OFFICE_B, 3.0, start=start,
                             v0=0.87, watch=watch)
    assert over[0] <= 1e-9, over[0]
    assert abs(math.degrees(pose[2]) - 90.0) < 10.0, math.degrees(pose[2])
def test_a_stage_turns_straight_is_asked_for_by_the_core() -> None:
    """The core's plan requests carry a stage turn's straight (Plan.then: where it lands), so
    the planner carries the stage on once the turn is done instead of looking again from the
    turned chair (nav_eval seed 1, office A's far corner: MPEPC turned it back, a loop)."""
    from autochair.nav.field import GridMap, NavField
    from autochair.nav.mpepc import Plan
    from autochair.nav.planner import PlanResult

    walls = np.array([[-1.0, -3.0, 6.0, -3.0], [6.0, -3.0, 6.0, 3.0], [6.0, 3.0, -1.0, 3.0],
                      [-1.0, 3.0, -1.0, -3.0]])
    core = fresh_core(INSTANT)
    core.inline_planning = False
    core.on_field(NavField(GridMap.from_shapes(walls, np.zeros((0, 3))), Footprint()))
    core.on_odom(OdomSample(2.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(4.0, 1.5, 0.0)]), 0.0).ok

    def request(then: tuple[float, float] | None, t: float) -> object:
        plan = Plan((0.0, 0.3, 0.0, 0.15), (2.0, 0.0, 0.3), 0.15, 0.0, 0.0, 1.0, 1.0,
                    np.zeros((1, 3)), False, math.nan, 0.0, 1, final_turn=True, then=then)
        core.on_plan(PlanResult(core.goal_id, core.index, core.field, None, plan), t)  # type: ignore[arg-type]
        return core.plan_request(t + 1.0)

    req = request((2.2, 0.06), 0.0)
    assert req is not None and req.then == (2.2, 0.06)  # type: ignore[attr-defined]
    assert req.previous[2] == pytest.approx(0.3)  # type: ignore[attr-defined]
    # positive control: a turn that is not a stage's (the final manoeuvre's): nothing after it
    req = request(None, 2.0)
    assert req is not None and req.then is None  # type: ignore[attr-defined]


def test_arrival_is_judged_on_the_measured_heading_not_the_predicted_one(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The core steers on the pose predicted from the commands it sent (`_predicted`); with
    the safety monitor's |ω| bound holding the turn back, that ran ahead of the chair, and a
    goal beside office B's desk ended "arrived" 34° off its heading (nav_eval --monitor seed
    7, with the final turn refused by the monitor). At rest, at the goal's position, the
    prediction on the goal's heading and the chair 20° off: not arrived (the old core
    arrived); with the chair on it too, arrived (positive control)."""
    def at_rest_at_goal(measured_yaw: float) -> ControlCore:
        core = fresh_core(INSTANT)
        core.on_odom(OdomSample(0.0, 0.0, measured_yaw, 0.0, 0.0, 0.0))
        assert core.set_goal(GoalRequest(waypoints=[Pose2D(0.0, 0.0, 0.0)]), 0.0).ok
        monkeypatch.setattr(core, "_predicted", lambda o, now: OdomSample(
            o.x, o.y, 0.0, o.v, o.omega, o.t))  # (the prediction: on the goal's heading)
        for k in range(10):
            core.on_odom(OdomSample(0.0, 0.0, measured_yaw, 0.0, 0.0, 0.02 * k))
            core.step(0.02 * k)
        return core

    assert at_rest_at_goal(0.0).state == core_mod.ARRIVED
    off = at_rest_at_goal(math.radians(20.0))
    assert off.state != core_mod.ARRIVED and off.active


def test_the_cores_own_final_approach_is_driven_no_faster_than_the_plans_sight_rule() -> None:
    """H67: MPEPC caps every candidate by a door's sight rule (Mpepc.sight_cap), the goal's
    own approach (row 0) too, and hands that cap on (Plan.sight_mps); the core's own final
    approach drives the law at the goal's top speed, so it must keep to it as well, else it
    drives faster than MPEPC checked it (through a door at up to 1.2 m/s). A goal 4 m ahead,
    handed over (is_goal) with a cap of 0.3 m/s: the commanded speed peaks at it (positive
    control: with none, over 1 m/s)."""
    from autochair.nav.mpepc import Plan
    from autochair.nav.planner import PlanResult

    goal = (4.0, 0.0, 0.0)

    def peak(sight: float) -> float:
        core = fresh_core(INSTANT)
        core.inline_planning = False
        core.on_field(_post_field(np.zeros((0, 3))))  # type: ignore[arg-type]
        assert core.set_goal(GoalRequest(waypoints=[Pose2D(*goal)]), 0.0).ok
        plan = Plan((4.0, 0.0, 0.0, 1.2), goal, 1.2, 0.0, 0.0, 1.0, 1.0, np.zeros((1, 3)),
                    True, 0.5, 0.0, 1, sight_mps=sight)
        top = [0.0]

        def fresh(t: float) -> None:  # (a plan each cycle, as MPEPC's, handing the goal on)
            if round(t / 0.02) % 10 == 0:
                core.on_plan(PlanResult(core.goal_id, core.index, core.field, None, plan), t)  # type: ignore[arg-type]
            top[0] = max(top[0], core.limiter.v.value)

        run_unicycle(core, 0.0, 3.0, [0.0, 0.0, 0.0], fresh)
        assert core.final
        return top[0]

    assert peak(math.inf) > 1.0
    assert 0.25 < peak(0.3) <= 0.3 + 1e-9


def _to_lineup(monitor: bool) -> tuple[ControlCore, list[tuple[float, float]]]:
    """The core 0.15 m from a door's line-up pose (MPEPC's target, the goal beyond the door),
    facing 42° off its heading and creeping on at 0.09 m/s, as nav_eval --monitor seed 7's
    "door: back to room A" came to it; `monitor`: the safety monitor's limit is in force (its
    bound the cap: clear). A chair that follows at once; (v, ω) sent until the line-up is
    passed (3 s at most)."""
    from autochair.nav.mpepc import Plan
    from autochair.nav.planner import PlanResult

    core = fresh_core(INSTANT)
    core.inline_planning = False
    pose = [5.69, 0.94, math.radians(138.0)]
    lineup = Pose2D(5.55, 1.01, math.pi)
    core.on_odom(OdomSample(pose[0], pose[1], pose[2], 0.09, 0.0, 0.0))
    if monitor:
        core.on_limit(1.2, 1.0, "clear", 0.0)
    assert core.set_goal(GoalRequest(waypoints=[lineup, Pose2D(1.0, 0.0, math.pi)]), 0.0).ok
    core.lineups = 1  # (as the route check inserts it before the door)
    core.limiter.v.reset(0.09)
    z = egocentric(pose[0], pose[1], pose[2], lineup.x_m, lineup.y_m, lineup.yaw_rad)
    plan = Plan((*z, 1.2), (lineup.x_m, lineup.y_m, lineup.yaw_rad), 1.2, 0.0, 0.1, 1.0, 0.1,
                np.zeros((1, 3)), True, math.nan, 0.0, 1)
    sent: list[tuple[float, float]] = []
    t = 0.0
    while t < 3.0 and core.index == 0:
        core.on_plan(PlanResult(core.goal_id, core.index, core.field, None, plan), t)  # type: ignore[arg-type]
        for _ in range(25):
            if monitor:
                core.on_limit(1.2, 1.0, "clear", t)
            v, w = core.step(t) or (0.0, 0.0)
            sent.append((v, w))
            pose[2] = wrap(pose[2] + w * 0.02)
            pose[0] += v * math.cos(pose[2]) * 0.02
            pose[1] += v * math.sin(pose[2]) * 0.02
            core.on_odom(OdomSample(pose[0], pose[1], pose[2], v, w, t))
            t += 0.02
    return core, sent


def test_a_doors_line_up_is_planned_with_the_lasers_points_of_the_last_second() -> None:
    """H79: at a door's line-up the plan request carries the laser's points of the scans
    within SCAN_WINDOW_S (Mpepc.through_door ranks the door's straights by them); one scan
    samples a jamb's end a beam apart, the scans from the way up fill it in. Older scans are
    left out, and away from a line-up none is sent (positive control: the same core before
    its line-up)."""
    from autochair.control.core import SCAN_WINDOW_S

    core = fresh_core(INSTANT)
    core.on_odom(OdomSample(0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(2.0, 0.0, 0.0)]), 0.0).ok
    core.on_scan(0.0, np.ones((3, 2)))
    req = core.plan_request(0.0)
    assert req is not None and not req.door and req.scan is None
    core, _ = _to_lineup(monitor=True)
    t = core.odom.t if core.odom is not None else 0.0
    core.on_scan(t - SCAN_WINDOW_S - 0.1, np.full((5, 2), 9.0))
    core.on_scan(t - 0.5, np.ones((3, 2)))
    core.on_scan(t - 0.1, np.ones((4, 2)))
    req = core.plan_request(t)
    assert req is not None and req.door
    assert req.scan is not None and req.scan.shape == (7, 2) and (req.scan == 1.0).all()


def test_a_lineup_within_reach_is_turned_onto_not_steered_onto_by_an_s() -> None:
    """H76 (nav_eval --monitor seed 7, back to room A): 0.15 m from a door's line-up pose,
    42° off its heading, the law's way onto it is an S at its ω floor: it turns away first
    (ω −0.5 rad/s at 0.06 m/s), then back. The safety monitor sweeps the measured arc, which
    the flip swings from one side to the other; a wall on the side turned to first dropped its
    free extent 0.82 -> 0.08 m within 0.3 s with v still sent, the PID latched its stop and
    the goal ended. With the monitor the core turns in place onto the line-up's heading (v
    braked, ω one-signed) and the line-up is reached there. Positive control: without the
    monitor the law's S is driven as before (ω of both signs while moving over 0.05 m/s)."""
    core, sent = _to_lineup(monitor=True)
    assert core.index == 1 and core.active  # (the line-up passed: on to its door)
    assert min(w for _, w in sent) > -1e-9  # (never turned away from its heading)
    assert all(v <= 0.09 + 1e-9 for v, _ in sent)
    _, sent = _to_lineup(monitor=False)
    turning = [w for v, w in sent if v > 0.05]
    assert min(turning) < -0.1 and max(turning) > 0.1


def test_a_stand_read_in_a_door_stays_in_it_till_the_chair_moves() -> None:
    """H75: standing with the laser in a door's plane, the beams along the wall's line cleared
    the jambs off the live map within ~10 s (nav_eval --map scans, door_person); the door's
    stand rule then read no door, and MPEPC turned the chair in the frame, 4.8 cm from the
    jamb, with the person 1.5 m off. Once a plan at rest reads the chair in a door
    (PlanResult.in_door), the core says so in every request while it stands there (within 2 cm
    and 1°), whatever the map; moved on, no longer."""
    core = fresh_core(INSTANT)
    core.on_odom(OdomSample(0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(3.0, 0.0, 0.0)]), 0.0).ok
    req = core.plan_request(0.0)
    assert req is not None and not req.in_door
    res = compute(req)
    assert not res.in_door  # (free floor)
    core.on_plan(dataclasses.replace(res, in_door=True), 0.1)
    req = core.plan_request(0.6)
    assert req is not None and req.in_door
    core.on_odom(OdomSample(0.05, 0.0, 0.0, 0.0, 0.0, 0.7))
    req = core.plan_request(1.2)
    assert req is not None and not req.in_door
