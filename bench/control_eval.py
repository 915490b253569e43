"""Control-law evaluation: a fixed suite of start/goal pairs driven in the simulator, in process
and in lockstep (deterministic, faster than real time).

Loop at the drive chain's rate (autochair.tune.lockstep.DT): ChairModel (sim/model.py) → encoder
counts → OdometryCore → ControlCore (stepped at its own configured rate, 50 Hz, like the node) →
VelocityPidCore → joystick volts → ChairModel. Comfort is measured from the odometry, not from the
commands: v and ω are smoothed with a centred moving average (0.1 s), then a, jerk and ω̇ are
central differences over ±0.05 s (odometry velocities are quantised: 1 count ≈ 31 µm, so raw
one-tick differences would report noise, not motion). The same peaks at the chair itself, from the
simulator's ground truth (true v and ω, exact each tick; smoothed 50 ms for the jerk), are the
goal's measure ("truth_*"); the planned (limiter) peaks are reported too ("cmd_*": the plan, not
what is sent, which leads the plan past the PID's prefilter: ControlConfig.lead).

Time is compared with four references: the trapezoid bound (straight line or in-place turn,
acceleration-limited), the jerk-limited S-curve bound, a turn–drive–turn reference, and the least
time any controller could take for a forward-only unicycle under all the comfort limits
(bench/min_time.py, solved once by collocation and cached in results/min_time.json):
`time_ratio_min`, the honest one (the first two ignore that a chair cannot move sideways).

The velocity PID is configured as the [pid] section (tuned gains and feed-forward model);
`--pid thesis` runs the thesis's ZN gains without a model for comparison.

    .venv/bin/python -m bench.control_eval [--quick] [--pid thesis]
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any

import msgspec
import numpy as np

from autochair.control.core import ARRIVED, ControlConfig, ControlCore, OdomSample
from autochair.geometry import wrap_angle as wrap
from autochair.nav.planner import PlanRequest, PlanResult, compute
from autochair.odometry.core import OdomState
from autochair.pid.core import PidConfig, VelocityPidCore, make_core
from autochair.tune.lockstep import DT, Rig  # DT: the drive chain's rate, for all benches
from autochair_msgs import GoalRequest, Pose2D

from .min_time import Limits, cached

SETTLE_S = 2.0  # keep simulating after arrival to measure the final error at rest
TIMEOUT_S = 60.0
FINAL_APPROACH_M = 1.0
REVERSAL_DEADBAND = 0.05  # rad/s: a sign change counts once ω passes this on the other side
RESULTS = Path(__file__).parent / "results" / "control_eval.json"


def suite() -> list[tuple[str, tuple[float, float, float], tuple[float, float, float]]]:
    """(name, start, goal): fixed, ≥ 24 pairs, including the cases the thesis's atan broke."""
    d = math.radians
    cases = [
        ("ahead 1 m", (0, 0, 0), (1, 0, 0)),
        ("ahead 3 m", (0, 0, 0), (3, 0, 0)),
        ("ahead 6 m", (0, 0, 0), (6, 0, 0)),
        ("ahead 0.3 m", (0, 0, 0), (0.3, 0, 0)),
        ("behind 2 m, same yaw", (0, 0, 0), (-2, 0, 0)),
        ("behind 2 m, u-turn", (0, 0, 0), (-2, 0, d(180))),
        ("behind 0.5 m", (0, 0, 0), (-0.5, 0, 0)),
        ("beside left 2 m", (0, 0, 0), (0, 2, 0)),
        ("beside right 2 m", (0, 0, 0), (0, -2, 0)),
        ("beside left 0.5 m", (0, 0, 0), (0, 0.5, 0)),
        ("beside left, facing it", (0, 0, 0), (0, 2, d(90))),
        ("beside right, facing away", (0, 0, 0), (0, -2, d(90))),
        ("diagonal 3,3", (0, 0, 0), (3, 3, d(45))),
        ("diagonal 3,3 yaw 0", (0, 0, 0), (3, 3, 0)),
        ("diagonal -3,2", (0, 0, 0), (-3, 2, d(135))),
        ("diagonal 2,-3 yaw -90", (0, 0, 0), (2, -3, d(-90))),
        ("turn in place 90", (0, 0, 0), (0, 0, d(90))),
        ("turn in place 180", (0, 0, 0), (0, 0, d(180))),
        ("turn in place -45", (0, 0, 0), (0, 0, d(-45))),
        ("parallel park 1 m left", (0, 0, 0), (1, 1, 0)),
        ("ahead 4 m, arrive facing back", (0, 0, 0), (4, 0, d(180))),
        ("from (2,1,30) to origin", (2, 1, d(30)), (0, 0, 0)),
        ("from (-1,-1,-120) to (1,2,60)", (-1, -1, d(-120)), (1, 2, d(60))),
        ("long 8 m", (0, 0, 0), (8, 1, d(10))),
        ("corridor 5 m", (0, 0, d(90)), (0, 5, d(90))),
        ("near 10 cm aside", (0, 0, 0), (0, 0.1, 0)),
        ("near 10 cm ahead", (0, 0, 0), (0.1, 0, 0)),
        ("offset start, goal behind", (1, 1, d(45)), (0, 0, d(45))),
    ]
    return [(n, tuple(map(float, s)), tuple(map(float, g))) for n, s, g in cases]  # type: ignore[misc]


