"""One goal from a parked chair, traced tick by tick through the velocity PID, on the process
stack and in lockstep: what the PID was asked (desired, the plan's accel/jerk), what it sent
(feed-forward, effort, volts) and what the simulated chair did (its truth).

    .venv/bin/python docs/experiments/scripts/pid_trace.py stack OUT.pkl ["ahead 1 m"]
    .venv/bin/python docs/experiments/scripts/pid_trace.py lockstep OUT.pkl ["ahead 1 m"]
    .venv/bin/python docs/experiments/scripts/pid_trace.py compare STACK.pkl LOCK.pkl [N]
    .venv/bin/python docs/experiments/scripts/pid_trace.py timed OUT.pkl "ahead 1 m" PHASE JITTER \
        [SEED [snap]]

(PYTHONPATH=. from the repository root; needs PidStatus's feed-forward, 48eb3b1. With the
planned-stream patch applied the commands' plan (accel, jerk) is traced too; without, None.)
`timed`: lockstep with the control on its own clock
as through the processes (see `timed` below): the model that reproduced the overrun.

Each trace is a list of PID updates from the first active one: the sim tick whose counts the
update acted on, desired v, the command's plan (v, accel, jerk) in force, feed-forward,
effort, volts; and the true chair (x, v) per sim tick.
"""
from __future__ import annotations

import math
import pickle
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

DT = 0.01


def plan(c: Any, field: str) -> float | None:
    """The v axis of a command's plan (the planned-stream patch), None without one."""
    x = getattr(c, field, None) if c is not None else None
    return None if x is None else float(x[0])


def suite_goal(name: str) -> tuple[float, float, float]:
    from bench.control_eval import suite
    return {n: g for n, st, g in suite()}[name]


def stack(out: str, name: str) -> None:
    from bench.control_stack import STACK, drive_case

    from autochair.launcher import Launcher, free_port
    from autochair.processes import PROCESSES, local_values
    from autochair.runtime.client import open_client, subscribe
    from autochair_msgs import keys

    logs: dict[str, list[Any]] = {k: [] for k in ("truth", "joy", "status", "cmd", "odom")}
    lock = threading.Lock()

    def rec(k: str) -> Any:
        def cb(m: Any) -> None:
            with lock:
                logs[k].append((time.time_ns(), m))
        return cb

    hub = f"tcp/127.0.0.1:{free_port()}"
    with tempfile.TemporaryDirectory() as tmp:
        launcher = Launcher([p for p in PROCESSES if p.name in STACK],
                            local_values(Path(tmp), hub), Path(tmp))
        launcher.start(ready_timeout_s=40)
        s = open_client(hub)
        try:
            truth: list[Any] = []

            def on_truth(m: Any) -> None:
                with lock:
                    truth.append(m)
                    logs["truth"].append((time.time_ns(), m))
            subscribe(s, keys.SIM_TRUTH, on_truth)
            for k, key in (("joy", keys.JOYSTICK), ("status", keys.PID_STATUS),
                           ("cmd", keys.CMD_VEL), ("odom", keys.ODOM)):
                subscribe(s, key, rec(k))
            while not truth:
                time.sleep(0.05)
            time.sleep(1.5)  # the simulated MCU ignores commands for its first second
            r = drive_case(s, truth, lock, suite_goal(name))
            print(name, r, flush=True)
        finally:
            s.close()
            launcher.stop()
    tr = [m for _, m in logs["truth"]]
    x0 = tr[0]
    status = {m.stamp_ns: m for _, m in logs["status"]}
    cmds = [m for _, m in logs["cmd"]]
    rows = []
    for _, j in logs["joy"]:
        st = status.get(j.stamp_ns)
        if st is None or not j.enable:
            continue
        # the command in force: the latest one with this desired v sent before the update
        c = next((c for c in reversed(cmds) if c.stamp_ns <= j.stamp_ns
                  and c.v_mps == st.v_desired_mps), None)
        rows.append({"tick": j.source_seq + 1, "wall_ns": j.stamp_ns,
                     "desired": st.v_desired_mps, "meas": st.v_measured_mps,
                     "ff": st.v_feedforward, "effort": st.v_effort, "volts": j.longitudinal_v,
                     "cmd_ns": c.stamp_ns if c else None,
                     "acc": plan(c, "accel"), "jerk": plan(c, "jerk")})
    chair = {round(m.sim_time_s / DT): (m.x_m - x0.x_m, m.v_mps, m.longitudinal_v) for m in tr}
    cmd_rows = [(c.stamp_ns, c.v_mps, getattr(c, "accel", None), getattr(c, "jerk", None))
                for c in cmds]
    odom = [(t, m.source_seq, m.v_mps, m.sample_dt_s) for t, m in logs["odom"]]
    Path(out).write_bytes(pickle.dumps({"pid": rows, "chair": chair, "cmds": cmd_rows,
                                        "odom": odom}))


