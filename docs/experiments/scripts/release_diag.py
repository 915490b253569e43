# Sessions 14-15 (issue 14): see docs/experiments/README.md. Copy into tests/ to run.
# Injected stalls (SIGSTOP, then SIGCONT after the time given: a diagnostic, not a sync):
#   STALL_MS: the simulator, once the ramp is under way (v > 0.15)
#   STALL_CONTROL_MS: the control, after its first moving command
#   STALL_START_MS: the control, as soon as the new goal is accepted (its first command late)
#   STALL_PROCS=gateway,odometry with STALL_PROCS_MS: those, once the ramp is under way (the
#     samples wait while the commands come on); STALL_PROCS_AGAIN_MS: 5 ms after, again
"""No unexpected start-up across processes: an e-stop under an active goal, then a release;
two command streams; the hub killed under a goal."""

from __future__ import annotations

import math
import os
import signal
import time
from collections.abc import Callable

import msgspec
import numpy as np
import pytest

from autochair.launcher import Launcher
from autochair.runtime.client import request
from autochair_msgs import (
    EStopAssert,
    EStopRelease,
    EStopReply,
    GoalReply,
    GoalRequest,
    GroundTruth,
    Pose2D,
    keys,
)
from tests.helpers import Recorder, Stream, client_session, goal_ready, pid_ready, wait_for

pytestmark = pytest.mark.slow

STACK = ["estop", "sim", "gateway", "odometry", "pid", "control"]
A_MAX = 1.0  # the comfort limit (ControlConfig.a_max_mps2)



def peak_accel(truth: list[GroundTruth]) -> float:
    """Peak |a| of the true speed, averaged over 0.1 s (as the control bench measures)."""
    t = np.array([m.sim_time_s for m in truth])
    v = np.array([m.v_mps for m in truth])
    grid = np.arange(t[0], t[-1], 0.01)
    vs = np.convolve(np.interp(grid, t, v), np.ones(10) / 10, mode="valid")
    return float(np.abs(np.diff(vs[::5]) / 0.05).max())


