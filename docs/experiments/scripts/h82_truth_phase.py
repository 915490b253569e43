"""nav_eval cases by name (argv) with the world's people shifted by PHASE s on their walks, on
the exact map or (SCANS=k) the laser's, with the monitor; SIGHT=crossing gives the crossing
world's people to the planner only once the laser has seen them (nav_eval's SIGHT_ONLY).
Session 34, H82. Run from the repo: PYTHONPATH=services:schemas:. python <this> "person: back"."""
import sys, os, json
import bench.nav_eval as ne
from bench.safety_rig import SafetyRig
from bench.scan_map import ScanMap
from autochair.control.core import ControlConfig
from autochair.runtime.config import load_section, ChairGeometry
cfg = load_section(ControlConfig, "control", None, [])
ch = ChairGeometry(); fp = ne.Footprint(ch.front_m, ch.rear_m, ch.half_width_m)
import bench.nav_eval as _ne; _ne.SIGHT_ONLY |= set(os.environ.get("SIGHT","").split(",")) - {""}
from autochair.sim.world import World
PHASE = float(os.environ.get("PHASE", "0"))
_ps = World.people_state
World.people_state = lambda self, t: _ps(self, t + PHASE)
seed = int(os.environ.get("SEED", "7")); ss = os.environ.get("SCANS")
for name in sys.argv[1:]:
    c = [c for c in ne.CASES if name in c[0]][0]
    world, fld = ne.build(c[1], fp)
    scans = ScanMap(ne.build(c[1], fp)[0], ne.laser_mount(), int(ss)) if ss is not None else None
    ne.planner._planners.clear(); ne.planner._lattices.clear()
    r = ne.run_case(world, fld, c[2], c[3], cfg, fp, ne.MpepcParams(seed=seed), 0.0, scans, ne.DRIVEN.get(c[0]) if scans else None, SafetyRig(int(ss or 0)), sight_only=c[1] in ne.SIGHT_ONLY)
    print(c[0], r['state'], round(r['time_s'],2), 'clr', r['min_clearance_m'], r['min_clearance_at'], 'person', r['person_clearance_m'], 'coll', r['collisions'], 'estops', r['monitor']['estops'], r['reason'][:90], flush=True)
