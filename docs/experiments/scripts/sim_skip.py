"""(session 14, issue 14; run with PYTHONPATH=. from the repository) Lockstep: a straight 3 m goal from rest; the simulator stalls (skips ticks) on chosen wall
ticks while the control keeps wall time. mode 'skip': sim time is lost (as Node.every does);
mode 'catchup': the chair keeps moving on the held volts, the PID sees nothing meanwhile."""
import sys
import numpy as np
from autochair.control.core import ControlConfig, ControlCore, OdomSample
from autochair.tune.lockstep import DT, Rig
from autochair_msgs import GoalRequest, Pose2D
from bench.control_eval import make_pid

def peak(t, v):
    t, v = np.asarray(t), np.asarray(v)
    grid = np.arange(t[0], t[-1], 0.01)
    vs = np.convolve(np.interp(grid, t, v), np.ones(10) / 10, mode="valid")
    return float(np.abs(np.diff(vs[::5]) / 0.05).max())

def run(stalls: set[int], mode: str, T: float = 4.0):
    cfg = ControlConfig()
    rig = Rig(make_pid("tuned"), start=(0, 0, 0))
    core = ControlCore(cfg)
    every = max(1, round(1.0 / (cfg.rate_hz * DT)))
    truth_t, truth_v = [], []
    st = rig.sense(); sim_t = DT
    core.on_odom(OdomSample(st.x, st.y, st.yaw, st.v, st.omega, 0.0))
    assert core.set_goal(GoalRequest(waypoints=[Pose2D(3.0, 0, 0)]), 0.0).ok
    out = None
    backlog = []
    for k in range(int(T / DT)):
        t = k * DT
        if k % every == 0:
            o = core.step(t)
            if o is not None:
                out = o
        if k in stalls:
            if mode == "catchup":  # the frames wait in the pty; the chair holds the volts
                backlog.append(rig.sense()); sim_t += DT
                truth_t.append(sim_t); truth_v.append(rig.chair.v)
            continue
        for b in backlog:  # the host works through the burst (only the last volts count)
            rig.act(t, st.v, st.omega, out); st = b
            core.on_odom(OdomSample(st.x, st.y, st.yaw, st.v, st.omega, t))
        backlog = []
        rig.act(t, st.v, st.omega, out)
        st = rig.sense(); sim_t += DT
        truth_t.append(sim_t); truth_v.append(rig.chair.v)
        core.on_odom(OdomSample(st.x, st.y, st.yaw, st.v, st.omega, t + DT))
    return peak(truth_t, truth_v)

base = run(set(), "skip")
print(f"no stall: peak {base:.3f}")
# motion starts ~0.55 s after the goal (the control's first plan + chain)
for label, ticks in [
    ("5 single skips 0.6-1.3 s", {60, 75, 90, 105, 120}),
    ("5 single skips 0.9-1.3 s", {90, 100, 110, 120, 130}),
    ("one 50 ms stall at 1.0 s", set(range(100, 105))),
    ("one 100 ms stall at 1.0 s", set(range(100, 110))),
    ("one 30 ms stall at 1.2 s", set(range(120, 123))),
    ("10 single skips 0.6-1.5 s", set(range(60, 150, 10))),
]:
    print(f"{label:28s} skip {run(ticks, 'skip'):.3f}  catch-up {run(ticks, 'catchup'):.3f}")
