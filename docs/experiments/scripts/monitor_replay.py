# trace a case (MON env) and evaluate the monitor's limit (noiseless scan) at each 0.1 s pose
import sys, math, os
import numpy as np
import bench.nav_eval as ne
from autochair.control.core import ControlConfig
from autochair.runtime.config import load_section, ChairGeometry
from autochair.safety.core import SafetyCore, SafetyParams, scan_points
from autochair.safety.node import SafetyConfig
from autochair.sim.lidar.scanner import UrgParams, ray_scan
name = sys.argv[1]; seed = int(os.environ.get("SEED", "7")); mon = os.environ.get("MON", "0") == "1"
t0 = float(os.environ.get("T0", "0"))
cfg = load_section(ControlConfig, "control", None, [])
ch = ChairGeometry(); fp = ne.Footprint(ch.front_m, ch.rear_m, ch.half_width_m)
sc = SafetyCore(SafetyParams.of(SafetyConfig(), ch.front_m, ch.rear_m, ch.half_width_m, ch.laser_mount))
urg = UrgParams(); inc = 2*math.pi/urg.ares; rng = np.random.default_rng(0)
last = [-1.0]; W = [None]
def lim(world, pose, v, w):
    raw = ray_scan(world.at(0.0), urg, pose, ch.laser_mount, 0.0, rng, (0.0, 0.0))
    r = np.where((raw < urg.dmin_mm) | (raw > urg.dmax_mm), np.nan, raw * 1e-3)
    pts = scan_points(r, (urg.amin - urg.afrt) * inc, inc, urg.dmin_mm * 1e-3, urg.dmax_mm * 1e-3, ch.laser_mount)
    return sc.limit(pts, v, w)
def tick(t, core, chair):
    if t >= t0 and t - last[0] >= 0.1:
        last[0] = t
        L = lim(W[0], (chair.x, chair.y, chair.yaw), chair.v, chair.omega)
        print(f"t={t:6.2f} mv={'M' if core._move else '-'} x={chair.x:5.3f} y={chair.y:5.3f} yaw={math.degrees(chair.yaw):6.1f} v={chair.v:5.2f} w={chair.omega:5.2f} vf={L.v_fwd:5.2f} wb={L.omega:5.2f} ff={L.free_fwd_m:5.2f} ccw={L.free_ccw_rad:4.2f} cw={L.free_cw_rad:4.2f}")
for c in ne.CASES:
    if c[0] != name: continue
    world, fld = ne.build(c[1], fp); W[0] = world
    r = ne.run_case(world, fld, c[2], c[3], cfg, fp, ne.MpepcParams(seed=seed), 0.0, None, ne.DRIVEN.get(name), ne.SafetyRig(0) if mon else None, on_tick=tick)
    print(r["state"], r.get("reason"), r.get("time_s"))
