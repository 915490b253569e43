"""H79: the monitor's core on noisy scans with the chair 1.9 cm off the door's centre line, its front
near the jamb's end, by heading: free fwd 0 and imminent per 40 draws (run from the repo root
with PYTHONPATH=services:schemas:.)."""
import math, numpy as np
from autochair.runtime.config import ChairGeometry
from autochair.safety.core import SafetyCore, SafetyParams, scan_points
from autochair.safety.node import SafetyConfig
from autochair.sim.lidar.scanner import UrgParams, ray_scan
from autochair.sim.world import load_world
from pathlib import Path
ch = ChairGeometry()
sc = SafetyCore(SafetyParams.of(SafetyConfig(), ch.front_m, ch.rear_m, ch.half_width_m, ch.laser_mount))
urg = UrgParams(); inc = 2*math.pi/urg.ares
world = load_world(Path("services/autochair/sim/worlds/doorway.world"))
rng = np.random.default_rng(1)
for yawd in (0.0, 0.6, 1.0, 2.0):
  for x in (2.95, 3.0, 3.024, 3.05, 3.1):
    z = imm = 0; reasons=set()
    for rep in range(40):
        raw = ray_scan(world.at(0.0), urg, (x, 1.019, math.radians(yawd)), ch.laser_mount, 0.01, rng, (0.448, 0.0))
        r = np.where((raw < urg.dmin_mm) | (raw > urg.dmax_mm), np.nan, raw * 1e-3)
        P = scan_points(r, (urg.amin - urg.afrt) * inc, inc, urg.dmin_mm * 1e-3, urg.dmax_mm * 1e-3, ch.laser_mount)
        L = sc.limit(P, 0.448, 0.0)
        z += L.free_fwd_m == 0.0; imm += L.imminent; reasons.add(L.reason[:40])
    print(yawd, x, "zero", z, "imminent", imm, sorted(reasons)[:3])
