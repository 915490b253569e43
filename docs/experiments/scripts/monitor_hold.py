"""How often the safety monitor's |ω| bound holds a chair standing at a pose (s32, office B's
desk): SafetyCore.assess on scans of the hallway with the simulator's laser noise (1 cm), at
rest; 'held' = |ω| bound <= 0.02 rad/s (the control core's HELD_RADPS: a turn under way it
brings to a stand ends the goal, H73). Also the map's footprint clearance there.

    PYTHONPATH=services:schemas:. .venv/bin/python docs/experiments/scripts/monitor_hold.py \
        X Y DEG [DEG ...]
"""
import math
import sys

import bench.nav_eval as ne
import numpy as np

from autochair.runtime.config import ChairGeometry
from autochair.safety.core import SafetyCore, SafetyParams, Scan
from autochair.safety.node import SafetyConfig
from autochair.sim.lidar.scanner import UrgParams, ray_scan

ch = ChairGeometry()
fp = ne.Footprint(ch.front_m, ch.rear_m, ch.half_width_m)
sc = SafetyCore(SafetyParams.of(SafetyConfig(), ch.front_m, ch.rear_m, ch.half_width_m,
                                ch.laser_mount))
urg = UrgParams()
inc = 2 * math.pi / urg.ares
rng = np.random.default_rng(0)
world, fld = ne.build("hallway", fp)


def held(x: float, y: float, deg: float, n: int = 40) -> float:
    count = 0
    for _ in range(n):
        raw = ray_scan(world.at(0.0), urg, (x, y, math.radians(deg)), ch.laser_mount, 0.01, rng,
                       (0.0, 0.0))
        r = np.where((raw < urg.dmin_mm) | (raw > urg.dmax_mm), np.nan, raw * 1e-3)
        scan = Scan(r, (urg.amin - urg.afrt) * inc, inc, urg.dmin_mm * 1e-3, urg.dmax_mm * 1e-3)
        count += sc.assess(scan, 0.0, 0.0).omega <= 0.02
    return count / n


x, y = float(sys.argv[1]), float(sys.argv[2])
for deg in map(float, sys.argv[3:]):
    c = fld.footprint_clearance(np.array([x]), np.array([y]), np.array([math.radians(deg)]))[0]
    print(f"({x}, {y}, {deg:g}°) map clearance {c:.3f} m, held on {100 * held(x, y, deg):.0f} %"
          " of scans")
