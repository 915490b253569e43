"""(sessions 14-15, issue 14; run with PYTHONPATH=. from the repository, or with PYTHONPATH at
another tree's services:schemas to measure that tree) Lockstep: a straight 3 m goal from rest
while a process on the way stalls. The chair (MCU) and the wall clock go on; the chair holds
the last volts.

- `samples` (gateway/odometry, or the PID's sample path, descheduled): the control steps on
  time and its commands reach the PID as they are sent (stamped with the control's time); the
  samples wait and are worked through in a burst with the newest command when the host runs
  again; the last output counts.
- `first` the same, but only the burst's first sample gets through before the host stalls
  again for 80 ms (holding that output), then the rest.
- `control` (the control descheduled): no command for the stall, then one step of the plan by
  the time gone (the node's due schedule).

Session 14's version fed the burst the command stamped at the burst's time; here the stamps
are the control's, as on the stack. Prints the true speed's peak |a| (0.1 s mean, differenced
over 50 ms, as the hazard test) and, for a control stall at the goal's start, the first
frame's volts (the hazard test's no-lunge check: within 0.1 V of 2.5 V).
"""
import sys

import msgspec
import numpy as np
from autochair.control.core import ControlConfig, ControlCore, OdomSample
from autochair.pid.core import Command, PidConfig, make_core
from autochair.tune.lockstep import DT, Rig
from autochair_msgs import GoalRequest, Pose2D


def peak(t, v):
    t, v = np.asarray(t), np.asarray(v)
    grid = np.arange(t[0], t[-1], 0.01)
    vs = np.convolve(np.interp(grid, t, v), np.ones(10) / 10, mode="valid")
    return float(np.abs(np.diff(vs[::5]) / 0.05).max())


def run(stalls, T=4.0, t_goal=0.5):
    """stalls: {tick: (kind, n ticks)} with kind samples | first | control."""
    cfg = ControlConfig()
    pcfg = msgspec.structs.replace(PidConfig(), require_safety_limit=False, require_estop=False)
    rig = Rig(make_core(pcfg, start_ns=1), start=(0, 0, 0))
    pid = rig.core
    core = ControlCore(cfg)
    every = round(1.0 / (cfg.rate_hz * DT))
    k_goal = round(t_goal / DT)
    start_ns = round(t_goal * 1e9)
    tt, vv, frames = [], [], []
    backlog = []  # samples waiting (tick time, state)
    samples_until = control_until = -1
    again = False  # `first`: the host stalls again after the burst's first sample
    last_step = None

    def through(t_s, st, now):
        core.on_odom(OdomSample(st.x, st.y, st.yaw, st.v, st.omega, now))
        out = pid.update(st.v, st.omega, DT, now, round(now * 1e9))
        rig.volts = (out.longitudinal_v, out.angular_v)
        if out.active:
            frames.append(out.longitudinal_v)

    for k in range(int(T / DT)):
        t = k * DT
        if k in stalls:
            kind, n = stalls[k]
            if kind == "control":
                control_until = k + n
            else:
                samples_until, again = k + n, kind == "first"
        if k == k_goal:
            assert core.set_goal(GoalRequest(waypoints=[Pose2D(3.0, 0, 0)]), t).ok
        if k % every == 0 and k >= control_until:  # (idle: None)
            o = core.step(t, None if last_step is None else t - last_step)
            last_step = t
            if o is not None:
                pid.set_desired(Command(o[0], o[1], "autonomy", round(t * 1e9), start_ns), t,
                                round(t * 1e9))
        st = rig.sense()
        tt.append(rig.chair.t)
        vv.append(rig.chair.v)
        if k < samples_until:
            backlog.append(st)
            continue
        if again and backlog:
            through(t, backlog.pop(0), t)
            samples_until, again = k + 8, False
            backlog.append(st)
            continue
        for b in backlog:
            through(t, b, t)
        backlog = []
        through(t, st, t)
    return peak(tt, vv), frames[0] if frames else float("nan")


CASES = [("none", {}),
         ("samples 80 ms at 1.0 s", {150: ("samples", 8)}),
         ("samples 40 ms x3 from 0.9 s", {140: ("samples", 4), 150: ("samples", 4),
                                          160: ("samples", 4)}),
         ("samples 40 ms every 0.1 s", {k: ("samples", 4) for k in range(60, 200, 10)}),
         ("samples 150 ms at 1.0 s", {150: ("samples", 15)}),
         ("first 80 ms at 1.0 s", {150: ("first", 8)}),
         ("first 80 ms at 1.2 s", {170: ("first", 8)}),
         ("first 40 ms x3 from 0.9 s", {140: ("first", 4), 150: ("first", 4),
                                        160: ("first", 4)}),
         ("control 80 ms at 1.0 s", {150: ("control", 8)}),
         ("control 170 ms at 1.0 s", {150: ("control", 17)}),
         ("control 170 ms at the goal's start", {50: ("control", 17)}),
         ("control 100 ms at the goal's start", {50: ("control", 10)})]

if __name__ == "__main__":
    for label, stalls in CASES:
        a, v0 = run(stalls)
        print(f"{label:38s} peak |a| {a:.3f} m/s²  first frame {v0:.3f} V", flush=True)
    sys.exit(0)
