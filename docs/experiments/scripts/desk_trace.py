"""Trace office B desk with the monitor: per plan cycle near the goal."""
import math, sys
import numpy as np
from bench import nav_eval as ne
from bench.safety_rig import SafetyRig
from autochair.nav import planner
from autochair.nav.mpepc import MpepcParams
from autochair.control.core import ControlConfig
from autochair.runtime.config import ChairGeometry, load_section
from autochair.nav.field import Footprint

name = sys.argv[1]; seed = int(sys.argv[2]) if len(sys.argv) > 2 else 7
mon = (sys.argv[3] != "0") if len(sys.argv) > 3 else True
case = [c for c in ne.CASES if name in c[0]][0]
cfg = load_section(ControlConfig, "control", None, [])
ch = ChairGeometry(); fp = Footprint(ch.front_m, ch.rear_m, ch.half_width_m)
world, fld = ne.build(case[1], fp)
orig = planner.compute
T = [0.0]
def compute(req, params=None):
    res = orig(req, params)
    p = res.plan
    gx, gy, gyaw = req.goal
    d = math.hypot(gx - req.pose[0], gy - req.pose[1])
    if d < 1.5 and p is not None:
        print(f"t={T[0]:.2f} PLAN pose=({req.pose[0]:.3f},{req.pose[1]:.3f},{math.degrees(req.pose[2]):.0f}) v={req.v:.2f} w={req.omega:.2f} d={d:.3f} "
              f"z=({p.z[0]:.2f},{math.degrees(p.z[1]):.0f},{math.degrees(p.z[2]):.0f},{p.z[3]:.2f}) "
              f"tgt=({p.target[0]:.2f},{p.target[1]:.2f},{math.degrees(p.target[2]):.0f}) goal={p.is_goal} ft={p.final_turn} st={p.straight_m:.2f} "
              f"cost={p.cost:.2f} prog={p.progress_m:.2f} clr={p.min_clearance_m:.3f} "
              f"gclr={p.goal_clearance_m:.3f} wh={p.goal_withheld} omax={req.law.omega_max_radps:.2f} blk={res.blocked_by[:50]}", flush=True)
    elif p is None:
        print(f"t={T[0]:.2f} NOPLAN {res.error}")
    return res
ne.compute = compute
last = [None]
def on_tick(t, core, chair):
    T[0] = t
    if int(round(t * 100)) % 10: return
    gx, gy = case[3][0], case[3][1]
    d = math.hypot(gx - chair.x, gy - chair.y)
    if d > 1.5: return
    ob = core._omega_bounds[-1][1] if core._omega_bounds else float('nan')
    s = (core.state, core.final, core.straight, core.aligning, core._move is not None)
    print(f"t={t:.2f} tick ({chair.x:.3f},{chair.y:.3f},{math.degrees(chair.yaw):.1f}) v={chair.v:.2f} w={chair.omega:.2f} "
          f"d={d:.3f} st={s} wb={ob:.2f} fz={core._fwd_zero} cap={core._fwd_cap():.2f} lb={core._last_blocked[0][:40]} reason={core.reason[:40]}")
planner._planners.clear(); planner._lattices.clear()
r = ne.run_case(world, fld, case[2], case[3], cfg, fp, MpepcParams(seed=seed), monitor=SafetyRig() if mon else None, on_tick=on_tick)
print(r["state"], r["reason"], r["true_pos_error_m"], r["true_yaw_error_deg"], r["min_clearance_m"], r["time_s"])
