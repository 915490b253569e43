"""The best minimum clearance a case allows (nav_eval's `clearance_bound_m`): issue 12's
"≥ 0.2 m elsewhere" is only attainable where the world leaves that much room.

`upper_bound` (what no motion can beat; from the exact world, people left out):
- the footprint's clearance at the start pose and at the goal pose (every motion holds them);
- the room along the way: a point of the rectangle at depth e from its outline (the disc of
  radius e round it lies inside) is at least (footprint clearance + e) from every obstacle, so
  a motion whose footprint keeps c everywhere carries that point along a path keeping c + e.
  The points of the chair's centre line from half a width behind to half a width before the
  ends (e = half width) are such points; the widest path of one between its places at the start
  and goal (the maximin of the point's clearance: a bottleneck search on a grid) less e bounds
  c. A corridor W wide gives (W − 2·half width)/2. It ignores the heading (turning a corner in
  a narrow corridor asks for more: the bound is then loose, never low).

`lattice_attainable` (what some forward-only motion does reach): the largest clearance at which
the heading lattice (nav/lattice.py: 0.05 m × 16 headings, straight steps, arcs of 0.6 m, turns
in place; states free when no map cell closer than that lies under the rectangle grown by half
a cell) still joins the start's state to the goal's: a lower estimate. The rasterised map (an
obstacle's edge on a cell's edge marks the cell beyond it: a 1.1 m gap is 1.0 m on the 0.05 m
grid) and the grown rectangle read it low, by up to ~9 cm (tests); the start and goal are taken
at the lattice states within half a cell and 11° of them.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import scipy.ndimage as ndi
from scipy.sparse.csgraph import breadth_first_order

from autochair.nav.field import Footprint, NavField, place
from autochair.nav.lattice import LatticeParams, free_states, graph, legal_moves, moves
from autochair.sim.world import World

Pose = tuple[float, float, float]
F64 = np.ndarray[Any, np.dtype[np.float64]]
GRID_M = 0.02  # the bottleneck search's grid (its reading is at most GRID_M/√2 under the truth)


def pose_clearance(world: World, fp: Footprint, pose: Pose, spacing_m: float = 0.01) -> float:
    """The footprint's clearance at a pose against the exact world's static shapes (0 if an
    obstacle is inside)."""
    pts = place(fp.outline(spacing_m), *pose)
    d = float(world.distance_to(pts).min())
    if len(world.circles):
        c = world.circles
        # a disc wholly under the chair: its centre inside the rectangle
        x, y = c[:, 0] - pose[0], c[:, 1] - pose[1]
        cs, sn = math.cos(pose[2]), math.sin(pose[2])
        if fp.contains(np.stack([cs * x + sn * y, -sn * x + cs * y], -1)).any():
            return 0.0
    return d


def point_clearance(world: World, x: F64, y: F64) -> F64:
    """Distance from points (...) to the world's static shapes (0 inside a disc): one shape at
    a time (World.distance_to's (points, shapes, 2) temporaries took ~20 s on the hallway)."""
    best = np.full(np.shape(x), np.inf)
    for x1, y1, x2, y2 in world.segments:
        dx, dy = x2 - x1, y2 - y1
        t = np.clip(((x - x1) * dx + (y - y1) * dy) / max(dx * dx + dy * dy, 1e-12), 0.0, 1.0)
        np.minimum(best, np.hypot(x - (x1 + t * dx), y - (y1 + t * dy)), out=best)
    for cx, cy, r in world.circles:
        np.minimum(best, np.maximum(np.hypot(x - cx, y - cy) - r, 0.0), out=best)
    return best


def bottleneck(clear: F64, a: tuple[int, int], b: tuple[int, int], tol_m: float = 1e-3
               ) -> float:
    """The largest t (to `tol_m`, rounded up) such that cells a and b (row, col) are joined by
    8-connected cells of `clear` ≥ t (the maximin path's value), by bisection."""
    lo, hi = 0.0, float(min(clear[a], clear[b])) + tol_m  # lo joins them, hi does not
    eight = np.ones((3, 3), dtype=bool)
    while hi - lo > tol_m:
        mid = (lo + hi) / 2
        lab, _ = ndi.label(clear >= mid, eight)
        lo, hi = (mid, hi) if lab[a] == lab[b] != 0 else (lo, mid)
    return hi


class Room:
    """A world's static shapes and its points' clearance on a GRID_M grid (`upper_bound`)."""

    def __init__(self, world: World, margin_m: float = 1.0) -> None:
        self.world = world
        shapes = np.concatenate([world.segments[:, :2], world.segments[:, 2:],
                                 world.circles[:, :2] - world.circles[:, 2:3],
                                 world.circles[:, :2] + world.circles[:, 2:3]])
        self.lo = shapes.min(0) - margin_m
        hi = shapes.max(0) + margin_m
        gx, gy = np.meshgrid(np.arange(self.lo[0], hi[0], GRID_M),
                             np.arange(self.lo[1], hi[1], GRID_M))
        self.clear = point_clearance(world, gx, gy)

    def upper_bound(self, fp: Footprint, start: Pose, goal: Pose) -> dict[str, float]:
        """The least of the start's and goal's clearances and the room along the way (see
        the module doc); each term too."""
        e = fp.half_width_m
        way = math.inf
        for u in np.linspace(e - fp.rear_m, fp.front_m - e, 3):  # points at depth e
            ends = [(round((y + u * math.sin(yaw) - self.lo[1]) / GRID_M),
                     round((x + u * math.cos(yaw) - self.lo[0]) / GRID_M))
                    for x, y, yaw in (start, goal)]
            # a path's cells lie within GRID_M/√2 of it: their clearance can read that less
            way = min(way, bottleneck(self.clear, ends[0], ends[1]) + GRID_M / math.sqrt(2) - e)
        s, g = pose_clearance(self.world, fp, start), pose_clearance(self.world, fp, goal)
        return {"bound_m": min(s, g, way), "start_m": s, "goal_m": g, "way_m": way}


def _joined(fld: NavField, start: Pose, goal: Pose, clear_m: float, p: LatticeParams
            ) -> bool:
    """Whether the lattice's forward-only motions with states clear by `clear_m` lead from the
    start's state to the goal's (a window round both, 1.5 m beyond)."""
    gm = fld.map
    res = gm.resolution_m
    f = max(1, round(p.resolution_m / res))
    pad = 1.5
    cell = [(math.floor((y - gm.origin_y_m) / res), math.floor((x - gm.origin_x_m) / res))
            for x, y, _ in (start, goal)]
    r = round(pad / res)
    mh, mw = gm.occupied.shape
    i0 = max(min(c[0] for c in cell) - r, 0)
    j0 = max(min(c[1] for c in cell) - r, 0)
    i1 = min(max(c[0] for c in cell) + r, mh - 1)
    j1 = min(max(c[1] for c in cell) + r, mw - 1)
    i1, j1 = i0 + (i1 - i0) // f * f, j0 + (j1 - j0) // f * f
    n = p.headings
    both = free_states(fld, (i0, i1, j0, j1), f, n, clear_m)
    full, half_steps = both[0::2], both[1::2]
    _, h, w = full.shape
    step = 2 * math.pi / n

    def state(pose: Pose, c: tuple[int, int]) -> int:
        k = round(pose[2] / step) % n
        return int((k * h + min((c[0] - i0 + f // 2) // f, h - 1)) * w
                   + min((c[1] - j0 + f // 2) // f, w - 1))

    s, g = state(start, cell[0]), state(goal, cell[1])
    if not (full.reshape(-1)[s] and full.reshape(-1)[g]):
        return False
    virtual = n * h * w
    lat = graph((n, h, w), len(moves(p)[0].k2),
                ((k, k2, a, b, ok, 1.0) for k, k2, a, b, ok, _, _ in
                 legal_moves(full, half_steps, p)), False, np.array([s], dtype=np.int32), 1.0)
    order = breadth_first_order(lat, virtual, directed=True, return_predecessors=False)
    return bool(np.isin(g, order))


def lattice_attainable(fld: NavField, start: Pose, goal: Pose, upto: float,
                       tol_m: float = 0.005) -> float | None:
    """The largest clearance (to `tol_m`, at most `upto`) at which the lattice joins the start
    to the goal (see the module doc); None if it does not even at its own min_clear_m."""
    p = LatticeParams()
    lo, hi = p.min_clear_m, upto
    if not _joined(fld, start, goal, lo, p):
        return None
    while hi - lo > tol_m:
        mid = (lo + hi) / 2
        if _joined(fld, start, goal, mid, p):
            lo = mid
        else:
            hi = mid
    return lo
