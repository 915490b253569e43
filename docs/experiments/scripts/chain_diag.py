"""Issue 14, session 11: run one bench.nav_eval case in lockstep and log every control tick
(truth pose and velocities, odometry, the core's predicted pose, the command sent, the
predictor chain's own output, state flags, truth clearance) and every plan cycle, to an .npz
for chain_fit.py / plan_log.py. `PID_<field>=value` in the environment overrides a PidConfig
field (e.g. PID_planned_slew_per_s=20); trailing KEY=VALUE override [control].

    PYTHONPATH=. .venv/bin/python docs/experiments/scripts/chain_diag.py "room B corner" 7 out.npz
"""
import math
import sys

import numpy as np

from bench import nav_eval as ne
from autochair.control.core import ControlConfig, ControlCore, OdomSample
from autochair.nav import planner
from autochair.nav.field import Footprint
from autochair.nav.mpepc import MpepcParams
from autochair.runtime.config import ChairGeometry, load_section
from autochair.tune.lockstep import DT, Rig
from autochair_msgs import GoalRequest, Pose2D

name, seed, out_path = sys.argv[1], int(sys.argv[2]), sys.argv[3]
case = [c for c in ne.CASES if name in c[0]][0]
cfg = load_section(ControlConfig, "control", None, sys.argv[4:])
ch = ChairGeometry()
fp = Footprint(ch.front_m, ch.rear_m, ch.half_width_m)
world, fld = ne.build(case[1], fp)
planner._planners.clear()
planner._lattices.clear()
params = MpepcParams(seed=seed)
start, goal = case[2], case[3]
import os, msgspec
from autochair.pid.core import PidConfig, make_core
extra = {k[4:]: float(v) for k, v in os.environ.items() if k.startswith("PID_")}
pcfg = msgspec.structs.replace(PidConfig(), require_safety_limit=False, require_estop=False, **extra)
rig = Rig(make_core(pcfg), start=start)
model = rig.chair
core = ControlCore(cfg, footprint=fp)
core.inline_planning = False
core.on_field(fld)
outline = fp.outline(0.02)
ctrl_every = max(1, round(1.0 / (cfg.rate_hz * DT)))
rows = []
plans = []
k = 0
t_end = None
while True:
    t = k * DT
    st = rig.sense()
    core.on_odom(OdomSample(st.x, st.y, st.yaw, st.v, st.omega, t))
    if k == 0:
        assert core.set_goal(GoalRequest(waypoints=[Pose2D(*goal)]), t).ok
    out = None
    if k % ctrl_every == 0:
        core.people = ne.people_at(world, t)
        req = core.plan_request(t)
        if req is not None:
            res = ne.compute(req, params)
            core.on_plan(res, t)
            p = res.plan
            plans.append(dict(t=t, pose=req.pose, v=req.v,
                              path=None if p is None else np.asarray(p.path),
                              straight=None if p is None else p.straight_m,
                              z=None if p is None else tuple(p.z),
                              blk=res.blocked_by, err=res.error))
        try:
            pred = core._predicted(core.odom, t)
        except TypeError:
            pred = core._predicted(core.odom)
        out = core.step(t)
        flags = (core.state == "driving") * 1 + core.final * 2 + core.aligning * 4 \
            + core.straight * 8 + (core._move is not None) * 16 \
            + (core.plan is not None and core.plan.straight_m > 0) * 32
        cv, cw = core._chain
        rows.append((t, model.x, model.y, model.yaw, model.v, model.omega,
                     st.x, st.y, st.yaw, pred.x, pred.y, pred.yaw,
                     out[0] if out else 0.0, out[1] if out else 0.0, cv.x2, cw.x2, flags,
                     ne.truth_clearance(world, fp, outline, model.x, model.y, model.yaw, t)))
    rig.act(t, st.v, st.omega, out)
    if t_end is None and not core.active:
        t_end = t
    at_rest = abs(model.v) < 0.01 and abs(model.omega) < 0.01
    if (t_end is not None and t - t_end >= ne.SETTLE_S and at_rest) or t >= ne.TIMEOUT_S:
        break
    k += 1
print(name, core.state, core.reason)
np.savez(out_path, rows=np.array(rows), plans=np.array(plans, dtype=object))
