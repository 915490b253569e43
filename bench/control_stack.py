"""A subset of the control_eval suite through the real processes (router, e-stop, simulator on
its pty, gateway, odometry, velocity PID, control law; Zenoh on loopback), compared with the
same cases in lockstep.

Each case is driven from wherever the previous one left the chair: its goal is the suite's
goal relative to the suite's start, applied to the chair's pose now (only cases that start at
the origin are used). Time to goal: from the goal request to the status "arrived". Comfort
peaks from the simulator's ground truth (autochair/sim/truth, 100 Hz, on its own clock).

    .venv/bin/python -m bench control_stack [--cases 6] [--out FILE] [--logs DIR [--record]]
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from autochair.control.core import ControlConfig
from autochair.geometry import wrap_angle as wrap
from autochair.launcher import Launcher, free_port
from autochair.pid.core import NEUTRAL_V
from autochair.processes import PROCESSES, local_values
from autochair.runtime.config import load_section
from autochair.tune.lockstep import DT

from .control_eval import run_case, scurve_time, smooth, suite, trapezoid_time
from .min_time import Limits, cached

RESULTS = Path(__file__).parent / "results" / "control_stack.json"
STACK = ["router", "estop", "sim", "gateway", "odometry", "pid", "control"]


def truth_peaks(rows: list[tuple[float, float, float]]) -> tuple[float, float, float]:
    """|a|, |jerk|, |ω̇| of the true motion, resampled to 10 ms (sim clock); a and ω̇ as
    first differences, the jerk from a smoothed over 50 ms."""
    t = np.array([r[0] for r in rows])
    grid = np.arange(t[0], t[-1], 0.01)
    v = np.interp(grid, t, [r[1] for r in rows])
    w = np.interp(grid, t, [r[2] for r in rows])
    acc = np.diff(v) / 0.01
    jerk = np.diff(smooth(acc, 5)) / 0.01
    return (float(np.abs(acc).max()), float(np.abs(jerk).max()),
            float(np.abs(np.diff(w) / 0.01).max()))


def sim_rate(truth: list[tuple[float, int]]) -> float:
    """Simulated seconds per wall second over (sim_time_s, stamp_ns) truth samples. Below 1
    the simulator skipped ticks (its loop overran under load): the chair's time then runs
    slower than the control's wall clock, which no lockstep run has."""
    if len(truth) < 2:
        return math.nan
    wall = (truth[-1][1] - truth[0][1]) / 1e9
    return (truth[-1][0] - truth[0][0]) / wall if wall > 0 else math.nan


def step_on_stack(session: Any, truth: list[Any], lock: threading.Lock, axis: str,
                  size: float = 0.5, hold_s: float = 5.0) -> dict[str, Any]:
    """A `drive`-like 0.5 step from rest through the stack, on the simulator's true velocity
    and clock; then a stop and a rest."""
    import msgspec

    from autochair.tune.lockstep import metrics, summary
    from autochair_msgs import VelocityCommand, keys

    pub = session.declare_publisher(keys.CMD_VEL.key)
    enc = msgspec.msgpack.Encoder()
    start_ns = time.time_ns()
    pair = (size, 0.0) if axis == "longitudinal" else (0.0, size)
    with lock:
        sim_t0 = truth[-1].sim_time_s
    t0 = time.monotonic()
    while time.monotonic() - t0 < hold_s + 1.5:
        v, w = pair if time.monotonic() - t0 < hold_s else (0.0, 0.0)
        pub.put(enc.encode(VelocityCommand(stamp_ns=time.time_ns(), v_mps=v, omega_radps=w,
                                           source="bench", stream_start_ns=start_ns)))
        time.sleep(0.05)  # the command stream's own 20 Hz
    pub.undeclare()
    with lock:
        # The step starts when the PID first drives: the first truth sample whose joystick is
        # off neutral (published at once: only a neutral, still chair's truth is thinned to
        # 10 Hz, so the last sample before the first command could be 0.1 s early), less the
        # tick the volts took to act, as in lockstep.
        sim_t0 = next((m.sim_time_s for m in truth if m.sim_time_s > sim_t0 and
                       (m.longitudinal_v != NEUTRAL_V or m.angular_v != NEUTRAL_V)),
                      sim_t0) - DT
        rows = [(m.sim_time_s - sim_t0, m.v_mps if axis == "longitudinal" else m.omega_radps)
                for m in truth if sim_t0 < m.sim_time_s <= sim_t0 + hold_s]
    return summary(metrics([r[0] for r in rows], [r[1] for r in rows], size))


