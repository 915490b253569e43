"""nav_eval cases with the people from the live tracker run on the rig's ray-cast scans (as the
control node: ScanPeople's tracker fed each scan's beams placed by odometry, its static map the
planner's current map: occupied or never observed), instead of the world's truth."""
import math, os, sys
import numpy as np
import bench.nav_eval as ne
import bench.safety_rig as sr
from bench.safety_rig import SafetyRig
from bench.scan_map import ScanMap
from autochair.control.core import ControlConfig, ControlCore
from autochair.nav.mpepc import Person
from autochair.people.core import PeopleTracker, StaticMap
from autochair.runtime.config import load_section, ChairGeometry

cfg = load_section(ControlConfig, "control", None, [])
ch = ChairGeometry(); fp = ne.Footprint(ch.front_m, ch.rear_m, ch.half_width_m)
seed = int(os.environ.get("SEED", "7")); ss = os.environ.get("SCANS")
st = {"rays": None, "tr": None, "core": None, "fkey": None, "people": []}
orig_rays = sr.beam_rays
def rays(*a, **k):
    out = orig_rays(*a, **k); st["rays"] = out; return out
sr.beam_rays = rays
orig_on_scan = ControlCore.on_scan
def on_scan(self, now, points):
    orig_on_scan(self, now, points)
    tr = st["tr"]
    f = self.field
    if f is not None and st["fkey"] is not f:
        gm = f.map
        static = gm.occupied | (gm.unknown if gm.unknown is not None else False)
        tr.static = StaticMap.of(static, gm.resolution_m, gm.origin_x_m, gm.origin_y_m)
        st["fkey"] = f
    bx, by, ba = st["rays"]
    mid = len(bx) // 2
    found = tr.update(points, (float(bx[mid]), float(by[mid])), now, (bx, by, ba))
    st["people"] = [Person(q.x_m, q.y_m, q.vx_mps, q.vy_mps, q.radius_m) for q in found]
ControlCore.on_scan = on_scan
ne.people_at = lambda *a, **k: list(st["people"])
from autochair.sim.world import World
PHASE = float(os.environ.get("PHASE", "0"))
_ps = World.people_state
World.people_state = lambda self, t: _ps(self, t + PHASE)
for name in sys.argv[1:]:
    c = [c for c in ne.CASES if name in c[0]][0]
    world, fld = ne.build(c[1], fp)
    scans = ScanMap(ne.build(c[1], fp)[0], ne.laser_mount(), int(ss)) if ss is not None else None
    ne.planner._planners.clear(); ne.planner._lattices.clear()
    st.update(tr=PeopleTracker(), fkey=None, people=[])
    r = ne.run_case(world, fld, c[2], c[3], cfg, fp, ne.MpepcParams(seed=seed), 0.0, scans, ne.DRIVEN.get(c[0]) if scans else None, SafetyRig(int(ss or 0)), sight_only=True)
    print(f"{c[0]:34s} {r['state']:8s} {r['time_s']:6.2f}s clr {r['min_clearance_m']} person {r['person_clearance_m']} coll {r['collisions']}/{r.get('collisions_moving')} estops {r['monitor']['estops']} {r['reason'][:80]}", flush=True)
