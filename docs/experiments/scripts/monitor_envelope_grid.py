import math, numpy as np, pickle, time
import bench.nav_eval as ne
from autochair.runtime.config import ChairGeometry
from autochair.safety.core import SafetyCore, SafetyParams, scan_points
from autochair.safety.node import SafetyConfig
from autochair.sim.lidar.scanner import UrgParams, ray_scan
ch = ChairGeometry(); fp = ne.Footprint(ch.front_m, ch.rear_m, ch.half_width_m)
sc = SafetyCore(SafetyParams.of(SafetyConfig(), ch.front_m, ch.rear_m, ch.half_width_m, ch.laser_mount))
urg = UrgParams(); inc = 2*math.pi/urg.ares; rng = np.random.default_rng(0)
import os; world, fld = ne.build(os.environ.get("WORLD","hallway"), fp)
xs = np.round(np.arange(*[float(v) for v in os.environ["XR"].split(",")], 0.05), 3); ys = np.round(np.arange(*[float(v) for v in os.environ["YR"].split(",")], 0.05), 3); ths = np.arange(0, 360, 10)
res = {}
t0 = time.time()
for x in xs:
    for y in ys:
        for td in ths:
            th = math.radians(td)
            # body clearance (footprint rectangle vs world segments) via the monitor itself: nearest_m
            raw = ray_scan(world.at(0.0), urg, (x, y, th), ch.laser_mount, 0.0, rng, (0.0, 0.0))
            r = np.where((raw < urg.dmin_mm) | (raw > urg.dmax_mm), np.nan, raw * 1e-3)
            P = scan_points(r, (urg.amin - urg.afrt) * inc, inc, urg.dmin_mm * 1e-3, urg.dmax_mm * 1e-3, ch.laser_mount)
            L = sc.limit(P, 0.0, 0.0)
            res[(float(x), float(y), int(td))] = (L.free_fwd_m, L.free_ccw_rad, L.free_cw_rad, L.omega, L.nearest_m)
print(len(res), time.time() - t0)
pickle.dump(res, open(os.environ["OUT"], "wb"))
