"""Session 25: what the safety monitor bounds at office A's door (the live failure poses), at rest and
moving with small steering corrections. Run: PYTHONPATH=services:schemas python THIS."""
import math, numpy as np
from autochair.runtime.config import ChairGeometry
from autochair.safety.core import SafetyCore, SafetyParams, Scan
from autochair.safety.node import SafetyConfig
from autochair.sim.lidar.scanner import UrgParams, ray_scan
from autochair.sim.world import DEFAULT_WORLD, load_world
w = load_world(DEFAULT_WORLD); c = ChairGeometry(); cfg = SafetyConfig()
core = SafetyCore(SafetyParams.of(cfg, c.front_m, c.rear_m, c.half_width_m, c.laser_mount))
u = UrgParams(); inc = 2*math.pi/u.ares
for pose in [(4.465, 0.385, math.radians(86.2)), (4.5, 0.385, math.radians(90)), (4.331, 0.498, math.radians(78.9)), (4.5, 0.0, math.radians(90))]:
    raw = ray_scan(w, u, pose, c.laser_mount, 0.0, np.random.default_rng(0))
    r = np.where((raw < u.dmin_mm) | (raw > u.dmax_mm), np.nan, raw*1e-3)
    scan = Scan(r, (u.amin-u.afrt)*inc, inc, u.dmin_mm*1e-3, u.dmax_mm*1e-3)
    lim = core.assess(scan, 0.0, 0.0)
    print([round(x,3) for x in pose], "v_fwd", round(lim.v_fwd,3), "omega", round(lim.omega,3), lim.reason)
print("moving")
pose = (4.465, 0.385, math.radians(86.2))
raw = ray_scan(w, u, pose, c.laser_mount, 0.0, np.random.default_rng(0))
r = np.where((raw < u.dmin_mm) | (raw > u.dmax_mm), np.nan, raw*1e-3)
scan = Scan(r, (u.amin-u.afrt)*inc, inc, u.dmin_mm*1e-3, u.dmax_mm*1e-3)
for v, om in [(0.1, 0.0), (0.1, 0.05), (0.1, -0.05), (0.1, 0.1), (0.1, -0.1), (0.2, 0.1), (0.2, -0.1), (0.3, 0.3), (0.3, -0.3)]:
    lim = core.assess(scan, v, om)
    print(v, om, "kappa", round(om/v,2), "v_fwd", round(lim.v_fwd, 3), lim.reason)
