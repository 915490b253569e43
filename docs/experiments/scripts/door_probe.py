"""Issue 12, session 17 (helper E): run one bench.nav_eval case in lockstep to its plan cycle at
T and evaluate there, as MPEPC would, the straight on along ψ (in-place candidates) for a fan of
ψ and vmax, and the law target main chose at seed 4: cost, progress, survival, clearance, hit.

    PYTHONPATH=services:schemas:. .venv/bin/python docs/experiments/scripts/door_probe.py \
        "facing down" 4 5.08
"""
import math, sys
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

name, seed, T = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
case = next(c for c in ne.CASES if name in c[0])
cfg = load_section(ControlConfig, "control", None, [])
ch = ChairGeometry()
fp = Footprint(ch.front_m, ch.rear_m, ch.half_width_m)
world, fld = ne.build(case[1], fp)
planner._planners.clear(); planner._lattices.clear()
params = MpepcParams(seed=seed)
rig = Rig(make_pid("tuned"), start=case[2])
core = ControlCore(cfg, footprint=fp)
core.inline_planning = False
core.on_field(fld)
k = 0
while True:
    t = k * DT
    st = rig.sense()
    core.on_odom(OdomSample(st.x, st.y, st.yaw, st.v, st.omega, t))
    if k == 0:
        core.set_goal(GoalRequest(waypoints=[Pose2D(*case[3])]), t)
    out = None
    if k % 2 == 0:
        req = core.plan_request(t)
        if req is not None:
            if t >= T - 1e-9:
                break
            core.on_plan(planner.compute(req, params), t)
        out = core.step(t)
    rig.act(t, st.v, st.omega, out)
    k += 1
mpc = planner.planner_for(fld, req.law, params)
print("t", t, "pose", req.pose, "v", req.v, "w", req.omega, "rates", req.rates)
zs = []
for psi in range(-12, 8, 2):
    for vm in (0.15, 0.3, 0.5, 0.8, 1.2):
        zs.append([0.0, math.radians(psi) - req.pose[2], 0.0, vm])
zs.append([0.62, math.radians(-33), math.radians(13), 0.15])
z = np.array(zs)
hf = None
c, info = mpc._costs(req.pose, req.v, req.omega, z, req.ctg, [], req.goal, req.rates, req.final, hf, req.chain)
pc_hit = info["hit"]
for i in range(len(z)):
    psi = math.degrees(req.pose[2] + z[i, 1] - z[i, 2])
    print(f"psi {psi:6.1f} vmax {z[i,3]:.2f} r {z[i,0]:.2f} cost {c[i]:.3f} prog {info['phi0'][i]-info['phi_end'][i]:.3f} surv {info['survival'][i]:.3f} clr {info['clearance'][i]:.3f} hit {info['hit'][i]:.0f} stop {info['stop_hit'][i]:.0f}")
