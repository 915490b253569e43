"""H79: per crossing of the 0.9 m door at v along a straight at heading th (deg) and lateral
offset off (m, at the wall x=4), the chance that a scan reads the forward way's bound 0 (a stop:
the PID latches it) and that one reads an imminent collision (the monitor's e-stop), against
the straight's bare clearance to the jambs (true geometry). From the repo root:
PYTHONPATH=services:schemas:. python docs/experiments/scripts/h79_cross.py REPS SEED V HEADINGS OFFSETS
e.g. `20 5 0.45 1,3 -0.035,-0.025,0.02`."""
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
rng = np.random.default_rng(int(sys.argv[2]) if len(sys.argv) > 2 else 1)
v = float(sys.argv[3]) if len(sys.argv) > 3 else 0.45
reps = int(sys.argv[1]) if len(sys.argv) > 1 else 10
wallpts = np.array([(4.0, y) for y in np.r_[np.arange(-2.0, 0.5501, 0.005), np.arange(1.45, 2.0001, 0.005)]])
def clearance(th, off, s_all):
    c, s = math.cos(th), math.sin(th)
    best = math.inf
    for d in s_all:
        x = 4.0 + d * c; y = 1.0 + off + d * s
        dx = wallpts[:, 0] - x; dy = wallpts[:, 1] - y
        lx = c * dx + s * dy; ly = -s * dx + c * dy
        ex = np.maximum(np.maximum(lx - ch.front_m, -ch.rear_m - lx), 0)
        ey = np.maximum(np.abs(ly) - ch.half_width_m, 0)
        best = min(best, float(np.hypot(ex, ey).min()))
    return best
step = v / 10.0  # one scan per 0.1 s
for thd in [float(a) for a in sys.argv[4].split(",")]:
    th = math.radians(thd)
    for off in [float(a) for a in sys.argv[5].split(",")]:
        s_all = np.arange(-1.6, 1.0, 0.01)  # the axle's distance along the straight from the wall
        clr = clearance(th, off, s_all)
        if clr <= 0.0:
            continue
        hit = zero = 0; scans = 0
        for rep in range(reps):
            phase = rng.uniform(0, step)
            for d in np.arange(-1.6 + phase, 1.0, step):
                pose = (4.0 + d * math.cos(th), 1.0 + off + d * math.sin(th), th)
                raw = ray_scan(world.at(0.0), urg, pose, ch.laser_mount, 0.01, rng, (v, 0.0))
                r = np.where((raw < urg.dmin_mm) | (raw > urg.dmax_mm), np.nan, raw * 1e-3)
                P = scan_points(r, (urg.amin - urg.afrt) * inc, inc, urg.dmin_mm * 1e-3, urg.dmax_mm * 1e-3, ch.laser_mount)
                scans += 1
                L = sc.limit(P, v, 0.0)
                if L.v_fwd == 0.0:
                    zero += 1
                    hit += L.imminent
                    break
        print(f"heading {thd:3.1f} deg offset {off*100:+3.0f} cm: bare clearance {clr:.3f} m, crossings stopped (bound 0) {zero}/{reps}, e-stopped {hit}/{reps}", flush=True)
