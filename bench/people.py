"""People tracker evaluation: `python -m bench people` → bench/results/people.json.

Simulated URG-04LX scans (the simulator's own ray caster, 1 cm range noise) of worlds with
walking people and without, seen from a chair driven along a scripted path; the map is the
world's static part (a surveyed map). Scored against the simulator's ground truth:
- recall: scans in which a visible person (in the field of view, within range, not hidden)
  has a confirmed track within 0.5 m;
- position and velocity error of matched tracks (velocity once a track is 1 s old);
- false tracks: confirmed tracks with no person within 0.6 m (distinct ids per minute);
- latency: from a person's first visible scan to their first confirmed track;
- time per scan.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from autochair.nav.field import GridMap
from autochair.people.core import PeopleTracker, StaticMap, scan_points
from autochair.runtime.config import ChairGeometry
from autochair.sim.lidar.scanner import UrgParams, ray_scan
from autochair.sim.world import World, load_world, raycast

WORLDS = Path(__file__).resolve().parents[1] / "services/autochair/sim/worlds"
RESULTS = Path(__file__).resolve().parent / "results" / "people.json"
DT = 0.1  # 10 scans/s
Pose = tuple[float, float, float]


def line(x0: float, y0: float, x1: float, v: float) -> Callable[[float], Pose]:
    """Along +x from (x0, y0) to x1 at v m/s, then parked."""
    return lambda t: (min(x0 + v * t, x1), y0, 0.0)


def spin(rate: float) -> Callable[[float], Pose]:
    return lambda t: (0.0, 0.0, rate * t)


# name, world, chair path, duration (s), map misplaced by (m): a map built from drifting
# odometry does not lie exactly under the scans
CASES: list[tuple[str, str, Callable[[float], Pose], float, float]] = [
    ("crossing: chair drives past", "crossing", line(0.0, 0.0, 9.0, 0.5), 40.0, 0.0),
    ("passing: met head-on", "passing", line(0.0, 0.6, 10.0, 0.4), 40.0, 0.0),
    ("passing: map 8 cm off", "passing", line(0.0, 0.6, 10.0, 0.4), 40.0, 0.08),
    ("hallway: no one", "hallway", line(0.0, 0.0, 20.0, 0.8), 30.0, 0.0),
    ("hallway: no one, map 8 cm off", "hallway", line(0.0, 0.0, 20.0, 0.8), 30.0, 0.08),
    ("cluttered: no one, turning", "cluttered", spin(0.4), 30.0, 0.0),
]


def visible(world: World, person: np.ndarray, laser: Pose, fov: float, rmax: float) -> bool:
    x, y, r = person[0], person[1], person[4]
    dx, dy = x - laser[0], y - laser[1]
    d = math.hypot(dx, dy)
    bearing = math.atan2(dy, dx)
    off = (bearing - laser[2] + math.pi) % (2 * math.pi) - math.pi
    if d > rmax or abs(off) > fov:
        return False
    hit = raycast(world, laser[0], laser[1], np.array([bearing]), rmax)[0]
    return bool(hit >= d - r - 0.05)


def run_case(world: World, path: Callable[[float], Pose], duration: float, off_m: float = 0.0,
             seed: int = 7) -> dict[str, float | None]:
    rng = np.random.default_rng(seed)
    params, mount = UrgParams(), ChairGeometry().laser_mount
    grid = GridMap.from_shapes(world.segments, world.circles, 0.05)
    tracker = PeopleTracker(static=StaticMap.of(grid.occupied, grid.resolution_m,
                                                grid.origin_x_m + off_m,
                                                grid.origin_y_m + off_m))
    angles = params.step_angles()
    fov = max(abs(angles[0]), abs(angles[-1]))
    n_vis = n_hit = 0
    pos_err: list[float] = []
    vel_err: list[float] = []
    first_seen: dict[int, float] = {}  # person → first visible scan
    found: set[int] = set()  # people whose latency is measured
    born: dict[int, float] = {}
    latency: list[float] = []
    false_ids: set[int] = set()
    times: list[float] = []
    for k in range(int(duration / DT)):
        t = k * DT
        x, y, yaw = path(t)
        lx = x + mount[0] * math.cos(yaw) - mount[1] * math.sin(yaw)
        ly = y + mount[0] * math.sin(yaw) + mount[1] * math.cos(yaw)
        raw = ray_scan(world.at(t), params, (x, y, yaw), mount, 0.01, rng)
        r = np.where(raw >= params.dmin_mm, raw / 1000.0, np.nan)
        t0 = time.perf_counter()
        pts = scan_points(r, float(angles[0]), float(angles[1] - angles[0]), 0.02, 5.6,
                          (lx, ly, yaw + mount[2]))
        rays = (np.full(r.size, lx), np.full(r.size, ly), yaw + mount[2] + angles)
        tracks = tracker.update(pts, (lx, ly), t, rays)
        times.append(time.perf_counter() - t0)
        for tr in tracks:
            born.setdefault(tr.track_id, t)
        truth = world.people_state(t)
        for i, person in enumerate(truth):
            if not visible(world, person, (lx, ly, yaw + mount[2]), fov, 5.6):
                continue
            n_vis += 1
            first_seen.setdefault(i, t)
            dists = [math.hypot(q.x_m - person[0], q.y_m - person[1]) for q in tracks]
            if not dists or min(dists) > 0.5:
                continue
            d = min(dists)
            tr = tracks[dists.index(d)]
            n_hit += 1
            pos_err.append(d)
            if i not in found:
                latency.append(t - first_seen[i])
                found.add(i)
            if t - born[tr.track_id] >= 1.0:
                vel_err.append(math.hypot(tr.vx_mps - person[2], tr.vy_mps - person[3]))
        for tr in tracks:
            if all(math.hypot(tr.x_m - p[0], tr.y_m - p[1]) > 0.6 for p in truth):
                false_ids.add(tr.track_id)
    ms = np.array(times) * 1e3

    def rms(e: list[float]) -> float | None:  # None: nothing to score (no one in view)
        return round(float(np.sqrt(np.mean(np.square(e)))), 3) if e else None

    return {"visible_scans": n_vis,
            "recall": round(n_hit / n_vis, 3) if n_vis else None,
            "pos_rmse_m": rms(pos_err), "vel_rmse_mps": rms(vel_err),
            "latency_s": round(max(latency), 2) if latency else None,
            "false_tracks_per_min": round(len(false_ids) / (duration / 60), 2),
            "ms_per_scan_median": round(float(np.median(ms)), 3),
            "ms_per_scan_p95": round(float(np.percentile(ms, 95)), 3)}


def main(argv: list[str]) -> int:
    out: dict[str, dict[str, float | None]] = {}
    for name, world_name, path, duration, off_m in CASES:
        res = run_case(load_world(WORLDS / f"{world_name}.world"), path, duration, off_m)
        out[name] = res
        print(f"{name:30s} " + "  ".join(f"{k} {v}" for k, v in res.items()), flush=True)
    RESULTS.write_text(json.dumps({"cases": out}, indent=1) + "\n")
    print(f"results: {RESULTS}")
    return 0


if __name__ == "__main__":
    import sys

    sys.exit(main(sys.argv[1:]))
