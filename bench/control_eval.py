"""Control-law evaluation: a fixed suite of start/goal pairs driven in the simulator, in process
and in lockstep (deterministic, faster than real time).

Loop at the encoder rate (200 Hz): ChairModel (sim/model.py) → encoder counts → OdometryCore →
ControlCore (stepped at its own configured rate, 50 Hz, like the node) → VelocityPidCore →
joystick volts → ChairModel. Comfort is measured from the odometry, not from the commands:
v and ω are smoothed with a centred moving average (0.1 s), then a, jerk and ω̇ are central
differences over ±0.05 s (odometry velocities are quantised: 1 count ≈ 31 µm, so raw 5 ms
differences would report noise, not motion). The commanded (limiter) peaks are reported too.

    .venv/bin/python -m bench.control_eval [--quick]
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np

from autochair.control.core import ARRIVED, ControlConfig, ControlCore, OdomSample
from autochair.geometry import wrap_angle as wrap
from autochair.odometry.core import OdometryCore
from autochair.pid.core import Command, VelocityPidCore
from autochair.sim.chair.model import ChairModel
from autochair_msgs import GoalRequest, Pose2D

DT = 0.005  # encoder rate
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


def run_case(start: tuple[float, float, float], goal: tuple[float, float, float],
             cfg: ControlConfig) -> dict[str, Any]:
    model = ChairModel()
    model.x, model.y, model.yaw = start
    odom = OdometryCore()
    odom.reset(*start)
    pid = VelocityPidCore(require_estop=False)  # no e-stop service in the lockstep loop
    core = ControlCore(cfg)
    ctrl_every = max(1, round(1.0 / (cfg.rate_hz * DT)))
    volts = (2.5, 2.5)
    rows: list[tuple[float, ...]] = []
    cmds: list[tuple[float, float]] = []
    t_arrive: float | None = None
    k = 0
    while True:
        t = k * DT
        model.step(volts[0], volts[1], DT)
        st = odom.update(model.left_counts, model.right_counts, round(model.t * 1e6))
        core.on_odom(OdomSample(st.x, st.y, st.yaw, st.v, st.omega, t))
        if k == 0:
            reply = core.set_goal(GoalRequest(waypoints=[Pose2D(*goal)]), t)
            assert reply.ok, reply.error
        if k % ctrl_every == 0:
            out = core.step(t)
            if out is not None:
                now_ns = round(t * 1e9)
                pid.set_desired(Command(out[0], out[1], "autonomy", now_ns, 1), t, now_ns)
                cmds.append(out)
        p = pid.update(st.v, st.omega, DT, t, round(t * 1e9))
        volts = (p.longitudinal_v, p.angular_v)
        rows.append((t, st.x, st.y, st.yaw, st.v, st.omega, st.distance,
                     model.x, model.y, model.yaw))
        if t_arrive is None and core.state != "active":
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
        "pos_error_m": round(math.hypot(gx - end[1], gy - end[2]), 4),
        "yaw_error_deg": round(math.degrees(abs(wrap(gyaw - end[3]))), 2),
        "true_pos_error_m": round(math.hypot(gx - end[7], gy - end[8]), 4),
        "true_yaw_error_deg": round(math.degrees(abs(wrap(gyaw - end[9]))), 2),
        "path_m": round(float(dist[i_arr] - dist[0]), 3),
        "peak_a_mps2": round(float(np.max(np.abs(acc))), 3),
        "peak_jerk_mps3": round(float(np.max(np.abs(jerk))), 3),
        "peak_omega_radps": round(float(np.max(np.abs(w))), 3),
        "peak_omega_dot_radps2": round(float(np.max(np.abs(wdot))), 3),
        "cmd_peak_a_mps2": round(float(np.max(np.abs(cmd_a))), 3),
        "cmd_peak_jerk_mps3": round(float(np.max(np.abs(np.diff(cmd_a)) * cfg.rate_hz)), 3),
        "cmd_peak_omega_dot_radps2": round(float(np.max(np.abs(cmd_wd))), 3),
        "final_reversals": reversals(w[final]),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="first 6 cases only")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="override a [control] setting")
    args = ap.parse_args(argv)
    from autochair.runtime.config import load_section

    cfg = load_section(ControlConfig, "control", None, args.set)
    cases = suite()[:6] if args.quick else suite()
    results = []
    t0 = time.perf_counter()
    for name, start, goal in cases:
        r = run_case(start, goal, cfg)
        r.update(name=name, start=start, goal=goal)
        results.append(r)
        print(f"{name:32s} {r['state']:8s} t={r['time_s']:6.2f}s x{r['time_ratio']:<5} "
              f"err={r['pos_error_m'] * 100:4.1f}cm/{r['yaw_error_deg']:4.1f}° "
              f"a={r['peak_a_mps2']:.2f} j={r['peak_jerk_mps3']:.2f} "
              f"ω={r['peak_omega_radps']:.2f} ω̇={r['peak_omega_dot_radps2']:.2f} "
              f"rev={r['final_reversals']}")
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
        "max_cmd_a_mps2": max(r["cmd_peak_a_mps2"] for r in results),
        "max_cmd_jerk_mps3": max(r["cmd_peak_jerk_mps3"] for r in results),
        "max_cmd_omega_dot_radps2": max(r["cmd_peak_omega_dot_radps2"] for r in results),
        "max_final_reversals": max(r["final_reversals"] for r in results),
        "median_time_ratio": statistics.median(r["time_ratio"] for r in results),
        "max_pos_error_m": max(r["pos_error_m"] for r in results),
        "max_yaw_error_deg": max(r["yaw_error_deg"] for r in results),
        "sim_time_s": round(sim_s, 1),
        "wall_time_s": round(wall, 1),
        "speedup_vs_real_time": round(sim_s / wall, 1),
    }
    print(json.dumps(summary, indent=1))
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps({"config": {f: getattr(cfg, f) for f in cfg.__struct_fields__},
                                   "summary": summary, "runs": results}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