def smooth(x: np.ndarray[Any, Any], n: int) -> np.ndarray[Any, Any]:
    """Centred moving average over n samples (edges use the shorter available window)."""
    k = np.ones(n) / n
    num = np.convolve(x, k, mode="same")
    den = np.convolve(np.ones_like(x), k, mode="same")
    return num / den  # type: ignore[no-any-return]


def deriv(x: np.ndarray[Any, Any], h: int) -> np.ndarray[Any, Any]:
    """Central difference over ±h samples."""
    out = np.zeros_like(x)
    out[h:-h] = (x[2 * h:] - x[:-2 * h]) / (2 * h * DT)
    return out


def reversals(omega: np.ndarray[Any, Any]) -> int:
    sign, count = 0, 0
    for w in omega:
        if abs(w) > REVERSAL_DEADBAND:
            s = 1 if w > 0 else -1
            if sign and s != sign:
                count += 1
            sign = s
    return count


def trapezoid_time(dist: float, vmax: float, amax: float) -> float:
    if dist <= 0:
        return 0.0
    if dist >= vmax * vmax / amax:
        return dist / vmax + vmax / amax
    return 2.0 * math.sqrt(dist / amax)


def make_pid(which: str, monitor: bool = False) -> VelocityPidCore:
    """No e-stop in the lockstep loop; a safety monitor's limit required only with `monitor`
    (nav_eval --monitor feeds it)."""
    if which == "thesis":
        return VelocityPidCore(require_estop=False)
    pcfg = msgspec.structs.replace(PidConfig(), require_safety_limit=monitor, require_estop=False)
    return make_core(pcfg)


def truth_peaks(v: np.ndarray[Any, Any], w: np.ndarray[Any, Any]) -> tuple[float, float, float]:
    """|a|, |jerk|, |ω̇| peaks of the chair's true velocities (exact, one sample a tick)."""
    acc = np.diff(v) / DT
    jerk = np.diff(smooth(acc, round(0.05 / DT))) / DT
    wdot = np.diff(w) / DT
    return (float(np.max(np.abs(acc))), float(np.max(np.abs(jerk))),
            float(np.max(np.abs(wdot))))


def scurve_time(dist: float, vmax: float, amax: float, jmax: float) -> float:
    """Rest-to-rest time over `dist` with |v| ≤ vmax, |a| ≤ amax, |jerk| ≤ jmax (S-curve)."""
    if dist <= 0:
        return 0.0

    def t_acc(vp: float) -> float:  # time from rest to vp (and back): jerk-limited ramp
        return vp / amax + amax / jmax if vp >= amax * amax / jmax else 2.0 * math.sqrt(vp / jmax)

    if vmax * t_acc(vmax) <= dist:
        return 2.0 * t_acc(vmax) + (dist - vmax * t_acc(vmax)) / vmax
    lo, hi = 0.0, vmax
    for _ in range(60):  # the distance vp·t_acc(vp) grows with vp: bisection
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if mid * t_acc(mid) < dist else (lo, mid)
    return 2.0 * t_acc(lo)


def turn_drive_turn_time(start: tuple[float, float, float], goal: tuple[float, float, float],
                         cfg: ControlConfig) -> float:
    """A reference for a chair that cannot move sideways: turn in place to face the goal,
    drive straight, turn to the goal yaw (each a rest-to-rest S-curve at the comfort limits).
    Not a strict bound (blending turns into the drive can be faster), but the trapezoid bound
    ignores that a goal beside the chair needs turning at all."""
    def turn(a: float) -> float:
        return scurve_time(abs(wrap(a)), cfg.omega_max_radps, cfg.omega_acc_max_radps2,
                           cfg.omega_jerk_max_radps3)

    (sx, sy, syaw), (gx, gy, gyaw) = start, goal
    d = math.hypot(gx - sx, gy - sy)
    if d < 0.05:
        return turn(gyaw - syaw)
    heading = math.atan2(gy - sy, gx - sx)
    return turn(heading - syaw) + scurve_time(d, cfg.vmax_mps, cfg.a_max_mps2,
                                              cfg.jerk_max_mps3) + turn(gyaw - heading)