def lockstep(out: str, name: str, odom_age: int = 0, cmd_delay: int = 0) -> None:
    from collections import deque

    from bench.control_eval import make_pid

    from autochair.control.core import ControlConfig, ControlCore, OdomSample
    from autochair.runtime.config import load_section
    from autochair.tune.lockstep import Rig
    from autochair_msgs import GoalRequest, Pose2D

    cfg = load_section(ControlConfig, "control", None, [])
    goal = suite_goal(name)
    rig = Rig(make_pid("tuned"), start=(0.0, 0.0, 0.0))
    core = ControlCore(cfg)
    every = max(1, round(1.0 / (cfg.rate_hz * DT)))
    rows, chair, cmd_rows = [], {}, []
    seen: deque[Any] = deque()
    sent: deque[Any] = deque()
    in_force = None
    for k in range(round(8.0 / DT)):
        t = k * DT
        st = rig.sense()
        chair[k + 1] = (rig.chair.x, rig.chair.v, rig.volts[0])  # truth after tick k+1
        seen.append((t, st))
        if len(seen) > odom_age or k == 0:
            ts, so = seen.popleft() if len(seen) > odom_age else seen[0]
            core.on_odom(OdomSample(so.x, so.y, so.yaw, so.v, so.omega, ts))
        if k == 0:
            assert core.set_goal(GoalRequest(waypoints=[Pose2D(*goal)]), t).ok
        c = core.step(t) if k % every == 0 else None
        if c is not None:
            cmd_rows.append((round(t * 1e9), c[0], getattr(c, "accel", None),
                             getattr(c, "jerk", None)))
        sent.append(c)
        d = sent.popleft() if len(sent) > cmd_delay else None
        if d is not None:
            in_force = d
        o = rig.act(t, st.v, st.omega, d)
        if o.active:
            rows.append({"tick": k + 1, "wall_ns": round(t * 1e9), "desired": o.desired[0],
                         "meas": st.v, "ff": o.feedforward[0], "effort": o.v_effort,
                         "volts": o.longitudinal_v, "cmd_ns": None,
                         "acc": plan(in_force, "accel"), "jerk": plan(in_force, "jerk")})
        if not core.active and k > 10 and abs(rig.chair.v) < 1e-4:
            break
    print(name, core.state, core.reason, "final x", round(rig.chair.x, 4))
    Path(out).write_bytes(pickle.dumps({"pid": rows, "chair": chair, "cmds": cmd_rows}))