def test_diag_release(
        stack_factory: Callable[..., Launcher], hub: str) -> None:
    launcher = stack_factory(STACK)
    session = client_session(hub)
    try:
        truth = Recorder(session, keys.SIM_TRUTH)
        out = Recorder(session, keys.JOYSTICK_OUT)
        cmd = Recorder(session, keys.CMD_VEL)
        odom = Recorder(session, keys.ODOM)
        status = Recorder(session, keys.GOAL_STATUS)
        pidst = Recorder(session, keys.PID_STATUS)

        def pid_says(since_ns: int) -> str:  # (why a goal did not move the chair)
            g = status.latest()
            return ("; pid: " + " | ".join(sorted({m.inhibit for m in pidst.messages()
                                                   if m.stamp_ns > since_ns}))
                    + f"; goal: {g.state if g else None} {g.reason if g else ''}")

        goal_ready(session)
        goal_ns = time.time_ns()
        wait_for(truth.latest, 10, "ground truth")  # (10 Hz while the chair is parked)
        goal = GoalRequest(waypoints=[Pose2D(8.0, 0.0, 0.0)])
        assert request(session, keys.GOAL_SET, goal, GoalReply).ok
        wait_for(lambda: truth.latest().v_mps > 0.6, 20,
                 lambda: "the chair cruising to the goal" + pid_says(goal_ns))
        # A momentary press (a button): latched, nothing left to clear.
        session.put(keys.ESTOP_ASSERT.key, msgspec.msgpack.encode(EStopAssert(
            stamp_ns=time.time_ns(), source="test", reason="hazard test", active=False)))
        wait_for(lambda: (lambda s: s is not None and s.state == "aborted")(status.latest()),
                 5, "the goal aborted by the e-stop")
        assert "e-stop" in status.latest().reason
        wait_for(lambda: abs(truth.latest().v_mps) < 0.005, 10, "the chair at rest")
        released = request(session, keys.ESTOP_RELEASE, EStopRelease(by="test"), EStopReply)
        assert released.ok, released.error
        release_ns = time.time_ns()
        x0, t_rel = truth.latest().x_m, time.monotonic()
        wait_for(lambda: time.monotonic() - t_rel > 2.0, 3, "two seconds after the release")
        after = [m for m in out.messages() if m.stamp_ns > release_ns]
        assert after and not any(m.enable for m in after), "the old goal resumed"
        assert abs(truth.latest().x_m - x0) < 0.01, "the chair moved after the release"
        # A new goal (a deliberate act after the stop) starts smoothly from rest.
        start_ns = time.time_ns()
        assert request(session, keys.GOAL_SET, GoalRequest(
            waypoints=[Pose2D(x0 + 3.0, 0.0, 0.0)]), GoalReply).ok
        sst = float(os.environ.get("STALL_START_MS", "0")) / 1000
        if sst:
            cpid = launcher.pid("control")
            os.kill(cpid, signal.SIGSTOP)
            time.sleep(sst)
            os.kill(cpid, signal.SIGCONT)
        cst = float(os.environ.get("STALL_CONTROL_MS", "0")) / 1000
        if cst:
            wait_for(lambda: any(m.v_mps > 0 for m in cmd.messages() if m.stamp_ns > start_ns), 5, "first cmd")
            cpid = launcher.pid("control")
            os.kill(cpid, signal.SIGSTOP)
            time.sleep(cst)
            os.kill(cpid, signal.SIGCONT)
        stall = float(os.environ.get("STALL_MS", "0")) / 1000
        if stall:
            wait_for(lambda: truth.latest().v_mps > 0.15, 20,
                     lambda: "ramp under way" + pid_says(start_ns))
            pid = launcher.pid("sim")
            os.kill(pid, signal.SIGSTOP)
            time.sleep(stall)
            os.kill(pid, signal.SIGCONT)
        pst = float(os.environ.get("STALL_PROCS_MS", "0")) / 1000
        if pst:
            wait_for(lambda: truth.latest().v_mps > 0.15, 20,
                     lambda: "ramp under way" + pid_says(start_ns))
            pids = [launcher.pid(n) for n in os.environ["STALL_PROCS"].split(",")]
            for p in pids:
                os.kill(p, signal.SIGSTOP)
            time.sleep(pst)
            for p in pids:
                os.kill(p, signal.SIGCONT)
            again = float(os.environ.get("STALL_PROCS_AGAIN_MS", "0")) / 1000
            if again:  # a few samples through, then the host stalls again holding their volts
                time.sleep(0.005)
                for p in pids:
                    os.kill(p, signal.SIGSTOP)
                time.sleep(again)
                for p in pids:
                    os.kill(p, signal.SIGCONT)
        wait_for(lambda: truth.latest().v_mps > 0.6, 20,
                 lambda: "the chair driving the new goal" + pid_says(start_ns))
        i_06 = len(truth.messages())
        t_06 = truth.latest().sim_time_s
        wait_for(lambda: truth.latest().sim_time_s > t_06 + 0.6, 5, "the rest of the ramp")
        frames = [m for m in out.messages() if m.stamp_ns > start_ns and m.enable]
        first = frames[0]
        lunge = max(abs(first.longitudinal_v - 2.5), abs(first.angular_v - 2.5))
        run = [m for m in truth.messages() if m.stamp_ns > start_ns]
        a = peak_accel(run)
        a_test = peak_accel([m for m in truth.messages()[:i_06] if m.stamp_ns > start_ns])
        time.sleep(1.5)  # (diagnostic only: the rest of the ramp)
        dump = {"start_ns": start_ns,
                "truth": [(m.stamp_ns, m.sim_time_s, m.v_mps, m.longitudinal_v) for m in truth.messages() if m.stamp_ns > start_ns - 10**9],
                "out": [(m.stamp_ns, m.longitudinal_v, m.enable) for m in out.messages() if m.stamp_ns > start_ns - 10**9],
                "cmd": [(m.stamp_ns, m.v_mps) for m in cmd.messages() if m.stamp_ns > start_ns - 10**9],
                "odom": [(m.stamp_ns, m.v_mps, m.sample_dt_s) for m in odom.messages() if m.stamp_ns > start_ns - 10**9],
                "peak": a, "peak_test_window": a_test, "first_v": first.longitudinal_v,
                "load": os.getloadavg()[0]}
        import json
        fn = os.environ.get("DIAG_OUT", "/tmp/s14a/run.json")
        with open(fn, "w") as f:
            json.dump(dump, f)
        print(f"first joystick frame after the new goal {first.longitudinal_v:.3f} V; "
              f"peak |a| {a:.2f} m/s² (limit {A_MAX})")
        assert lunge < 0.1, f"first frame {lunge:.2f} V off neutral: a lunge"
        print(f"DIAG {fn} first {first.longitudinal_v:.3f} V peak {a:.3f} "
              f"(test's window {a_test:.3f}) load {os.getloadavg()[0]:.2f}")
        assert a <= A_MAX, f"peak |a| {a:.2f} m/s² beyond the comfort limit"
    finally:
        session.close()


