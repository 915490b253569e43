"""Diagnose one nav_eval case: per plan cycle, what the planner chooses."""
import math, sys
import numpy as np
from bench import nav_eval as ne
from autochair.nav import planner
from autochair.nav.mpepc import MpepcParams
from autochair.control.core import ControlConfig
from autochair.runtime.config import ChairGeometry, load_section
from autochair.nav.field import Footprint

name = sys.argv[1]; seed = int(sys.argv[2]) if len(sys.argv) > 2 else 7
case = [c for c in ne.CASES if name in c[0]][0]
cfg = load_section(ControlConfig, "control", None, [])
ch = ChairGeometry(); fp = Footprint(ch.front_m, ch.rear_m, ch.half_width_m)
world, fld = ne.build(case[1], fp)
orig = planner.compute
log = []
def compute(req, params=None):
    res = orig(req, params)
    p = res.plan
    hf = planner._lattices.get((id(req.field), req.goal), (None, None))[1]
    lc = None
    if hf is not None:
        c, ok = hf.at(np.array(req.pose[0]), np.array(req.pose[1]), np.array(req.pose[2]))
        lc = (round(float(c), 2), bool(ok))
    gx, gy, gyaw = req.goal
    d = math.hypot(gx - req.pose[0], gy - req.pose[1])
    if d < 2.0:
        print(f"pose=({req.pose[0]:.2f},{req.pose[1]:.2f},{math.degrees(req.pose[2]):.0f}) v={req.v:.2f} d={d:.2f} "
              f"z=({p.z[0]:.2f},{math.degrees(p.z[1]):.0f},{math.degrees(p.z[2]):.0f},{p.z[3]:.2f}) "
              f"tgt=({p.target[0]:.2f},{p.target[1]:.2f},{math.degrees(p.target[2]):.0f}) goal={p.is_goal} "
              f"cost={p.cost:.2f} stop={p.stop_cost:.2f} prog={p.progress_m:.2f} clr={p.min_clearance_m:.3f} "
              f"gclr={p.goal_clearance_m:.3f} lat={lc} blk={res.blocked_by[:40]}", flush=True)
    return res
ne.compute = compute
planner._planners.clear(); planner._lattices.clear()
r = ne.run_case(world, fld, case[2], case[3], cfg, fp, MpepcParams(seed=seed))
print(r["state"], r["reason"], r["true_pos_error_m"], r["true_yaw_error_deg"], r["min_clearance_m"])
