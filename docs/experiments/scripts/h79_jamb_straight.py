"""H79: how often the monitor's core reads a point inside the padded sweep (free fwd 0) and
judges an imminent collision while the chair drives straight through the 0.9 m door at
0.45 m/s, by its offset from the door's centre line (simulated laser noise, many draws)."""
import math, sys, numpy as np
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
v = 0.45
xs = np.arange(2.6, 4.6, 0.045)  # the axle from 1.4 m before the wall to 0.6 m past it (front 0.95)
for off in (0.0, 0.01, 0.02, 0.03, 0.04):
    imm = zero = n = 0
    for rep in range(int(sys.argv[1]) if len(sys.argv) > 1 else 5):
        for x in xs:
            pose = (float(x), 1.0 + off, 0.0)
            raw = ray_scan(world.at(0.0), urg, pose, ch.laser_mount, 0.01, rng, (v, 0.0))
            r = np.where((raw < urg.dmin_mm) | (raw > urg.dmax_mm), np.nan, raw * 1e-3)
            P = scan_points(r, (urg.amin - urg.afrt) * inc, inc, urg.dmin_mm * 1e-3, urg.dmax_mm * 1e-3, ch.laser_mount)
            L = sc.limit(P, v, 0.0)
            n += 1; imm += L.imminent; zero += L.free_fwd_m == 0.0
    print(f"offset {off*100:.0f} cm: scans {n}, free fwd 0: {zero} ({100*zero/n:.2f} %), imminent: {imm} ({100*imm/n:.2f} %)", flush=True)
