"""Issue 12, session 17 (helper E): per plan cycle of one bench.nav_eval case in lockstep, between
T0 and T1: the request's pose, v, ω; the chosen z (r, θ°, δ°, vmax), its target, progress, cost
against the stop's, least clearance, the core's state and blocked reason; and over all
candidates evaluated: how many, hits, committed-stop hits, on the lattice, the best progress of
those not a hit. -v: the eight cheapest candidates too.

    PYTHONPATH=services:schemas:. .venv/bin/python docs/experiments/scripts/door_trace.py \
        "facing down" 4 4.0 6.1 [-v] [KEY=VALUE ...]
"""
import math
import sys

import numpy as np
from bench import nav_eval as ne
from bench.control_eval import make_pid

from autochair.control.core import ControlConfig, ControlCore, OdomSample
from autochair.nav import mpepc as M
from autochair.nav import planner
from autochair.nav.field import Footprint
from autochair.nav.mpepc import MpepcParams
from autochair.runtime.config import ChairGeometry, load_section
from autochair.tune.lockstep import DT, Rig
from autochair_msgs import GoalRequest, Pose2D

name, seed, t0, t1 = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
evals: list[dict] = []
orig_ev, orig_plan = M.Mpepc.evaluate, M.Mpepc.plan
VERB = "-v" in sys.argv


def evaluate(self, pose, v0, w0, z, *a, **k):
    c, info = orig_ev(self, pose, v0, w0, z, *a, **k)
    evals.append({"z": np.array(z).copy(), "cost": c.copy(), "hit": info["hit"].copy(),
                  "stop": info["stop_hit"].copy(), "prog": info["phi0"] - info["phi_end"],
                  "lat": info["in_lattice"].copy(), "clr": info["clearance"].copy()})
    return c, info


M.Mpepc.evaluate = evaluate
case = next(c for c in ne.CASES if name in c[0])
cfg = load_section(ControlConfig, "control", None, [a for a in sys.argv[5:] if "=" in a])
ch = ChairGeometry()
fp = Footprint(ch.front_m, ch.rear_m, ch.half_width_m)
world, fld = ne.build(case[1], fp)
planner._planners.clear()
planner._lattices.clear()
params = MpepcParams(seed=seed)
rig = Rig(make_pid("tuned"), start=case[2])
core = ControlCore(cfg, footprint=fp)
core.inline_planning = False
core.on_field(fld)
k, t_end = 0, None
while True:
    t = k * DT
    st = rig.sense()
    core.on_odom(OdomSample(st.x, st.y, st.yaw, st.v, st.omega, t))
    if k == 0:
        core.set_goal(GoalRequest(waypoints=[Pose2D(*case[3])]), t)
    out = None
    if k % 2 == 0:
        core.people = ne.people_at(world, t)
        req = core.plan_request(t)
        if req is not None:
            evals.clear()
            res = planner.compute(req, params)
            core.on_plan(res, t)
            if t0 <= t <= t1 and res.plan is not None:
                p = res.plan
                allc = {key: np.concatenate([e[key] for e in evals]) for key in evals[0]} \
                    if evals else None
                x, y, yaw = req.pose
                s = (f"{t:5.2f} pose ({x:.3f},{y:.3f},{math.degrees(yaw):6.1f}) v {req.v:.3f} "
                     f"w {req.omega:+.3f} | z ({p.z[0]:.2f},{math.degrees(p.z[1]):.0f},"
                     f"{math.degrees(p.z[2]):.0f},{p.z[3]:.2f}) tgt ({p.target[0]:.2f},"
                     f"{p.target[1]:.2f},{math.degrees(p.target[2]):.0f}) prog {p.progress_m:.3f}"
                     f" cost {p.cost:.3f} stop {p.stop_cost:.3f} clr {p.min_clearance_m:.3f}"
                     f" goal {p.is_goal} str {p.straight_m:.2f} ft {p.final_turn}"
                     f" | {core.state} {res.blocked_by[:30]}")
                if allc is not None:
                    ok = allc["hit"] < 0.5
                    s += (f" | n {len(ok)} hit {int((~ok).sum())} stophit "
                          f"{int((allc['stop'] > 0.5).sum())} lat {int(allc['lat'].sum())}"
                          f" bestprog(ok) {allc['prog'][ok].max() if ok.any() else math.nan:.3f}")
                print(s)
                if VERB and allc is not None:
                    order = np.argsort(allc["cost"])[:8]
                    for i in order:
                        zz = allc["z"][i]
                        print(f"      z ({zz[0]:.2f},{math.degrees(zz[1]):.0f},"
                              f"{math.degrees(zz[2]):.0f},{zz[3]:.2f}) c {allc['cost'][i]:.3f}"
                              f" prog {allc['prog'][i]:.3f} hit {allc['hit'][i]:.0f} stop "
                              f"{allc['stop'][i]:.0f} clr {allc['clr'][i]:.3f}")
        out = core.step(t)
    rig.act(t, st.v, st.omega, out)
    if t_end is None and not core.active:
        t_end = t
    if (t_end is not None and t - t_end >= 0.5) or t > 90:
        break
    k += 1
print(f"{case[0]} seed {seed}: {core.state} {core.reason}")