class Planning:
    """The control node's planning thread in lockstep: a plan asked for at `t` takes effect
    `delay_s` later (at once when 0), the core driving the previous plan meanwhile; one
    request at a time, as the node's. `plan` computes one (nav_eval times it)."""

    def __init__(self, core: ControlCore, delay_s: float,
                 plan: Callable[[PlanRequest], PlanResult] = compute) -> None:
        self.core, self.delay_s, self.plan = core, delay_s, plan
        core.inline_planning = False
        self._pending: tuple[PlanResult, float] | None = None  # a plan, when it takes effect

    def tick(self, t: float) -> None:
        core, pending = self.core, self._pending
        if pending is not None and t >= pending[1] - 1e-9:
            core.on_plan(pending[0], t)
            self._pending = pending = None
        req = None if pending is not None else core.plan_request(t)
        if req is None:
            return
        res = self.plan(req)
        if self.delay_s > 0.0:
            self._pending = (res, t + self.delay_s)
        else:
            core.on_plan(res, t)


def run_case(start: tuple[float, float, float], goal: tuple[float, float, float],
             cfg: ControlConfig, pid_kind: str = "tuned", odom_age_ticks: int = 0,
             cmd_delay_ticks: int = 0, plan_delay_s: float = 0.0) -> dict[str, Any]:
    """One goal in lockstep. `odom_age_ticks` / `cmd_delay_ticks` (drive ticks, default 0:
    none): the delays of the control's path through the processes, which lockstep lacks. The
    control reads ODOM_SLOW (every second sample) on its own free-running 50 Hz timer, so it
    acts on odometry 0–20 ms old; the PID takes its command up at its next odometry sample,
    0–10 ms later (measured through the processes: 10 or 20 ms in all, by the timer's
    phase; the PID's volts reach the chair on the next tick, as here)."""
    rig = Rig(make_pid(pid_kind), start=start)
    seen: deque[tuple[float, OdomState]] = deque()  # odometry on its way to the control
    sent: deque[Any] = deque()  # the control's commands on their way to the PID
    model = rig.chair
    core = ControlCore(cfg)
    # (at 0 the core plans inside step(), as it did before plans could be delayed)
    planning = Planning(core, plan_delay_s) if plan_delay_s > 0.0 else None
    ctrl_every = max(1, round(1.0 / (cfg.rate_hz * DT)))
    rows: list[tuple[float, ...]] = []
    cmds: list[tuple[float, float]] = []
    t_arrive: float | None = None
    k = 0
    while True:
        t = k * DT
        st = rig.sense()
        seen.append((t, st))
        if len(seen) > odom_age_ticks or k == 0:  # (at first the chair stands where placed)
            ts, so = seen.popleft() if len(seen) > odom_age_ticks else seen[0]
            core.on_odom(OdomSample(so.x, so.y, so.yaw, so.v, so.omega, ts))
        if k == 0:
            reply = core.set_goal(GoalRequest(waypoints=[Pose2D(*goal)]), t)
            assert reply.ok, reply.error
        out = None
        if k % ctrl_every == 0:
            if planning is not None:
                planning.tick(t)
            if cmd_delay_ticks:  # (as the node hears it from the PID: PidStatus.command_age_s)
                core.on_command_age(cmd_delay_ticks * DT)
            out = core.step(t)
        if out is not None:  # the plan (what is sent leads it past the PID's prefilter)
            cmds.append((core.limiter.v.value, core.limiter.w.value))
        sent.append(out)
        rig.act(t, st.v, st.omega, sent.popleft() if len(sent) > cmd_delay_ticks else None)
        rows.append((t, st.x, st.y, st.yaw, st.v, st.omega, st.distance,
                     model.x, model.y, model.yaw, model.v, model.omega))
        if t_arrive is None and not getattr(core, "active", core.state == "active"):
            t_arrive = t
        if (t_arrive is not None and t - t_arrive >= SETTLE_S) or t >= TIMEOUT_S:
            break
        k += 1
    a = np.array(rows)
    n = round(0.1 / DT)
    h = round(0.05 / DT)
    v, w = smooth(a[:, 4], n), smooth(a[:, 5], n)
    acc = deriv(v, h)
    jerk = deriv(smooth(acc, n), h)
    wdot = deriv(w, h)
    dist = a[:, 6]
    i_arr = len(a) - 1 if t_arrive is None else round(t_arrive / DT)
    final = dist >= dist[i_arr] - FINAL_APPROACH_M
    gx, gy, gyaw = goal
    sx, sy, syaw = start
    d_straight = math.hypot(gx - sx, gy - sy)
    bound = max(trapezoid_time(d_straight, cfg.vmax_mps, cfg.a_max_mps2),
                trapezoid_time(abs(wrap(gyaw - syaw)), cfg.omega_max_radps,
                               cfg.omega_acc_max_radps2))
    ta, tj, tw = truth_peaks(a[:, 10], a[:, 11])
    jbound = max(scurve_time(d_straight, cfg.vmax_mps, cfg.a_max_mps2, cfg.jerk_max_mps3),
                 scurve_time(abs(wrap(gyaw - syaw)), cfg.omega_max_radps,
                             cfg.omega_acc_max_radps2, cfg.omega_jerk_max_radps3))
    ref = cached(start, goal, Limits.of(cfg))
    cmd = np.array(cmds)
    cmd_a = np.diff(cmd[:, 0]) * cfg.rate_hz
    cmd_wd = np.diff(cmd[:, 1]) * cfg.rate_hz
    end = a[-1]
    return {
        "state": core.state,
        "reason": core.reason,
        "arrived": core.state == ARRIVED,
        "time_s": round(t_arrive if t_arrive is not None else TIMEOUT_S, 3),
        "trapezoid_bound_s": round(bound, 3),
        "time_ratio": round((t_arrive or TIMEOUT_S) / bound, 2) if bound > 0 else None,
        "jerk_bound_s": round(jbound, 3),
        "time_ratio_jerk": round((t_arrive or TIMEOUT_S) / jbound, 2) if jbound > 0 else None,
        "tdt_ref_s": round(turn_drive_turn_time(start, goal, cfg), 3),
        "time_ratio_tdt": round((t_arrive or TIMEOUT_S) / turn_drive_turn_time(start, goal, cfg),
                                2),
        # the least time any controller could take (bench/min_time.py: unicycle, comfort
        # limits, forward only), and this run's time over it
        "min_time_s": round(ref.time_s, 3),
        "min_time_ok": ref.ok,
        "time_ratio_min": round((t_arrive or TIMEOUT_S) / ref.time_s, 2),
        "pos_error_m": round(math.hypot(gx - end[1], gy - end[2]), 4),
        "yaw_error_deg": round(math.degrees(abs(wrap(gyaw - end[3]))), 2),
        "true_pos_error_m": round(math.hypot(gx - end[7], gy - end[8]), 4),
        "true_yaw_error_deg": round(math.degrees(abs(wrap(gyaw - end[9]))), 2),
        "path_m": round(float(dist[i_arr] - dist[0]), 3),
        "peak_a_mps2": round(float(np.max(np.abs(acc))), 3),
        "peak_jerk_mps3": round(float(np.max(np.abs(jerk))), 3),
        "peak_omega_radps": round(float(np.max(np.abs(w))), 3),
        "peak_omega_dot_radps2": round(float(np.max(np.abs(wdot))), 3),
        "truth_peak_a_mps2": round(ta, 3),
        "truth_peak_jerk_mps3": round(tj, 3),
        "truth_peak_omega_dot_radps2": round(tw, 3),
        "cmd_peak_a_mps2": round(float(np.max(np.abs(cmd_a))), 3),
        "cmd_peak_jerk_mps3": round(float(np.max(np.abs(np.diff(cmd_a)) * cfg.rate_hz)), 3),
        "cmd_peak_omega_dot_radps2": round(float(np.max(np.abs(cmd_wd))), 3),
        "final_reversals": reversals(w[final]),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="first 6 cases only")
    ap.add_argument("--no-save", action="store_true", help="do not write the results file")
    ap.add_argument("--pid", choices=("tuned", "thesis"), default="tuned",
                    help="velocity PID: [pid] as configured (default) or the thesis's ZN")
    ap.add_argument("--odom-age-ticks", type=int, default=0, metavar="N",
                    help="the control acts on odometry N drive ticks old (processes: 0–2)")
    ap.add_argument("--cmd-delay-ticks", type=int, default=0, metavar="N",
                    help="the PID takes the control's command up N drive ticks late (0–1)")
    ap.add_argument("--plan-delay-s", type=float, default=0.0, metavar="D",
                    help="each MPEPC plan takes effect D s after it was asked for, as on the "
                         "node's planning thread (default 0: at once)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="override a [control] setting")
    args = ap.parse_args(argv)
    from autochair.runtime.config import load_section

    cfg = load_section(ControlConfig, "control", None, args.set)
    cases = suite()[:6] if args.quick else suite()
    results = []
    t0 = time.perf_counter()
    for name, start, goal in cases:
        r = run_case(start, goal, cfg, args.pid, args.odom_age_ticks, args.cmd_delay_ticks,
                     args.plan_delay_s)
        r.update(name=name, start=start, goal=goal)
        results.append(r)
        print(f"{name:32s} {r['state']:8s} t={r['time_s']:6.2f}s x{r['time_ratio']:<5} "
              f"xj{r['time_ratio_jerk']:<5} xtdt{r['time_ratio_tdt']:<5} "
              f"xmin{r['time_ratio_min']:<5} "
              f"err={r['pos_error_m'] * 100:4.1f}cm/{r['yaw_error_deg']:4.1f}° "
              f"a={r['peak_a_mps2']:.2f} j={r['peak_jerk_mps3']:.2f} "
              f"ω={r['peak_omega_radps']:.2f} ω̇={r['peak_omega_dot_radps2']:.2f} "
              f"rev={r['final_reversals']} truth a={r['truth_peak_a_mps2']:.2f} "
              f"j={r['truth_peak_jerk_mps3']:.2f} ω̇={r['truth_peak_omega_dot_radps2']:.2f}")
    wall = time.perf_counter() - t0
    sim_s = sum(r["time_s"] + SETTLE_S for r in results)
    summary = {
        "cases": len(results),
        "arrived": sum(r["arrived"] for r in results),
        "within_tolerance_at_rest": sum(r["pos_error_m"] <= 0.05 and r["yaw_error_deg"] <= 3.0
                                        for r in results),
        "max_peak_a_mps2": max(r["peak_a_mps2"] for r in results),
        "max_peak_jerk_mps3": max(r["peak_jerk_mps3"] for r in results),
        "max_peak_omega_radps": max(r["peak_omega_radps"] for r in results),
        "max_peak_omega_dot_radps2": max(r["peak_omega_dot_radps2"] for r in results),
        "max_truth_a_mps2": max(r["truth_peak_a_mps2"] for r in results),
        "max_truth_jerk_mps3": max(r["truth_peak_jerk_mps3"] for r in results),
        "max_truth_omega_dot_radps2": max(r["truth_peak_omega_dot_radps2"] for r in results),
        "max_time_ratio": max(r["time_ratio"] for r in results),
        "max_cmd_a_mps2": max(r["cmd_peak_a_mps2"] for r in results),
        "max_cmd_jerk_mps3": max(r["cmd_peak_jerk_mps3"] for r in results),
        "max_cmd_omega_dot_radps2": max(r["cmd_peak_omega_dot_radps2"] for r in results),
        "max_final_reversals": max(r["final_reversals"] for r in results),
        "median_time_ratio": statistics.median(r["time_ratio"] for r in results),
        "median_time_ratio_jerk": statistics.median(r["time_ratio_jerk"] for r in results),
        "max_time_ratio_jerk": max(r["time_ratio_jerk"] for r in results),
        "median_time_ratio_tdt": statistics.median(r["time_ratio_tdt"] for r in results),
        "max_time_ratio_tdt": max(r["time_ratio_tdt"] for r in results),
        "median_time_ratio_min": statistics.median(r["time_ratio_min"] for r in results),
        "max_time_ratio_min": max(r["time_ratio_min"] for r in results),
        "min_time_all_ok": all(r["min_time_ok"] for r in results),
        "max_pos_error_m": max(r["pos_error_m"] for r in results),
        "max_yaw_error_deg": max(r["yaw_error_deg"] for r in results),
        "sim_time_s": round(sim_s, 1),
        "wall_time_s": round(wall, 1),
        "speedup_vs_real_time": round(sim_s / wall, 1),
    }
    print(json.dumps(summary, indent=1))
    if args.no_save:
        return 0
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps({"pid": args.pid, "odom_age_ticks": args.odom_age_ticks,
                                   "cmd_delay_ticks": args.cmd_delay_ticks,
                                   "plan_delay_s": args.plan_delay_s,
                                   "config": {f: getattr(cfg, f) for f in cfg.__struct_fields__},
                                   "summary": summary, "runs": results}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
