"""Issue 14 residual: the velocity PID's stop, replayed open loop on the chair model.

1. record: the lockstep 'ahead 6 m' (bench.control_eval.run_case), the control's command per
   drive tick (None between its 50 Hz ticks).
2. replay: the same command stream into VelocityPidCore + ChairModel + OdometryCore, with
   perturbations of the PID's schedule, its measurement or the chain (a)-(d); the control is
   open loop here, so any shift of the rest position is the PID's and the chain's own.
"""
from __future__ import annotations

import json
import math
import sys
from collections import deque
from pathlib import Path

from autochair.control.core import ControlConfig
from autochair.odometry.core import OdometryCore
from autochair.pid.core import Command
from autochair.sim.chair.model import ChairModel, effort
from autochair.tune import lockstep
from bench import control_eval as ce

DT = lockstep.DT
REC = Path("/tmp/dscratch/stream6.json")


def record() -> list:
    cmds: list = []
    orig = lockstep.Rig.act

    def act(self, t, v, w, desired=None):
        cmds.append(None if desired is None else list(desired))
        return orig(self, t, v, w, desired)

    lockstep.Rig.act = act
    r = ce.run_case((0, 0, 0), (6, 0, 0), ControlConfig())
    lockstep.Rig.act = orig
    REC.write_text(json.dumps(cmds))
    print("recorded", r["state"], r["pos_error_m"], len(cmds))
    return cmds


def replay(cmds, *, stalls=(), merged=False, odom_age=0, chain_delay=0, wrong_dt=None,
           gateway_stale_s=0.1, extra_s=3.0, after_zero=None):
    """stalls: (tick, n): the PID sees no sample for n ticks from tick on, then the backlog
    (burst: n samples of 10 ms in a row; merged: one sample of n·10 ms, the frames between
    lost). The chair holds the last volts meanwhile, neutral once the gateway's command is
    gateway_stale_s old. odom_age: the PID's measurement is this many samples old.
    chain_delay: the PID's volts reach the chair this many ticks later. wrong_dt: (tick, dt):
    that one update is passed dt instead of 10 ms."""
    chair, odom = ChairModel(), OdometryCore()
    core = ce.make_pid("tuned")
    stall_at = dict(stalls)
    volts = (2.5, 2.5)
    sent_t = 0.0  # when the gateway last got a command
    to_chair: deque = deque()
    meas: deque = deque()
    pending: list = []  # samples the stalled PID has not seen: (t, v, w, dt)
    stall_until = -1
    prev_t_pid = None
    rows = []
    zeroed = False
    n = len(cmds) + round(extra_s / DT)
    for k in range(n):
        t = k * DT
        # the gateway: the newest volts, neutral once stale
        gv = volts if t - sent_t <= gateway_stale_s + 1e-9 else (2.5, 2.5)
        to_chair.append(gv)
        cv = to_chair.popleft() if len(to_chair) > chain_delay else (2.5, 2.5)
        chair.step(*cv, DT)
        st = odom.update(chair.left_counts, chair.right_counts, round(chair.t * 1e6))
        meas.append((st.v, st.omega))
        mv, mw = meas.popleft() if len(meas) > odom_age else meas[0]
        c = cmds[k] if k < len(cmds) else None
        ns = round(t * 1e9)
        if c is not None and c[0] == 0.0 and k > 300:
            zeroed = True
        if c is not None:  # (the Zenoh thread takes commands even while the loop stalls)
            core.set_desired(Command(c[0], c[1], "autonomy", ns + 1, 1), t, ns)
        if k in stall_at:
            stall_until = k + stall_at[k]
        pending.append((t, mv, mw, DT))
        if k < stall_until:
            out = None
        else:
            if merged and len(pending) > 1:
                pending = [(t, mv, mw, DT * len(pending))]
            for (ts, v, w, dt) in pending:
                if wrong_dt is not None and k == wrong_dt[0]:
                    dt = wrong_dt[1]
                out = core.update(v, w, dt, t, ns)
            pending = []
            lv = out.longitudinal_v
            if after_zero is not None and zeroed:
                lv = 2.5 + 1.5 * after_zero(out.v_effort, v)
            volts, sent_t = (lv, out.angular_v), t
        rows.append((t, core._desired[0] if core.obeying else 0.0, mv, chair.v, chair.x,
                     None if out is None else out.v_effort, core.v_pid.integral,
                     None if out is None else out.feedforward[0], effort(cv[0]),
                     core._ff[0]._m2))
    return rows


def summary(rows, base_x=None, label=""):
    i0 = next(i for i, r in enumerate(rows) if r[1] > 0.3)
    iz = next(i for i in range(i0, len(rows)) if rows[i][1] == 0.0)
    t, d, mv, v, x, u, integ, ff, uc, mref = rows[iz]
    after = [r for r in rows[iz:iz + 100] if r[5] is not None]
    # forward drive after the stop: effort beyond the chair's dead band while it still moves
    fwd = max((r[8] for r in rows[iz:] if r[3] > 0.02), default=0.0)
    acc = [(rows[i + 1][3] - rows[i][3]) / DT for i in range(iz - 100, len(rows) - 1)]
    rest = rows[-1][4]
    vs = [r[3] for r in rows]
    import numpy as np
    a = np.diff(vs) / DT
    j = np.diff(np.convolve(a, np.ones(5) / 5, mode="same")) / DT
    label += f" [model ref {mref:.3f}, a {a[iz-100:].min():+.2f}, |j| {np.abs(j[iz-100:-5]).max():.2f}]" 
    shift = "" if base_x is None else f" shift {100 * (rest - base_x):+5.1f} cm"
    print(f"{label:34s} desired 0 at t={t:.2f}: meas {mv:.3f} true {v:.3f} effort "
          f"{u if u is not None else float('nan'):+.3f} I {integ:+.4f}; next 1 s effort "
          f"[{min(r[5] for r in after):+.3f}, {max(r[5] for r in after):+.3f}], at the chair "
          f"max {fwd:+.3f}; min a {min(acc):+.2f}; rest {rest:.4f}{shift}")
    return rest


if __name__ == "__main__":
    cmds = record() if not REC.exists() or "rec" in sys.argv else json.loads(REC.read_text())