def drive_case(session: Any, truth: list[Any], lock: threading.Lock, rel: tuple[float, ...],
               timeout_s: float = 40.0) -> dict[str, Any]:
    from autochair.runtime.client import request
    from autochair_msgs import Empty, GoalReply, GoalRequest, GoalStatus, Pose2D, keys

    with lock:
        now = truth[-1]
    c, s = math.cos(now.yaw_rad), math.sin(now.yaw_rad)
    gx, gy = now.x_m + c * rel[0] - s * rel[1], now.y_m + s * rel[0] + c * rel[1]
    gyaw = wrap(now.yaw_rad + rel[2])
    sim_t0 = now.sim_time_s
    reply = request(session, keys.GOAL_SET, GoalRequest(waypoints=[Pose2D(gx, gy, gyaw)]),
                    GoalReply, timeout_s=10.0)
    if not reply.ok:
        return {"state": "rejected", "reason": reply.error}
    t0 = time.monotonic()
    st = None
    while time.monotonic() - t0 < timeout_s:
        time.sleep(0.1)  # (polling the goal's state, not a synchronisation)
        st = request(session, keys.GOAL_GET, Empty(), GoalStatus)
        if st.state in ("arrived", "aborted", "cancelled"):
            break
    with lock:
        end = truth[-1]
        rows = [(m.sim_time_s, m.v_mps, m.omega_radps) for m in truth
                if m.sim_time_s >= sim_t0]
        clock = [(m.sim_time_s, m.stamp_ns) for m in truth if m.sim_time_s >= sim_t0]
    a, j, wd = truth_peaks(rows)
    rate = sim_rate(clock)
    return {"state": st.state if st else "?", "reason": st.reason if st else "",
            "time_s": round(end.sim_time_s - sim_t0, 3),
            "pos_error_m": round(math.hypot(gx - end.x_m, gy - end.y_m), 4),
            "truth_peak_a_mps2": round(a, 3), "truth_peak_jerk_mps3": round(j, 3),
            "truth_peak_omega_dot_radps2": round(wd, 3),
            "sim_rate": round(rate, 3) if math.isfinite(rate) else None}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", type=int, default=6, help="how many origin-start cases")
    ap.add_argument("--out", type=Path, default=RESULTS, help="results file")
    ap.add_argument("--only", default="", help="only cases whose name contains this")
    ap.add_argument("--logs", type=Path, default=None, help="keep the processes' logs here")
    ap.add_argument("--record", action="store_true",
                    help="run the logger too: every key to an MCAP file beside the logs (the "
                         "commands, odometry, PID status and truth of a failed case to trace)")
    args = ap.parse_args(argv)
    if args.record and args.logs is None:
        ap.error("--record needs --logs DIR (where the recording is kept)")
    stack = [*STACK, "logger"] if args.record else STACK
    from autochair.runtime.client import open_client, subscribe
    from autochair_msgs import GroundTruth, keys

    cfg = load_section(ControlConfig, "control", None, [])
    cases = [c for c in suite() if c[1] == (0.0, 0.0, 0.0) and args.only in c[0]][:args.cases]
    hub = f"tcp/127.0.0.1:{free_port()}"
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = args.logs or Path(tmp)
        run_dir.mkdir(parents=True, exist_ok=True)
        launcher = Launcher([p for p in PROCESSES if p.name in stack],
                            local_values(run_dir, hub), run_dir)
        launcher.start(ready_timeout_s=40)
        session = open_client(hub)
        try:
            truth: list[GroundTruth] = []
            lock = threading.Lock()

            def on_truth(m: GroundTruth) -> None:
                with lock:
                    truth.append(m)

            subscribe(session, keys.SIM_TRUTH, on_truth)
            deadline = time.monotonic() + 10
            while not truth and time.monotonic() < deadline:
                time.sleep(0.05)
            time.sleep(1.5)  # the simulated MCU ignores commands for its first second
            steps = {axis: step_on_stack(session, truth, lock, axis)
                     for axis in ("longitudinal", "angular")}
            print(f"0.5 steps through the stack: {steps}", flush=True)
            for name, _, goal in cases:
                r = drive_case(session, truth, lock, goal)
                lock_r = run_case((0.0, 0.0, 0.0), goal, cfg)
                bound = max(trapezoid_time(math.hypot(goal[0], goal[1]), cfg.vmax_mps,
                                           cfg.a_max_mps2),
                            trapezoid_time(abs(goal[2]), cfg.omega_max_radps,
                                           cfg.omega_acc_max_radps2))
                jb = max(scurve_time(math.hypot(goal[0], goal[1]), cfg.vmax_mps,
                                     cfg.a_max_mps2, cfg.jerk_max_mps3),
                         scurve_time(abs(goal[2]), cfg.omega_max_radps,
                                     cfg.omega_acc_max_radps2, cfg.omega_jerk_max_radps3))
                ref = cached((0.0, 0.0, 0.0), goal, Limits.of(cfg))
                r.update(name=name, time_ratio=round(r.get("time_s", 0) / bound, 2),
                         time_ratio_jerk=round(r.get("time_s", 0) / jb, 2),
                         time_ratio_min=round(r.get("time_s", 0) / ref.time_s, 2),
                         lockstep_time_s=lock_r["time_s"],
                         lockstep_truth_peak_a_mps2=lock_r["truth_peak_a_mps2"])
                results.append(r)
                print(f"{name:32s} {r['state']:8s} t={r.get('time_s', 0):6.2f}s "
                      f"(lockstep {lock_r['time_s']:.2f}s) x{r['time_ratio']} "
                      f"xmin{r['time_ratio_min']} "
                      f"a={r.get('truth_peak_a_mps2')} j={r.get('truth_peak_jerk_mps3')} "
                      f"ω̇={r.get('truth_peak_omega_dot_radps2')} sim/wall={r.get('sim_rate')}",
                      flush=True)
        finally:
            session.close()
            launcher.stop()
    done = [r for r in results if r["state"] == "arrived"]
    summary = {
        "cases": len(results), "arrived": len(done),
        "median_time_ratio": statistics.median(r["time_ratio"] for r in done) if done else None,
        "median_time_ratio_jerk": statistics.median(r["time_ratio_jerk"] for r in done)
        if done else None,
        "median_time_ratio_min": statistics.median(r["time_ratio_min"] for r in done)
        if done else None,
        "median_stack_over_lockstep_time": statistics.median(
            r["time_s"] / r["lockstep_time_s"] for r in done) if done else None,
        "max_truth_a_mps2": max((r["truth_peak_a_mps2"] for r in done), default=None),
        "max_truth_jerk_mps3": max((r["truth_peak_jerk_mps3"] for r in done), default=None),
        "max_truth_omega_dot_radps2": max((r["truth_peak_omega_dot_radps2"] for r in done),
                                          default=None),
        "min_sim_rate": min((r["sim_rate"] for r in results if r.get("sim_rate") is not None),
                            default=None),
    }
    print(json.dumps(summary, indent=1))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"summary": summary, "steps_0.5": steps, "runs": results},
                                  indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
