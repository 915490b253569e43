import math, dataclasses
import bench.nav_eval as ne
from bench.safety_rig import SafetyRig
from autochair.control.core import ControlConfig
from autochair.runtime.config import load_section, ChairGeometry
cfg = load_section(ControlConfig, "control", None, [])
ch = ChairGeometry(); fp = ne.Footprint(ch.front_m, ch.rear_m, ch.half_width_m)
name = "person: stepping out of a side room"
c = [c for c in ne.CASES if c[0] == name][0]
world, fld = ne.build(c[1], fp)
world = dataclasses.replace(world, phase_s=ne.STEPPING_OUT[name])
def tick(t, core, chair):
    if abs(t * 5 - round(t * 5)) < 1e-6:
        st = world.people_state(t)[0]
        p = core.plan
        print(f"t={t:4.1f} chair=({chair.x:.2f},{chair.y:.2f},{math.degrees(chair.yaw):+.0f}) v={chair.v:.2f} truth=({st[0]:.2f},{st[1]:.2f},vy {st[3]:+.1f}) known={[(round(q.x_m,2), round(q.y_m,2), round(q.vy_mps,1)) for q in core.people]} st={core.state} plan_v={None if p is None else round(p.vmax_mps,2)}", flush=True)
ne.planner._planners.clear(); ne.planner._lattices.clear()
r = ne.run_case(world, fld, c[2], c[3], cfg, fp, ne.MpepcParams(seed=7), 0.0, None, None, SafetyRig(0), on_tick=tick, sight_only=True)
print(r['state'], r['reason'][:80], r['person_clearance_m'])
