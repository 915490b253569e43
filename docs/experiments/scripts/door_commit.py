"""Issue 12, session 17: what committed the chair to a door frame under MPEPC's 5 cm. Runs one
bench.nav_eval case in lockstep and prints, for each plan cycle between T0 and T1: the chosen
plan's committed-stop clearance (Mpepc.stop_clearance) against `need`, how many candidates kept
it and the best; and how far the core's chain predictor, fed the commands the core really sent
next, put the body from the simulator's truth 0.2-1.0 s on (yaw, and the most any footprint
corner is off).

    PYTHONPATH=services:schemas:. .venv/bin/python docs/experiments/scripts/door_commit.py \
        "into room B facing down" 7 7.0 8.6 [KEY=VALUE ...]
"""
import copy
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
chosen: list[tuple] = []
orig_ev, orig_sc, orig_plan = M.Mpepc.evaluate, M.Mpepc.stop_clearance, M.Mpepc.plan


def evaluate(self, pose, v0, w0, z, *a, **k):
    evals.append({"z": np.array(z).copy()})
    return orig_ev(self, pose, v0, w0, z, *a, **k)


def stop_clearance(self, pose, v0, w0, sweep, need, *a, **k):
    res = orig_sc(self, pose, v0, w0, sweep, need, *a, **k)
    evals[-1].update(res=res.copy(), need=need)
    return res


def plan(self, pose, *a, **k):
    evals.clear()
    p = orig_plan(self, pose, *a, **k)
    res = np.concatenate([e["res"] for e in evals if "res" in e])
    mine = math.nan
    for e in evals:
        if "res" in e:
            rows = np.nonzero(np.all(np.abs(e["z"] - np.array(p.z)[None]) < 1e-12, 1))[0]
            if rows.size:
                mine = float(e["res"][rows[0]])
    need = next(e["need"] for e in evals if "need" in e)
    chosen.append((need, mine, int((res >= need).sum()), len(res), float(res.max())))
    return p


M.Mpepc.evaluate, M.Mpepc.stop_clearance, M.Mpepc.plan = evaluate, stop_clearance, plan

case = next(c for c in ne.CASES if name in c[0])
cfg = load_section(ControlConfig, "control", None, sys.argv[5:])
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
truth, steps, k, t_end = [], [], 0, None
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
            core.on_plan(planner.compute(req, params), t)
        snap = (copy.deepcopy(core._chain[0]), copy.deepcopy(core._chain[1]),
                core._now_pose(core.odom, t))
        out = core.step(t)
        steps.append((k, snap, out or (0.0, 0.0), req is not None))
    rig.act(t, st.v, st.omega, out)
    c = rig.chair
    truth.append((c.x, c.y, c.yaw))
    if t_end is None and not core.active:
        t_end = t
    if (t_end is not None and t - t_end >= 1.5) or t > 90:
        break
    k += 1
print(f"{case[0]} seed {seed}: {core.state}")
corners = np.array([[fp.front_m, fp.half_width_m], [fp.front_m, -fp.half_width_m],
                    [-fp.rear_m, fp.half_width_m], [-fp.rear_m, -fp.half_width_m]])


def place(p):
    c, s = math.cos(p[2]), math.sin(p[2])
    return np.stack([p[0] + c * corners[:, 0] - s * corners[:, 1],
                     p[1] + s * corners[:, 0] + c * corners[:, 1]], 1)


i_plan = 0
for i, (k, (cv, cw, pose), _, planned) in enumerate(steps):
    if not planned:
        continue
    need, mine, n_ok, n, best = chosen[i_plan]
    i_plan += 1
    t = k * DT
    if not t0 <= t <= t1:
        continue
    cv, cw = copy.deepcopy(cv), copy.deepcopy(cw)
    for j in range(i, min(len(steps), i + 60)):  # the commands really sent next
        cv.pipe.append((0.02, steps[j][2][0]))
        cw.pipe.append((0.02, steps[j][2][1]))
    x, y, yaw = pose
    # (the odometry stamped t read the chair one tick on: the tick's sense stepped it first)
    tr = truth[k]
    row = [f"+0.0 s {math.degrees(tr[2] - yaw):+.2f}°"]
    for j, (v, w) in enumerate(zip(cv.future(0.02, 50), cw.future(0.02, 50), strict=True)):
        x += v * math.cos(yaw + 0.01 * w) * 0.02
        y += v * math.sin(yaw + 0.01 * w) * 0.02
        yaw += w * 0.02
        if (j + 1) % 10 == 0:
            tr = truth[min(len(truth) - 1, k + 2 * (j + 1))]
            off = float(np.max(np.hypot(*(place(tr) - place((x, y, yaw))).T)))
            row.append(f"+{(j + 1) * 0.02:.1f} s {math.degrees(tr[2] - yaw):+.2f}° "
                       f"{off * 100:.1f} cm")
    print(f"plan {t:.2f}: chosen stop {mine:.4f} (need {need:.3f}); {n_ok}/{n} keep it, best "
          f"{best:.4f} | chain vs truth: " + ", ".join(row))