def timed(out: str, name: str, phase: float = 0.0, jitter: float = 0.0, seed: int = 1,
          slow_every: int = 2, snap: bool = False) -> float:
    """Lockstep, but the control on its own clock as through the processes: its ticks at
    n·20 ms + `phase` + uniform ±`jitter` (s) with `now` = that time, each seeing the newest
    odometry published by then (every `slow_every`-th sample: ODOM_SLOW), its command taken
    up by the PID at the next drive tick. `snap`: the control steps on its schedule's time
    (n·20 ms + phase) while still running (and being taken up) at the jittered one. Returns
    the chair's final x."""
    import random

    from bench.control_eval import make_pid

    from autochair.control.core import ControlConfig, ControlCore, OdomSample
    from autochair.runtime.config import load_section
    from autochair.tune.lockstep import Rig
    from autochair_msgs import GoalRequest, Pose2D

    rnd = random.Random(seed)
    cfg = load_section(ControlConfig, "control", None, [])
    goal = suite_goal(name)
    rig = Rig(make_pid("tuned"), start=(0.0, 0.0, 0.0))
    core = ControlCore(cfg)
    rows, chair, cmd_rows = [], {}, []
    newest = None  # the newest odometry the control can have
    n, t_next = 0, phase
    pending = None
    started = False
    for k in range(round(10.0 / DT)):
        t = k * DT
        # control ticks that fall before this drive tick's PID update
        while t_next <= t:
            if newest is None:
                break
            core.on_odom(newest)
            if not started:
                assert core.set_goal(GoalRequest(waypoints=[Pose2D(*goal)]), t_next).ok
                started = True
            c = core.step(n * 0.02 + phase if snap else t_next)
            if c is not None:
                pending = c
                cmd_rows.append((round(t_next * 1e9), c[0], getattr(c, "accel", None),
                                 getattr(c, "jerk", None)))
            n += 1
            t_next = n * 0.02 + phase + rnd.uniform(-jitter, jitter)
        st = rig.sense()
        chair[k + 1] = (rig.chair.x, rig.chair.v, rig.volts[0])
        if k % slow_every == 0:
            newest = OdomSample(st.x, st.y, st.yaw, st.v, st.omega, t + 1e-4)
        o = rig.act(t, st.v, st.omega, pending)
        if o.active:
            rows.append({"tick": k + 1, "wall_ns": round(t * 1e9), "desired": o.desired[0],
                         "meas": st.v, "ff": o.feedforward[0], "effort": o.v_effort,
                         "volts": o.longitudinal_v, "cmd_ns": None,
                         "acc": None, "jerk": None})
        pending = None
        if started and not core.active and k > 10 and abs(rig.chair.v) < 1e-4:
            break
    print(name, f"phase {phase} jitter {jitter} seed {seed} snap {snap}:", core.state, core.reason,
          "final x", round(rig.chair.x, 4), "asked", round(sum(r["desired"] for r in rows) * DT, 4))
    Path(out).write_bytes(pickle.dumps({"pid": rows, "chair": chair, "cmds": cmd_rows}))
    return rig.chair.x


def compare(a_path: str, b_path: str, n: int = 60) -> None:
    a, b = pickle.loads(Path(a_path).read_bytes()), pickle.loads(Path(b_path).read_bytes())
    ra, rb = a["pid"], b["pid"]
    ka, kb = ra[0]["tick"], rb[0]["tick"]
    print(f"first active update: stack tick {ka}, lockstep tick {kb}; aligned there")
    print(" i | stack: des     acc    jerk   ff     eff   V     x_chair v_chair | lock: des"
          "     acc    jerk   ff     eff   V     x_chair v_chair")
    for i in range(min(n, len(ra), len(rb))):
        p, q = ra[i], rb[i]
        ca = a["chair"].get(p["tick"] + 1, (math.nan,) * 3)
        cb = b["chair"].get(q["tick"] + 1, (math.nan,) * 3)

        def f(r: dict[str, Any], c: tuple[float, ...]) -> str:
            acc = r["acc"] if r["acc"] is not None else math.nan
            jerk = r["jerk"] if r["jerk"] is not None else math.nan
            return (f"{r['desired']:6.4f} {acc:6.3f} {jerk:6.2f} {r['ff']:6.4f} "
                    f"{r['effort']:6.4f} {r['volts']:5.3f} {c[0]:7.4f} {c[1]:6.4f}")
        print(f"{i:3d}| dt{p['tick'] - ra[i - 1]['tick'] if i else 0} {f(p, ca)} | {f(q, cb)}")
    for name, d in (("stack", a), ("lock", b)):
        xs = [c[0] for c in d["chair"].values()]
        print(name, "final x", round(xs[-1], 4), "max x", round(max(xs), 4))


if __name__ == "__main__":
    mode = sys.argv[1]
    if mode == "stack":
        stack(sys.argv[2], sys.argv[3] if len(sys.argv) > 3 else "ahead 1 m")
    elif mode == "lockstep":
        lockstep(sys.argv[2], sys.argv[3] if len(sys.argv) > 3 else "ahead 1 m")
    elif mode == "timed":
        timed(sys.argv[2], sys.argv[3], float(sys.argv[4]), float(sys.argv[5]),
              int(sys.argv[6]) if len(sys.argv) > 6 else 1,
              snap=len(sys.argv) > 7 and sys.argv[7] == "snap")
    else:
        compare(sys.argv[2], sys.argv[3], int(sys.argv[4]) if len(sys.argv) > 4 else 60)
