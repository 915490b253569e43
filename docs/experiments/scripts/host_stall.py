"""(session 14, issue 14; run with PYTHONPATH=. from the repository) Lockstep: a straight 3 m goal from rest; the host (gateway/odometry/PID) stalls while the
chair (MCU) and the control's wall clock go on: the chair holds the last volts, the samples wait
and are worked through in a burst when the host runs again."""
import math, sys
import msgspec
import numpy as np
from autochair.control.core import ControlConfig, ControlCore, OdomSample
from autochair.pid.core import PidConfig, make_core
from autochair.tune.lockstep import DT, Rig
from autochair_msgs import GoalRequest, Pose2D

def peak(t, v):
    t, v = np.asarray(t), np.asarray(v)
    grid = np.arange(t[0], t[-1], 0.01)
    vs = np.convolve(np.interp(grid, t, v), np.ones(10) / 10, mode="valid")
    return float(np.abs(np.diff(vs[::5]) / 0.05).max())

def run(stalls, speed_up, T=4.0, first_only=False):
    """stalls: {tick: n}: at that tick the host stalls n ticks; then works its backlog."""
    cfg = ControlConfig()
    pcfg = msgspec.structs.replace(PidConfig(), require_safety_limit=False, require_estop=False,
                                   speed_up_mps2=speed_up)
    rig = Rig(make_core(pcfg), start=(0, 0, 0))
    core = ControlCore(cfg)
    every = round(1.0 / (cfg.rate_hz * DT))
    tt, vv = [], []
    st = rig.sense()
    core.on_odom(OdomSample(st.x, st.y, st.yaw, st.v, st.omega, 0.0))
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(3.0, 0, 0)]), 0.0).ok
    out, backlog, stalled_until = None, [], -1
    restalled = False
    for k in range(int(T / DT)):
        t = k * DT
        if k % every == 0:
            o = core.step(t)
            out = o if o is not None else out
        if k in stalls:
            stalled_until = k + stalls[k]; restalled = False
        if k < stalled_until:  # the host sleeps; the chair goes on with the volts it has
            backlog.append(st)
            st = rig.sense()
            tt.append(rig.chair.t); vv.append(rig.chair.v)
            continue
        if first_only and len(backlog) > 1 and not restalled:  # one sample through, then the host sleeps again
            b = backlog.pop(0)
            rig.act(t, b.v, b.omega, out)
            core.on_odom(OdomSample(b.x, b.y, b.yaw, b.v, b.omega, t))
            stalled_until = k + 8; restalled = True
            backlog.append(st); st = rig.sense(); tt.append(rig.chair.t); vv.append(rig.chair.v)
            continue
        for b in backlog:  # the burst: every waiting sample through the PID, the last counts
            rig.act(t, b.v, b.omega, out)
            core.on_odom(OdomSample(b.x, b.y, b.yaw, b.v, b.omega, t))
        backlog = []
        rig.act(t, st.v, st.omega, out)
        st = rig.sense()
        tt.append(rig.chair.t); vv.append(rig.chair.v)
        core.on_odom(OdomSample(st.x, st.y, st.yaw, st.v, st.omega, t + DT))
    return peak(tt, vv)

if __name__ == "__main__":
    for label, stalls in [("none", {}), ("80 ms at 1.0 s", {100: 8}),
                          ("80 ms at 1.0 s, 80 ms again after one sample", {100: 8, 109: 8}),
                          ("40 ms x3 from 0.9 s", {90: 4, 100: 4, 110: 4}),
                          ("80 ms at 1.2 s, again", {120: 8, 129: 8}),
                          ("150 ms at 1.0 s", {100: 15})]:
        print(f"{label:45s} unbounded {run(stalls, math.inf):.3f}  speed_up 1.0 {run(stalls, 1.0):.3f}"
              f"   | first sample of the burst, then 80 ms stall: unbounded {run(stalls, math.inf, first_only=True):.3f}  speed_up 1.0 {run(stalls, 1.0, first_only=True):.3f}")
