"""The control core plans v under the safety monitor's forward bound (H76): lockstep on the
simulated chair, the tuned velocity PID requiring the monitor's limit, the monitor's forward
bound from a wall ahead (its braking curve over the free extent, safety/core.py stop_speed)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from bench.control_eval import deriv, make_pid, smooth

from autochair.control.core import ControlConfig, ControlCore, OdomSample
from autochair.safety.core import SafetyTuning, stop_speed
from autochair.tune.lockstep import DT, Rig
from autochair_msgs import GoalRequest, Pose2D

SCAN_S = 0.1  # the laser's scan period: one limit a scan
FRONT_M = 1.0  # the padded footprint's front ahead of the axle (0.95 + 0.05)


def drive_to_wall(wall_m: float, goal_m: float, blocked: tuple[float, float] | None = None,
                  gone_s: float = math.inf) -> dict[str, float | str]:
    """A straight goal `goal_m` ahead, a wall `wall_m` ahead of the axle: the monitor's
    forward bound each scan from the chair's true pose (`blocked`: 0 over that window, as
    for someone stepping in front). The goal's state and reason, the scans whose bound the
    PID clamped the command to, by how much at most (m/s), the chair's peak jerk (m/s³, as
    nav_eval measures it) and how far it moved after the goal ended."""
    m, cfg = SafetyTuning(), ControlConfig()
    rig = Rig(make_pid("tuned", True), start=(0.0, 0.0, 0.0))
    core = ControlCore(cfg)
    every = round(1.0 / (cfg.rate_hz * DT))
    scan_every = round(SCAN_S / DT)
    bound, clamped, over = math.inf, 0, 0.0
    v: list[float] = []
    t_end, x_end = math.inf, math.nan
    k = 0
    while True:
        t = k * DT
        st = rig.sense()
        core.on_odom(OdomSample(st.x, st.y, st.yaw, st.v, st.omega, t))
        if k % scan_every == 0:
            free = wall_m - rig.chair.x - FRONT_M if t < gone_s else math.inf
            bound = min(m.v_max_fwd_mps, stop_speed(free, m.decel_mps2, m.reaction_s,
                                                    m.stop_margin_m))
            if blocked is not None and blocked[0] <= t < blocked[1]:
                bound = 0.0
            rig.core.set_limit(bound, 0.0, 1.0, t, 0.0)
            core.on_limit(bound, 1.0, f"free fwd {free:.2f} m", t)
        if k == 0:
            assert core.set_goal(GoalRequest(waypoints=[Pose2D(goal_m, 0.0, 0.0)]), t).ok
        out = core.step(t) if k % every == 0 else None
        if out is not None and out[0] > bound + 1e-3:
            clamped += 1
            over = max(over, out[0] - bound)
        rig.act(t, st.v, st.omega, out)
        v.append(rig.chair.v)
        if t_end == math.inf and not core.active:
            t_end, x_end = t, rig.chair.x
        if t > t_end + 3.0:
            break
        k += 1
        assert t < 40.0
    n, h = round(0.1 / DT), round(0.05 / DT)
    jerk = deriv(smooth(deriv(smooth(np.array(v), n), h), n), h)
    return {"state": core.state, "reason": core.reason, "clamped": clamped, "over": over,
            "jerk": float(np.abs(jerk).max()), "after": rig.chair.x - x_end}


def test_the_core_plans_v_under_the_monitors_forward_bound() -> None:
    """Someone stands 3.5 m ahead (the padded front 2.5 m off) of a chair on a 10 m goal and
    steps aside at 4 s: the monitor's bound falls below the goal's speed 1.5 m on. The core
    plans v under that braking curve, and the chair stays within the comfort jerk (2 m/s³):
    the PID clamps only the onset, where the bound first falls below its cap (it says
    nothing of a way longer than its cap's, 1.92 m), by < 0.1 m/s. The old core drove on at
    1.2 m/s into the PID's clamp, 0.70 m/s over the bound, and each scan's step of the clamp
    reached the chair (peak jerk 4.4 m/s³; nav_eval --monitor 2.3-4.3 m/s³, H76)."""
    r = drive_to_wall(4.5, 10.0, gone_s=4.0)
    assert r["state"] == "arrived", r
    assert float(r["jerk"]) <= 2.0 and float(r["over"]) < 0.15, r


def test_without_the_cap_the_pid_clamps_and_jolts(monkeypatch: pytest.MonkeyPatch) -> None:
    """Positive control of the test above: without the cap (the old core) the same drive is
    clamped far over the bound and jolts."""
    monkeypatch.setattr(ControlCore, "_fwd_cap", lambda self: math.inf)
    r = drive_to_wall(4.5, 10.0, gone_s=4.0)
    assert float(r["jerk"]) > 2.0 and float(r["over"]) > 0.5, r


def test_a_drive_the_forward_bound_stops_ends_the_goal() -> None:
    """The forward bound 0 from 1.5 s (someone steps in front) to 6 s, the chair at speed:
    a safety stop, as a turn's (H73): the goal ends naming the monitor, and the chair does
    not drive on when the bound lifts. (The old core ended it too, by the PID's latched
    stop, 2 s later as "does not follow"; with the core braking under the bound itself, a
    stop whose last command is (0, 0) is no stop to the PID, and the goal must end here.)"""
    r = drive_to_wall(20.0, 6.0, blocked=(1.5, 6.0))
    assert r["state"] == "aborted" and "safety monitor stopped" in str(r["reason"]), r
    assert abs(float(r["after"])) < 0.01, r


def test_a_bound_of_0_met_with_v_sent_ends_the_goal_though_it_lifts_at_once() -> None:
    """The forward bound 0 for a single scan (1.5 s) while the chair drives: the PID latches
    its stop on the v still sent (H03) and obeys that stream no more. The goal ends once the
    chair stands, naming the monitor. The old core took the bound's lift before the chair
    stood for a slow-down and drove on into the latched PID, ending 2 s later "does not
    follow" (nav_eval --monitor seed 7, the clutter's far side)."""
    r = drive_to_wall(20.0, 6.0, blocked=(1.5, 1.6))
    assert r["state"] == "aborted" and "safety monitor stopped" in str(r["reason"]), r


def test_the_last_sweep_step_before_a_bound_of_0_is_not_driven_into() -> None:
    """The monitor reads its free extent in sweep steps (`step_m`), and the next scan may read
    the last step before its bound of 0 as 0: the PID then latches a stop on any v > 0 still
    sent (H03), though the chair had not yet moved. So the core plans no v on a bound whose
    way left is one step (nav_eval --monitor seed 7: behind the table, creeping on at
    0.03 m/s, the goal ended at the PID's latch). Positive control: three steps left, it
    creeps on."""
    m = SafetyTuning()
    caps = []
    for steps in (1, 3):
        core = ControlCore(ControlConfig())
        core.on_odom(OdomSample(0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
        assert core.set_goal(GoalRequest(waypoints=[Pose2D(2.0, 0.0, 0.0)]), 0.0).ok
        free = m.stop_margin_m + steps * m.step_m
        bound = stop_speed(free, m.decel_mps2, m.reaction_s, m.stop_margin_m)
        core.on_limit(bound, 1.0, f"free fwd {free:.2f} m", 0.0)
        caps.append(core._fwd_cap())
    assert caps[0] == 0.0 < caps[1], caps


def test_a_goal_within_the_stop_margin_is_met_where_the_bound_ends_it() -> None:
    """A goal 0.08 m (padded) short of a wall, inside the monitor's 0.10 m stop margin: the
    straight final creeps under the forward bound and stands where it comes to 0, within the
    5 cm tolerance, and arrives; the PID never clamps a command (0 over the bound). The old
    core drove the straight final uncapped: through the bound's 0 at speed, the PID latched
    its stop and the chair coasted into the margin (nav_eval --monitor: the dead end)."""
    goal = 3.0
    r = drive_to_wall(goal + FRONT_M + 0.08, goal)
    assert r["state"] == "arrived", r
    assert r["clamped"] == 0, r


def test_a_goal_deeper_in_the_stop_margin_waits_as_blocked_then_ends_naming_the_monitor(
        ) -> None:
    """A goal 0.03 m short of a wall: the bound's last step leaves the chair standing 8 cm
    short, out of tolerance. It waits as blocked by the monitor, as for a person in front,
    and the goal ends after `blocked_abort_s` naming it. (Without the last step counted as
    the monitor's hold, it waited unexplained for "no progress", 15 s.)"""
    goal = 3.0
    r = drive_to_wall(goal + FRONT_M + 0.03, goal)
    assert r["state"] == "aborted" and "safety monitor held the chair for 12 s" in str(
        r["reason"]), r
    assert r["clamped"] == 0, r
