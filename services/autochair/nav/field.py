"""Navigation function over an occupancy grid. PURE (numpy, scipy, scikit-fmm; no clock, no I/O).

- `GridMap`: a boolean obstacle grid in a named frame (from the mapping service's OccupancyGrid
  message, or rasterised from a simulator world file).
- `Footprint`: the chair's real rectangle around the drive axle (ChairGeometry: 0.95 m ahead,
  0.25 m behind, 0.35 m each side), sampled along its outline.
- `NavField`: the clearance (Euclidean distance transform, scipy; read by bilinear interpolation,
  and near obstacles as the exact distance to the nearest occupied cell's square) and, per
  goal, the costs-to-go (fast marching, scikit-fmm: the Eikonal solution has no 8-neighbour
  staircase, so its gradient — what MPEPC measures progress on — is smooth).

Footprint: the axle point may only cross cells with clearance ≥ half width + `pass_margin_m`
(whatever the heading, the body reaches that far sideways of the axle); costs grow near
obstacles (slower travel within `soft_m` of that bound), so paths keep to the middle of
corridors and doorways. The full, non-circular outline is checked by the planner on every
predicted pose and by `check_goal` on the goal pose.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import numpy.typing as npt
import scipy.ndimage as ndi
import skfmm

from . import gil

F64 = npt.NDArray[np.float64]
IntOrArray = int | npt.NDArray[np.intp]
Bool = npt.NDArray[np.bool_]

OCCUPIED_PCT = 65  # an OccupancyGrid cell ≥ this (percent, not 255 = unknown) is an obstacle
# Outline points sampled per batch (NavField.footprint_clearance): the sampling's ~40
# temporaries then stay in the CPU's cache. A plan round's 88k points in one batch took 3×
# as long as in batches of ~13k (measured: 6.4 → 2.3 ms).
BATCH_POINTS = 16384
COARSE_SPACING_M = 0.15  # NavField's coarse outline: its points at most this far apart
FINE_SPLIT = 3  # NavField's fine outline: the coarse one's gaps split in 3
REFINE_BELOW_M = 0.10  # ... read where the coarse one reads under this
# Where the bilinear clearance reads under this, the exact distance to the nearest occupied
# cell's square is read instead (NavField._exact: the bilinear one reads up to ~2.3 cm over
# it by an obstacle's corner, H47). Above every reading a decision is taken at (margins
# 0.02–0.05 m; the fine outline's range, `_refine_range`, up to ~0.123 m) by more than
# BILINEAR_OVER_M, how far the bilinear reading can be over the exact one where it reads this
# or more (measured: 1.2 cm; 0.21 cells from the centres' diagonal bias, ~0.05 the
# interpolation's overshoot of a cone 2.5 cells off).
EXACT_BELOW_M = 0.14
BILINEAR_OVER_M = 0.015
# (x, y) offsets of the cell centres whose nearest obstacles NavField._exact reads, from the
# one at or left of and below the point: the 4 round it first
EXACT_BLOCK = ((0, 0), (1, 0), (0, 1), (1, 1), (-1, 0), (-1, 1), (2, 0), (2, 1), (0, -1),
               (1, -1), (0, 2), (1, 2))
EXACT_X = np.array([float(dx) for dx, _ in EXACT_BLOCK])
EXACT_Y = np.array([float(dy) for _, dy in EXACT_BLOCK])
# On coarser grids (a map saved or built at over 0.05 m), the same in cells: EXACT_BELOW_M is
# 2.8 cells at 0.05 m and BILINEAR_OVER_M 0.3 (at 0.1 m cells the bilinear reading past 0.14 m
# was 2.6 cm over the exact one; past 2.8 cells ≤ 0.27 cells at 0.025–0.2 m; measured)
EXACT_BELOW_CELLS = 2.8
BILINEAR_OVER_CELLS = 0.3
SLOTS = 6  # distinct candidates kept per cell (NavField._candidates; more: all are read)


@dataclass(frozen=True)
class Footprint:
    front_m: float = 0.95
    rear_m: float = 0.25
    half_width_m: float = 0.35

    @property
    def reach_m(self) -> float:
        """Radius of the disc the body sweeps turning in place round the axle."""
        return math.hypot(max(self.front_m, self.rear_m), self.half_width_m)

    def turn_samples(self, angle_rad: float, step_m: float = 0.05) -> int:
        """Poses to check an in-place turn through `angle_rad` at: the body's far corners
        move at most `step_m` between two (both ends included)."""
        return max(2, math.ceil(abs(angle_rad) * self.reach_m / step_m) + 1)

    def outline(self, spacing_m: float = 0.1, split: int = 1) -> F64:
        """(P, 2) points on the rectangle's outline, in the chair frame, at most `spacing_m`
        apart; with `split`, each gap between those divided into that many."""
        xs = np.linspace(-self.rear_m, self.front_m, split * max(
            1, math.ceil((self.front_m + self.rear_m) / spacing_m)) + 1)
        ys = np.linspace(-self.half_width_m, self.half_width_m, split * max(
            1, math.ceil(2 * self.half_width_m / spacing_m)) + 1)
        hw = self.half_width_m
        pts = [np.stack([xs, np.full_like(xs, hw)], 1), np.stack([xs, np.full_like(xs, -hw)], 1),
               np.stack([np.full_like(ys, self.front_m), ys], 1),
               np.stack([np.full_like(ys, -self.rear_m), ys], 1)]
        return np.unique(np.concatenate(pts), axis=0)

    def contains(self, pts_chair: F64) -> Bool:
        """Which chair-frame points lie inside the rectangle."""
        x, y = pts_chair[..., 0], pts_chair[..., 1]
        return (x >= -self.rear_m) & (x <= self.front_m) & (np.abs(y) <= self.half_width_m)


@dataclass(frozen=True)
class Contact:
    """A chair the map shows within its margin, as it stands (NavField.contact)."""

    outline: F64  # (P, 2) chair-frame points, the coarse outline's and the fine one's
    now: F64  # (P,) their signed clearance (NavField.signed_xy)
    cells: F64  # (K, 2) world centres of the occupied cells the body overlaps
    deepest: float  # how far the deepest of them reaches into it (NavField.body_depth)
    slack: float  # how much closer (deeper) any may come (noise, not motion: MPEPC's TOUCH_M)


def place(points: F64, x: F64 | float, y: F64 | float, yaw: F64 | float) -> F64:
    """Chair-frame (P, 2) points at poses (...): world (..., P, 2)."""
    return np.stack(place_xy(points, x, y, yaw), axis=-1)


def place_xy(points: F64, x: F64 | float, y: F64 | float, yaw: F64 | float
             ) -> tuple[F64, F64]:
    """`place` as separate world x and y arrays (..., P) (the planner's hot path: no stacking)."""
    x, y, yaw = np.asarray(x)[..., None], np.asarray(y)[..., None], np.asarray(yaw)[..., None]
    c, s = np.cos(yaw), np.sin(yaw)
    px, py = points[:, 0], points[:, 1]
    # x + c·px − s·py and y + s·px + c·py, operation for operation, in place (fewer temporaries)
    shape = np.broadcast_shapes(x.shape, y.shape, c.shape, px.shape)
    wx, wy, t = np.empty(shape), np.empty(shape), np.empty(shape)
    np.multiply(c, px, out=wx)
    wx += x
    np.multiply(s, py, out=t)
    wx -= t
    np.multiply(s, px, out=wy)
    wy += y
    np.multiply(c, py, out=t)
    wy += t
    return wx, wy


def _merged(cells: Bool, f: int, every: bool) -> Bool:
    """f × f blocks of `cells` merged into one: true if any (`every`: all) of them is; the
    blocks past the edges padded with `every`. Strided slices or-ed (and-ed) in place: numpy's
    any/all over two axes of a 4-D view took 2.5 ms a grid, this 0.2 ms (every new grid, 1 Hz)."""
    h, w = cells.shape
    pad = np.full((-(-h // f) * f, -(-w // f) * f), every, dtype=np.bool_)
    pad[:h, :w] = cells
    out = pad[0::f, 0::f].copy()
    op = np.logical_and if every else np.logical_or
    for i in range(f):
        for j in range(f):
            if i or j:
                op(out, pad[i::f, j::f], out=out)
    return out


@dataclass(frozen=True)
class GridMap:
    occupied: Bool  # (H, W), row = y
    resolution_m: float
    origin_x_m: float  # world position of cell (0, 0)'s corner
    origin_y_m: float
    frame_id: str = "map"
    unknown: Bool | None = None  # (H, W) cells never observed (None: all were)

    @classmethod
    def from_msg(cls, msg: object) -> GridMap:
        """From an autochair_msgs.OccupancyGrid (unknown cells count as free: the chair
        must be able to plan into what the laser has not seen yet; they are kept apart for
        where it matters that nothing was seen there: nav/lattice.unreachable)."""
        data = np.frombuffer(msg.data, dtype=np.uint8)  # type: ignore[attr-defined]
        grid = data.reshape(msg.height, msg.width)  # type: ignore[attr-defined]
        occ = (grid >= OCCUPIED_PCT) & (grid != 255)
        return cls(occ, float(msg.resolution_m), float(msg.origin_x_m),  # type: ignore[attr-defined]
                   float(msg.origin_y_m), str(msg.frame_id), grid == 255)  # type: ignore[attr-defined]

    @classmethod
    def from_shapes(cls, segments: F64, circles: F64, resolution_m: float = 0.05,
                    margin_m: float = 1.0, frame_id: str = "map") -> GridMap:
        """Rasterise walls (S, 4) and discs (C, 3) (a simulator world) onto a grid that covers
        them plus `margin_m`."""
        pts = [segments[:, :2], segments[:, 2:], circles[:, :2] - circles[:, 2:],
               circles[:, :2] + circles[:, 2:]]
        allp = np.concatenate([p.reshape(-1, 2) for p in pts])
        lo, hi = allp.min(0) - margin_m, allp.max(0) + margin_m
        w, h = (np.ceil((hi - lo) / resolution_m)).astype(int)
        occ = np.zeros((h, w), dtype=np.bool_)
        gm = cls(occ, resolution_m, float(lo[0]), float(lo[1]), frame_id)
        step = resolution_m / 3
        for x1, y1, x2, y2 in segments:
            n = max(2, math.ceil(math.hypot(x2 - x1, y2 - y1) / step) + 1)
            t = np.linspace(0, 1, n)
            gm.mark(np.stack([x1 + t * (x2 - x1), y1 + t * (y2 - y1)], 1))
        if len(circles):
            cx, cy = gm.centres()
            for x0, y0, r in circles:
                occ |= (cx - x0) ** 2 + (cy - y0) ** 2 <= (r + resolution_m / 2) ** 2
        return gm

    def coarsened(self, factor: int) -> GridMap:
        """`factor` × `factor` cells merged into one, occupied if any of them is (the field is
        computed at this resolution to bound its cost on a large live map)."""
        if factor <= 1:
            return self
        occ = _merged(self.occupied, factor, False)
        # unknown where none of them was observed
        unknown = None if self.unknown is None else _merged(self.unknown, factor, True)
        return GridMap(occ, self.resolution_m * factor, self.origin_x_m, self.origin_y_m,
                       self.frame_id, unknown)

    def centre(self, ix: IntOrArray, iy: IntOrArray) -> tuple[F64, F64]:
        """World centres (x, y) of the cells at column(s) ix, row(s) iy."""
        return (np.asarray(self.origin_x_m + (ix + 0.5) * self.resolution_m, dtype=np.float64),
                np.asarray(self.origin_y_m + (iy + 0.5) * self.resolution_m, dtype=np.float64))

    def centres(self) -> tuple[F64, F64]:
        h, w = self.occupied.shape
        return np.meshgrid(*self.centre(np.arange(w), np.arange(h)))

    def mark(self, pts: F64) -> None:
        """Set the cells holding world points (N, 2) occupied (outside ones are ignored)."""
        h, w = self.occupied.shape
        ix = np.floor((pts[:, 0] - self.origin_x_m) / self.resolution_m).astype(int)
        iy = np.floor((pts[:, 1] - self.origin_y_m) / self.resolution_m).astype(int)
        ok = (ix >= 0) & (ix < w) & (iy >= 0) & (iy < h)
        self.occupied[iy[ok], ix[ok]] = True


def bilinear(grid: F64, gm: GridMap, pts: F64, outside: float) -> F64:
    """Sample a cell-centred (H, W) grid at world points (..., 2)."""
    return bilinear_xy(grid, gm, pts[..., 0], pts[..., 1], outside)


def bilinear_xy(grid: F64, gm: GridMap, x: F64, y: F64, outside: float) -> F64:
    """`bilinear` at world points given as separate x and y arrays (...)."""
    return _sample(grid, *_cell_xy(gm, x, y), outside)


def _cell_xy(gm: GridMap, x: F64, y: F64) -> tuple[F64, F64]:
    """World points as fractional indices of the cell-centred grid (what _sample reads)."""
    return (np.asarray((x - gm.origin_x_m) / gm.resolution_m - 0.5, dtype=np.float64),
            np.asarray((y - gm.origin_y_m) / gm.resolution_m - 0.5, dtype=np.float64))


def _sample(grid: F64, fx: F64, fy: F64, outside: float,
            corners: tuple[F64, F64, F64, F64] | None = None) -> F64:
    """`bilinear_xy` at fractional cell indices fx, fy. With `corners` (the grid flat and
    shifted by one cell in x, y and both: NavField._corners) the four gathers take one index
    and the sum is formed in place, term by term (the same numbers; fx, fy are then the
    caller's scratch, overwritten)."""
    return _sample_at(grid, fx, fy, outside, corners)[0]


def _sample_at(grid: F64, fx: F64, fy: F64, outside: float,
               corners: tuple[F64, F64, F64, F64] | None = None
               ) -> tuple[F64, npt.NDArray[np.intp], F64, F64]:
    """`_sample`; and the flat index of each point's lower left cell centre and the point's
    fraction of a cell past it in x and y (with `corners`: fx, fy or, near the edges, new
    arrays)."""
    h, w = grid.shape
    # Points all well inside (the planner's usual case) need neither the clamp nor `outside`.
    inner = fx.size > 0 and fx.min() >= 0 and fy.min() >= 0 \
        and fx.max() <= w - 1.0001 and fy.max() <= h - 1.0001
    if not inner:
        inside = (fx >= 0) & (fx <= w - 1) & (fy >= 0) & (fy <= h - 1)
        fx = np.minimum(np.maximum(fx, 0), w - 1.0001)
        fy = np.minimum(np.maximum(fy, 0), h - 1.0001)
    x0, y0 = fx.astype(np.intp), fy.astype(np.intp)
    # Gathers from the flat grid (faster than 2-D fancy indexing; the planner's hot spot).
    i = y0 * w + x0
    if corners is None:
        ax, ay = fx - x0, fy - y0
        bx, by = 1 - ax, 1 - ay
        flat = grid.ravel()
        v = (flat.take(i) * bx * by + flat.take(i + 1) * ax * by
             + flat.take(i + w) * bx * ay + flat.take(i + w + 1) * ax * ay)
        return (v if inner else np.where(inside, v, outside)), i, ax, ay
    ax, ay = fx, fy
    ax -= x0
    ay -= y0
    bx, by = 1 - ax, 1 - ay
    c00, c01, c10, c11 = corners
    v = c00.take(i)
    v *= bx
    v *= by
    t = c01.take(i)
    t *= ax
    t *= by
    v += t
    c10.take(i, out=t)
    t *= bx
    t *= ay
    v += t
    c11.take(i, out=t)
    t *= ax
    t *= ay
    v += t
    return (v if inner else np.where(inside, v, outside)), i, ax, ay


def _sample_one(grid: F64, gm: GridMap, x: float, y: float, outside: float) -> float:
    """`bilinear_xy` at one point in Python floats: the same operations in the same order
    (_cell_xy, _sample_at), so the same number."""
    h, w = grid.shape
    fx = (x - gm.origin_x_m) / gm.resolution_m - 0.5
    fy = (y - gm.origin_y_m) / gm.resolution_m - 0.5
    inside = 0 <= fx <= w - 1 and 0 <= fy <= h - 1
    fx = min(max(fx, 0.0), w - 1.0001)  # (a no-op where _sample_at skips the clamp)
    fy = min(max(fy, 0.0), h - 1.0001)
    x0, y0 = int(fx), int(fy)
    ax, ay = fx - x0, fy - y0
    bx, by = 1 - ax, 1 - ay
    flat = grid.ravel()
    i = y0 * w + x0
    v = (float(flat[i]) * bx * by + float(flat[i + 1]) * ax * by
         + float(flat[i + w]) * bx * ay + float(flat[i + w + 1]) * ax * ay)
    return v if inside else outside


# A way is in a narrow passage (a door) where the axle's clearance is under this
NARROW_M = 0.6
# A door's line-up pose stands this far before its narrowest point (NavField.door_approaches)
LINE_UP_M = 1.5


def passages(clr: F64, narrow_m: float) -> Iterator[tuple[int, int]]:
    """The narrow passages (doors) along a way whose clearances are `clr` (N,): each one's
    end (the first index past it with `narrow_m` again; N: the way ends in it) and its
    narrowest point's index."""
    i, n = 0, len(clr)
    while i < n:
        if clr[i] >= narrow_m:
            i += 1
            continue
        j = i
        while j < n and clr[j] < narrow_m:
            j += 1
        yield j, i + int(np.argmin(clr[i:j]))
        i = j


def heading_through(path: F64, k: int) -> float:
    """The way's heading (rad) through its point k (N, 2): over 6 points each side."""
    a, b = path[max(k - 6, 0)], path[min(k + 6, len(path) - 1)]
    return math.atan2(b[1] - a[1], b[0] - a[0])


def walked_to(path: F64, k: int) -> float:
    """The way's length (m) from its start to its point k."""
    return float(np.hypot(*np.diff(path[:k + 1], axis=0).T).sum()) if k else 0.0


@dataclass(frozen=True)
class CostToGo:
    """Costs-to-go (metres at full speed) to one goal position; extended past the passable
    region (+ `outside_slope` per metre into it) so predictions grazing a wall still compare."""

    phi: F64  # (H, W)
    grad_x: F64
    grad_y: F64
    reachable: Bool  # passable and connected to the goal
    goal_xy: tuple[float, float]

    def at(self, gm: GridMap, pts: F64) -> F64:
        return bilinear(self.phi, gm, pts, float(self.phi.max()) + 10.0)

    def descent(self, gm: GridMap, pts: F64) -> F64:
        """Heading (rad) of −∇φ at world points (..., 2)."""
        gx = bilinear(self.grad_x, gm, pts, 0.0)
        gy = bilinear(self.grad_y, gm, pts, 0.0)
        return np.arctan2(-gy, -gx)

    def descent_xy(self, gm: GridMap, x: float, y: float) -> float:
        """`descent` at one point, the same number: the descent paths step it point by point
        (~55 a planning cycle), where numpy's per-call cost was most of it."""
        gx = _sample_one(self.grad_x, gm, x, y, 0.0)
        gy = _sample_one(self.grad_y, gm, x, y, 0.0)
        return float(np.arctan2(-gy, -gx))


class NavField:
    def __init__(self, gm: GridMap, footprint: Footprint, pass_margin_m: float = 0.02,
                 soft_m: float = 0.6, slow_factor: float = 0.3, power: float = 1.0) -> None:
        self.map, self.footprint = gm, footprint
        res = gm.resolution_m
        # Distance from each cell centre to the nearest obstacle cell's edge.
        edt, self._nearest = ndi.distance_transform_edt(~gm.occupied, return_indices=True)
        edt = edt * res
        self.clearance: F64 = np.maximum(np.asarray(edt, dtype=np.float64) - res / 2, 0.0)
        if not gm.occupied.any():
            self.clearance[:] = 1e3
        # (EXACT_BELOW_M, BILINEAR_OVER_M for this grid's cells)
        self.exact_below_m = max(EXACT_BELOW_M, EXACT_BELOW_CELLS * res)
        self.bilinear_over_m = max(BILINEAR_OVER_M, BILINEAR_OVER_CELLS * res)
        exact = bool(gm.occupied.any()) and min(gm.occupied.shape) >= 2
        self._corner = self._corner_cells() if exact else None
        self._slots = self._candidates() if exact else None
        self.pass_m = footprint.half_width_m + pass_margin_m
        self.passable: Bool = self.clearance >= self.pass_m
        # Speed 1 beyond `soft_m` of the bound, down to `slow_factor` at it.
        ramp = np.clip((self.clearance - self.pass_m) / soft_m, 0.0, 1.0) ** power
        self.speed: F64 = slow_factor + (1.0 - slow_factor) * ramp
        # The outline is sampled at two spacings. At 0.15 m alone a thin obstacle (a 4 cm pole,
        # a table leg) head-on between two points read 4.9 cm while it touched the front edge
        # (measured); at 0.05 m, read exactly (`_exact`), not over the truth (the bilinear
        # reading: 2.4 cm over, ~1.9 of it its corner bias, H47). Every pose is read on the
        # coarse outline (cheap: most poses are far from everything) and, where that reads
        # under `REFINE_BELOW_M`, at the points between (`outline_fine`).
        self.outline = footprint.outline(COARSE_SPACING_M)
        fine = footprint.outline(COARSE_SPACING_M, FINE_SPLIT)  # (the coarse points among them)
        self.outline_fine = fine[~(np.abs(fine[:, None] - self.outline[None]).sum(-1)
                                   < 1e-9).any(1)]  # the points between the coarse ones

    @property
    def frame_id(self) -> str:
        return self.map.frame_id

    def clearance_at(self, pts: F64) -> F64:
        """Clearance (m) at world points (..., 2); 0 outside the map. The clearance grid read
        by bilinear interpolation, and where that reads under `EXACT_BELOW_M` the exact
        distance to the nearest occupied cell's square (`_exact`)."""
        return self.clearance_xy(pts[..., 0], pts[..., 1])

    def clearance_xy(self, x: F64, y: F64) -> F64:
        """`clearance_at` for points given as separate x and y arrays (...)."""
        v, i, ax, ay = _sample_at(self.clearance, *_cell_xy(self.map, x, y), 0.0)
        return self._exactly(np.array(v, dtype=np.float64), i, np.asarray(ax), np.asarray(ay))

    def signed_xy(self, x: F64, y: F64) -> F64:
        """`clearance_xy`, and where that reads 0 (at or inside an occupied cell's square)
        minus the depth: the exact distance to the nearest free cell's square (`_inside`,
        within its EXACT_BELOW_M);
        off the map −1e3. Unsigned, moving deeper into an obstacle cannot be told from
        moving out of it (H57). Where the clearance reads > 0, these are its numbers."""
        v = self.clearance_xy(x, y)
        at = v <= 0.0
        if at.any():
            inner = self._inside
            d, i, ax, ay = _sample_at(inner.clearance, *_cell_xy(inner.map, x[at], y[at]), 1e3)
            d = np.array(d, dtype=np.float64)
            if inner._corner is not None:
                # (the exact reading, not the least of it and the bilinear one, which reads
                # under it between two faces: shallower, in the middle of a thick wall)
                sel = (d < inner.exact_below_m) & inner._corner.take(i)
                d[sel] = inner._exact(i[sel], ax[sel], ay[sel])
            v[at] = -d
        return v

    @cached_property
    def _inside(self) -> NavField:
        """The field whose obstacles are the free cells next to the map's (its clearance, in
        an occupied square: the depth, the distance to the nearest free one, which always
        borders an occupied cell); built when first read (a chair the map shows within a
        margin: rare). (All the free cells: 4–5 times the field's own build, 110 ms against
        25 on nav_eval's world; these: ~25, the same readings in the occupied squares.)"""
        gm = self.map
        edge = ~gm.occupied & ndi.binary_dilation(gm.occupied, np.ones((3, 3), dtype=np.bool_))
        return NavField(GridMap(edge, gm.resolution_m, gm.origin_x_m, gm.origin_y_m,
                                gm.frame_id), self.footprint)

    def contact(self, x: float, y: float, yaw: float, slack: float) -> Contact:
        """The chair at the pose as `keeps` compares other poses with: its outline's points
        (the coarse and the fine, chair frame) and their signed clearance; the occupied cells
        its body overlaps (their squares reach in, by `body_depth`) and how deep the deepest."""
        pts = np.concatenate([self.outline, self.outline_fine])
        now = self.signed_xy(*place_xy(pts, x, y, yaw))
        iy, ix = self.cells_under(x, y, yaw, grow=self.map.resolution_m)
        occ = self.map.occupied[iy, ix]
        cells = np.stack(self.map.centre(ix[occ], iy[occ]), -1)
        depth = self.body_depth(cells, np.array(x), np.array(y), np.array(yaw))
        return Contact(pts, now, cells[depth > 0.0], float(depth.max(initial=0.0)), slack)

    def body_depth(self, cells: F64, x: F64, y: F64, yaw: F64) -> F64:
        """(..., K): how far the squares of cells (K, 2) (world centres) reach into the body
        at poses (...) (the centre's depth inside the rectangle plus half a cell; ≤ 0: not
        in it). The outline's points alone cannot see an obstacle the body passes over: a
        thin one, a cell thick, the front edge in its middle, reads shallower whichever way
        the edge moves, so driving on through it looked like getting out."""
        fp = self.footprint
        dx, dy = cells[:, 0] - x[..., None], cells[:, 1] - y[..., None]
        c, s = np.cos(yaw)[..., None], np.sin(yaw)[..., None]
        u, w = c * dx + s * dy, np.abs(c * dy - s * dx)
        inside = np.minimum(np.minimum(u + fp.rear_m, fp.front_m - u), fp.half_width_m - w)
        return np.asarray(inside + self.map.resolution_m / 2, dtype=np.float64)

    def keeps(self, c: Contact, x: F64, y: F64, yaw: F64, margin: float,
              far: npt.NDArray[np.bool_] | None = None) -> npt.NDArray[np.bool_]:
        """Per pose (...): no point of the outline reads under min(`margin`, its own reading
        at `c` − slack), and no cell the body overlapped at `c` reaches into it deeper than
        the deepest did but by the slack: nothing deeper in, nothing else nearer than the
        margin (the footprint's least reading alone let a turn keep the deepest point where
        it was and sweep another part of the body into another obstacle). (Per cell, a
        corner sliding along a wall at the same depth was deeper into the next cell.) A cell
        the body did not overlap can come in only past the outline's points, which read it.
        `far`: poses known to read over `margin` everywhere on the outline (not read)."""
        shape = np.broadcast_shapes(np.shape(x), np.shape(y), np.shape(yaw))
        xs, ys, yaws = (np.broadcast_to(np.asarray(a, dtype=np.float64), shape).reshape(-1)
                        for a in (x, y, yaw))
        under = np.minimum(margin, c.now - c.slack)
        ok = np.ones(xs.size, dtype=np.bool_)
        near = np.arange(xs.size) if far is None else np.flatnonzero(~far.reshape(-1))
        step = max(1, BATCH_POINTS // len(c.outline))
        for i in range(0, near.size, step):
            b = near[i:i + step]
            ok[b] = (self.signed_xy(*place_xy(c.outline, xs[b], ys[b], yaws[b])) >= under).all(-1)
        if c.cells.size:
            ok &= (self.body_depth(c.cells, xs, ys, yaws) <= c.deepest + c.slack).all(-1)
        return ok.reshape(shape)

    def _exactly(self, v: F64, i: npt.NDArray[np.intp], ax: F64, ay: F64) -> F64:
        """Bilinear readings `v` (_sample_at: with the points' cells and fractions) lowered to
        `_exact` where they read under `EXACT_BELOW_M` and can be over it (`_corner_cells`),
        in place. (0 is left: outside the map, or amid four occupied cells, where the exact
        distance is 0 too.)"""
        if self._corner is not None:
            sel = (v > 0.0) & (v < self.exact_below_m)
            sel &= self._corner.take(i)
            if sel.any():
                v[sel] = np.minimum(v[sel], self._exact(i[sel], ax[sel], ay[sel]))
        return v

    def _corner_cells(self) -> Bool:
        """(H·W): whether the bilinear reading between the cell centre and the next ones in
        x, y and both (the square they span) can differ from the exact one (`_exact`); only
        for the spans that read under EXACT_BELOW_M somewhere (no other is read exactly).
        It is the exact one where the four centres' nearest obstacle cells lie straight
        across from them (in their own rows, or columns), all in the same column (row),
        beyond the span: the face those cells form covers the span's rows (columns), and
        the distance to it, affine, is read exactly at the centres (the distance transform
        less half a cell)."""
        ny, nx = (a.ravel() for a in self._nearest)
        h, w = self.clearance.shape
        c = self.clearance
        span = np.full((h, w), np.inf)
        span[:-1, :-1] = np.minimum(np.minimum(c[:-1, :-1], c[:-1, 1:]),
                                    np.minimum(c[1:, :-1], c[1:, 1:]))
        cells = np.flatnonzero(span.ravel() < self.exact_below_m)
        y0, x0 = cells // w, cells % w
        nx0, ny0 = nx[cells], ny[cells]
        same_col = (nx0 < x0) | (nx0 > x0 + 1)
        same_row = (ny0 < y0) | (ny0 > y0 + 1)
        for oy in (0, 1):
            for ox in (0, 1):
                q = cells + (oy * w + ox)
                same_col &= (nx[q] == nx0) & (ny[q] == y0 + oy)
                same_row &= (ny[q] == ny0) & (nx[q] == x0 + ox)
        corner = np.zeros(h * w, dtype=np.bool_)
        corner[cells] = ~(same_col | same_row)
        return corner

    def _candidates(self) -> tuple[F64, F64, Bool, npt.NDArray[np.intp]]:
        """For the corner cells (`_corner_cells`) whose span reads under EXACT_BELOW_M
        somewhere (the only ones read exactly; all cells of a 400 × 1000 map took 0.35 s),
        as the lower left cell centre of a point: the distinct obstacle cells nearest to the
        cell centres of EXACT_BLOCK round it, as their centres' offsets (cells) from it in x
        and y, (SLOTS, n + 1) each (unused slots, and column 0, far); whether there are more
        than SLOTS (then all are read); and each cell's column (H·W; 0: none)."""
        ny, nx = self._nearest
        h, w = ny.shape
        assert self._corner is not None
        cells = np.flatnonzero(self._corner)
        big = h * w  # (beyond any cell: off the map, or a slot left empty)
        flat = np.pad(ny * w + nx, 2, constant_values=big).ravel()
        y0, x0 = cells // w, cells % w
        base = (y0 + 2) * (w + 4) + x0 + 2
        cand = np.stack([flat[base + (dy * (w + 4) + dx)] for dx, dy in EXACT_BLOCK], -1)
        cand.sort(-1)
        cand[:, 1:][cand[:, 1:] == cand[:, :-1]] = big  # duplicates
        cand.sort(-1)
        n = cells.size
        many = np.zeros(n + 1, dtype=np.bool_)
        if cand.shape[1] > SLOTS:
            many[1:] = cand[:, SLOTS] < big
        ox, oy = np.full((SLOTS, n + 1), 1e3), np.full((SLOTS, n + 1), 1e3)
        for k in range(min(SLOTS, cand.shape[1])):
            ck = cand[:, k]
            real = np.flatnonzero(ck < big)
            ox[k, real + 1] = (ck[real] % w - x0[real]).astype(np.float64)
            oy[k, real + 1] = (ck[real] // w - y0[real]).astype(np.float64)
        row = np.zeros(h * w, dtype=np.intp)
        row[cells] = np.arange(1, n + 1)
        return ox, oy, many, row

    def _exact(self, i: npt.NDArray[np.intp], ax: F64, ay: F64) -> F64:
        """The exact distance (m) from points, each `ax`, `ay` cells past the cell centre of
        flat index `i`, to the nearest occupied cell's square: the least over the obstacle
        cells (the distance transform's indices) nearest to the 4 × 4 cell centres round the
        point but the block's corners (`_candidates`: mostly 4 or fewer distinct ones). Along
        a wall it is the bilinear reading; by a corner it reads neither the centres' diagonal
        bias (the distance from a centre to a square's corner, not to its centre less half a
        cell) nor the interpolation's overshoot of a cone (H47). The four centres round the
        point alone missed the nearest square where a centre is as near to two (a tie, common
        on a grid): up to 2.6 cm over on random clutter; these twelve were exact on 1.6 M
        points over 400 random grids (1–40 % occupied), the sixteen no better
        (tests/test_nav.py)."""
        assert self._slots is not None
        ox, oy, many, row = self._slots
        col = row.take(i)
        out = self._nearest_of(ox, oy, col, ax, ay)
        more = many.take(col)
        if more.any():  # (more distinct candidates than slots: read them all)
            j = i[more]
            w = self.map.occupied.shape[1]
            jp = j + 4 * (j // w) + 2 * (w + 4) + 2  # (in the grid padded by 2 cells)
            px, py, offs = self._block
            k = jp[None, :] + offs[:, None]
            out[more] = np.minimum(out[more], self._nearest_of(
                px.take(k) + EXACT_X[:, None], py.take(k) + EXACT_Y[:, None], None,
                ax[more], ay[more]))
        return out

    @cached_property
    def _block(self) -> tuple[F64, F64, npt.NDArray[np.intp]]:
        """Each cell centre's offset (cells) from its nearest obstacle cell's, flat, in the
        grid padded by 2 cells (far); and EXACT_BLOCK's offsets in that flat grid."""
        ny, nx = self._nearest
        h, w = ny.shape
        iy, ix = np.indices((h, w))
        ox = np.pad((nx - ix).astype(np.float64), 2, constant_values=1e3).ravel()
        oy = np.pad((ny - iy).astype(np.float64), 2, constant_values=1e3).ravel()
        offs = np.array([dy * (w + 4) + dx for dx, dy in EXACT_BLOCK], dtype=np.intp)
        return ox, oy, offs

    def _nearest_of(self, ox: F64, oy: F64, i: npt.NDArray[np.intp] | None, ax: F64,
                    ay: F64) -> F64:
        """The distance (m) from the points to the nearest of the squares whose centres are
        offset by ox[k], oy[k] (cells) from cell i's centre (i None: ox, oy per point)."""
        if i is not None:
            ox, oy = ox[:, i], oy[:, i]  # (slots, points)
        gx = ax - ox
        np.abs(gx, out=gx)
        gx -= 0.5
        np.maximum(gx, 0.0, out=gx)
        gy = ay - oy
        np.abs(gy, out=gy)
        gy -= 0.5
        np.maximum(gy, 0.0, out=gy)
        gx *= gx
        gy *= gy
        gx += gy
        best: F64 = gx.min(0)
        np.sqrt(best, out=best)
        best *= self.map.resolution_m
        return best

    def nearest_obstacle(self, x: float, y: float) -> tuple[float, float] | None:
        """Centre of the obstacle cell nearest to (x, y); None without obstacles or outside."""
        c = self.cell(x, y)
        if c is None or not self.map.occupied.any():
            return None
        cx, cy = self.map.centre(int(self._nearest[1][c]), int(self._nearest[0][c]))
        return float(cx), float(cy)

    def footprint_clearance(self, x: F64 | float, y: F64 | float, yaw: F64 | float,
                            fine: bool = True, need: float | None = None,
                            upto: float | None = None, below: float | None = None,
                            decided: float = 0.0) -> F64:
        """Least clearance of the footprint outline at poses (...) (broadcast together): on
        the coarse outline, and (`fine`) on the fine one where that reads under
        `REFINE_BELOW_M`; for a caller that compares with `need` (`_refined`), only where the
        fine one could read under `upto` (default `need`) and the coarse one does not already
        read under `need`. `below`, `decided`: on the coarse outline, read exactly only where
        the bilinear reading is under `below`, and not at poses it puts under `decided`
        (`outline_clearance`; the fine one: under EXACT_BELOW_M)."""
        shape = np.broadcast_shapes(np.shape(x), np.shape(y), np.shape(yaw))
        xs, ys, yaws = (np.broadcast_to(np.asarray(a, dtype=np.float64), shape).reshape(-1)
                        for a in (x, y, yaw))
        d = self._clearance(self.outline, xs, ys, yaws, below, decided)
        if not fine:
            return d.reshape(shape)
        return self._refined(d, xs, ys, yaws, need, upto).reshape(shape)

    def _refined(self, d: F64, x: F64, y: F64, yaw: F64, need: float | None,
                 upto: float | None) -> F64:
        """`d`, coarse outline clearances at poses (N,), with those under `REFINE_BELOW_M`
        read on the fine outline (in place). Past it the coarse reading cannot hide a fine one
        under 0.066 m, more than any margin checked (0.02–0.05): read exactly (`_exact`), an
        obstacle at c from a point between two coarse points s = COARSE_SPACING_M apart is at
        most √(c² + (s/2)²) from the nearer of them (the nearest an obstacle can come to the
        point between, outside both discs of radius d round them, is √(d² − (s/2)²)). With
        `need`, only readings from `need` to that bound for c = `upto` (5 mm more): a coarse
        reading under `need` decides alone, one past the bound keeps the fine one at `upto`
        or more (the planner's committed sweeps, read under 0.10 m alike, took 35 % more time
        at its p95)."""
        lo, hi = self._refine_range(need, upto)
        near = (d >= lo) & (d < hi)
        if near.any():
            d[near] = np.minimum(d[near], self._clearance(self.outline_fine, x[near], y[near],
                                                          yaw[near]))
        return d

    def reading_floor(self, d: F64, need: float | None = None, upto: float | None = None
                      ) -> F64:
        """A lower bound of the fine outline's clearance at poses that
        footprint_clearance(..., need=need, upto=upto) read as `d`: `d` where it was read on
        the fine outline, else the least the fine one can be beside that coarse reading (the
        bound of `_refined`, inverted). A pose's least reading is exact only under
        EXACT_BELOW_M − BILINEAR_OVER_M: its points read EXACT_BELOW_M or more are read
        bilinear, at most BILINEAR_OVER_M over the exact distance, so under the least `d`
        read exactly at another point one of them can be (a reading of 0.138 m at 0.05 m cells
        was 0.130 in truth on the coarse outline and its floor 2.4 mm over the fine one's)."""
        lo, hi = self._refine_range(need, upto)
        exact = np.minimum(d, np.maximum(d, self.exact_below_m) - self.bilinear_over_m)
        coarse = np.sqrt(np.maximum(exact ** 2 - (COARSE_SPACING_M / 2) ** 2, 0.0))
        return np.asarray(np.where((d >= lo) & (d < hi), exact, coarse), dtype=np.float64)

    def _refine_range(self, need: float | None, upto: float | None) -> tuple[float, float]:
        """The coarse readings `_refined` reads on the fine outline too: [lo, hi)."""
        if need is None:
            return -math.inf, REFINE_BELOW_M
        hi = math.hypot(need if upto is None else upto, COARSE_SPACING_M / 2) + 0.005
        # (a coarse reading past EXACT_BELOW_M is the bilinear one: up to BILINEAR_OVER_M over)
        over = self.bilinear_over_m
        return need, hi + over if hi + over > self.exact_below_m else hi

    def _clearance(self, outline: F64, xs: F64, ys: F64, yaws: F64,
                   below: float | None = None, decided: float = 0.0) -> F64:
        """Least clearance of `outline` at poses (N,), in batches of about BATCH_POINTS
        outline points (the same numbers)."""
        out = np.empty(len(xs))
        step = max(1, BATCH_POINTS // len(outline))
        for i in range(0, len(xs), step):
            b = slice(i, i + step)
            out[b] = self.outline_clearance(*place_xy(outline, xs[b], ys[b], yaws[b]), below,
                                            decided)
        return out

    def outline_clearance(self, px: F64, py: F64, below: float | None = None,
                          decided: float = 0.0) -> F64:
        """clearance_xy(px, py).min(-1) (the same numbers) of world points (..., P) that
        are the caller's scratch: overwritten. The exact reading only for the poses whose
        bilinear one reads under `EXACT_BELOW_M` somewhere (most are far from everything),
        and of those only at the points that could lower the least (on a doorway's recorded
        plan cycles, reading every point under EXACT_BELOW_M took the planner ~30 % more
        time; measured). With `below`, only where the bilinear reading is under that (a caller that
        decides at a lower margin: the prediction's contact_m, Mpepc.outline_distances); and
        not at poses whose bilinear least is under `decided` (read so they are under it
        anyway: the prediction's poses that are hits whatever the exact reading)."""
        gm = self.map
        px -= gm.origin_x_m  # (x − origin) / resolution − 0.5, as bilinear_xy
        px /= gm.resolution_m
        px -= 0.5
        py -= gm.origin_y_m
        py /= gm.resolution_m
        py -= 0.5
        v, i, ax, ay = _sample_at(self.clearance, px, py, 0.0, self._corners)
        m = np.asarray(v.min(-1))
        if self._corner is None:
            return m
        below = self.exact_below_m if below is None else min(below, self.exact_below_m)
        mf = m.reshape(-1)  # (a view: the poses' readings, lowered in place)
        if not mf.size or mf.min() >= below:
            return m
        decided = max(decided, 0.0)
        # The points that could read under their pose's bilinear least: within half a cell of
        # it (the bilinear reading is at most that over the exact one), under `below`, and
        # not on a pose already at 0 (inside an obstacle or off the map) or under `decided`.
        n = v.shape[-1]
        thr = np.minimum(mf + self.map.resolution_m / 2, below)
        thr[(mf <= 0.0) | (mf < decided)] = 0.0
        k = np.flatnonzero(v.reshape(-1, n) < thr[:, None])  # (flat point indices)
        ik = i.reshape(-1)[k]
        at = self._corner.take(ik)
        if at.any():
            k, ik = k[at], ik[at]
            np.minimum.at(mf, k // n, self._exact(ik, ax.reshape(-1)[k], ay.reshape(-1)[k]))
        return m

    @cached_property
    def _corners(self) -> tuple[F64, F64, F64, F64]:
        """The clearance grid flat, and shifted by one cell in x, y and both (_sample)."""
        h, w = self.clearance.shape
        flat = self.clearance.ravel()
        pad = np.concatenate([flat, np.zeros(w + 1)])
        return flat, pad[1:1 + h * w], pad[w:w + h * w], pad[w + 1:w + 1 + h * w]

    def straight_clearance(self, pose: tuple[float, float, float], ds: F64) -> float:
        """Least clearance of the footprint driven straight ahead from `pose` (no steering),
        sampled at the distances `ds` along its heading."""
        x, y, yaw = pose
        return float(self.footprint_clearance(x + ds * math.cos(yaw), y + ds * math.sin(yaw),
                                              np.full(ds.size, yaw)).min())

    def turn_clearance(self, pose: tuple[float, float, float], angle_rad: float) -> float:
        """Least clearance of the footprint turned in place from `pose` through `angle_rad`
        (Footprint.turn_samples: the far corners at most 5 cm apart)."""
        x, y, yaw = pose
        n = self.footprint.turn_samples(angle_rad)
        return float(self.footprint_clearance(np.full(n, x), np.full(n, y),
                                              yaw + np.linspace(0.0, angle_rad, n)).min())

    def cell(self, x: float, y: float) -> tuple[int, int] | None:
        gm = self.map
        ix = math.floor((x - gm.origin_x_m) / gm.resolution_m)
        iy = math.floor((y - gm.origin_y_m) / gm.resolution_m)
        h, w = gm.occupied.shape
        return (iy, ix) if 0 <= ix < w and 0 <= iy < h else None

    def cost_to_go(self, gx: float, gy: float, outside_slope: float = 3.0,
                   closed: Bool | None = None) -> CostToGo | None:
        """Fast-marching costs-to-go to (gx, gy); None if the goal point is not passable.
        `closed`: cells (H, W) given up besides the obstacles (planner.compute: those the
        chair cannot get to from where it stands)."""
        passable = self.passable if closed is None else self.passable & ~closed
        c = self.cell(gx, gy)
        if c is None or not passable[c]:
            return None
        res = self.map.resolution_m
        phi0 = np.ones(passable.shape)
        phi0[c] = -1.0  # the zero contour surrounds the goal cell
        t = gil.run(skfmm.travel_time, np.ma.MaskedArray(phi0, ~passable), self.speed, dx=res)
        reach = ~np.ma.getmaskarray(t) & passable
        phi = np.where(reach, np.ma.getdata(t), np.inf)
        phi[c] = 0.0
        # Extend into walls and unreachable cells: the nearest reachable cell's cost plus
        # the distance from it, steeply, so "closer to a wall" is never cheaper.
        dist, (iy, ix) = ndi.distance_transform_edt(~reach, return_indices=True)
        ext = phi[iy, ix] + outside_slope * dist * res
        full = np.where(reach, phi, ext)
        gy_, gx_ = np.gradient(full, res)
        return CostToGo(full, gx_, gy_, reach, (gx, gy))

    def cells_of(self, marked: GridMap) -> Bool:
        """This map's cells whose centres fall in a marked cell of another grid (over the same
        world frame; a grid kept from an earlier map, which the live map outgrows)."""
        cx, cy = self.map.centres()
        h, w = marked.occupied.shape
        ix = np.floor((cx - marked.origin_x_m) / marked.resolution_m).astype(np.intp)
        iy = np.floor((cy - marked.origin_y_m) / marked.resolution_m).astype(np.intp)
        ok = (ix >= 0) & (ix < w) & (iy >= 0) & (iy < h)
        out = np.zeros(ok.shape, dtype=np.bool_)
        out[ok] = marked.occupied[iy[ok], ix[ok]]
        return out

    def check_goal(self, x: float, y: float, yaw: float, min_clearance_m: float = 0.02) -> str:
        """'' if the chair fits at the pose, else why not (names the pose and the obstacle)."""
        if self.cell(x, y) is None:
            return f"({x:.2f}, {y:.2f}) is outside the map"
        clr = float(self.footprint_clearance(x, y, yaw))
        where = f"the chair's footprint at ({x:.2f}, {y:.2f}, {math.degrees(yaw):.0f}°)"
        if self.map.occupied[self.cells_under(x, y, yaw)].any():
            return f"{where} overlaps an obstacle"
        if clr < min_clearance_m:
            return (f"{where} comes within {max(clr, 0.0):.2f} m of an obstacle (needs "
                    f"{min_clearance_m:.2f} m: the position tolerance and a margin)")
        if float(self.clearance_at(np.array([x, y]))) < self.pass_m:
            return (f"({x:.2f}, {y:.2f}) is closer than {self.pass_m:.2f} m to an obstacle: "
                    "the chair cannot get there")
        return ""

    def cells_under(self, x: float, y: float, yaw: float, grow: float = 0.0
                    ) -> tuple[npt.NDArray[np.intp], ...]:
        """Indices of the grid cells whose centres lie under the footprint at the pose (grown
        by `grow` on every side)."""
        fp, gm = self.footprint, self.map
        if grow:
            fp = Footprint(fp.front_m + grow, fp.rear_m + grow, fp.half_width_m + grow)
        reach = math.hypot(max(fp.front_m, fp.rear_m), fp.half_width_m) + gm.resolution_m
        c0 = self.cell(x - reach, y - reach) or (0, 0)
        h, w = gm.occupied.shape
        c1 = self.cell(x + reach, y + reach) or (h - 1, w - 1)
        iy, ix = np.mgrid[c0[0]:c1[0] + 1, c0[1]:c1[1] + 1]
        cx, cy = gm.centre(ix, iy)
        px, py = cx - x, cy - y
        c, s = math.cos(yaw), math.sin(yaw)
        inside = fp.contains(np.stack([c * px + s * py, -s * px + c * py], -1))
        return iy[inside], ix[inside]

    def descent_path(self, ctg: CostToGo, x: float, y: float, step_m: float = 0.05,
                     max_m: float = 80.0) -> F64:
        """(N, 2) points down −∇φ from (x, y) to the goal (the path the field implies)."""
        pts = [(x, y)]
        gx, gy = ctg.goal_xy
        for _ in range(int(max_m / step_m)):
            if math.hypot(gx - x, gy - y) < 2 * step_m:
                break
            heading = ctg.descent_xy(self.map, x, y)
            x, y = x + step_m * math.cos(heading), y + step_m * math.sin(heading)
            pts.append((x, y))
        pts.append((gx, gy))
        return np.array(pts)

    def door_approaches(self, ctg: CostToGo, x: float, y: float, narrow_m: float = NARROW_M,
                        back_m: float = LINE_UP_M, clear_m: float = 0.05, stand_m: float = 0.1
                        ) -> list[tuple[float, float, float]]:
        """Poses to line up at before each narrow passage (a door) on the way from (x, y):
        `back_m` before its narrowest point, facing along the passage, the chair `stand_m`
        clear there (a line-up is passed anywhere within 0.2 m of it: the doors' measured 0.19
        to 0.56 m), from which the straight through it keeps `clear_m`. The field is for the
        axle, which cuts a door's corner; the chair's front, 0.95 m ahead of it, cannot follow
        (forward only, it can neither turn in place under the door nor curve in), so it lines
        up first, as a wheelchair user does.
        (On the laser's map the cluttered room's gaps read as passages: a chair sent to line up
        in one, 3 cm from a table, was blocked there.)"""
        path = self.descent_path(ctg, x, y)
        out: list[tuple[float, float, float]] = []
        for j, k in passages(self.clearance_at(path), narrow_m):
            yaw = heading_through(path, k)
            px = float(path[k, 0]) - back_m * math.cos(yaw)
            py = float(path[k, 1]) - back_m * math.sin(yaw)
            at = walked_to(path, k)
            through = back_m + walked_to(path, min(j, len(path) - 1)) - at + 0.2
            if at > back_m + 0.3 \
                    and self.check_goal(px, py, yaw, min_clearance_m=stand_m) == "" \
                    and math.hypot(ctg.goal_xy[0] - path[k, 0],
                                   ctg.goal_xy[1] - path[k, 1]) > 0.3 \
                    and self.straight_clearance((px, py, yaw),
                                                np.arange(0.0, through, 0.05)) >= clear_m:
                out.append((px, py, yaw))
        return out

    def passage_ahead(self, ctg: CostToGo, x: float, y: float, within_m: float,
                      narrow_m: float = NARROW_M) -> tuple[F64, int, int] | None:
        """The first narrow passage (a door: the axle's clearance under `narrow_m`, as
        `door_approaches`) on the way from (x, y) whose narrowest point lies within `within_m`
        along it: the way's points (N, 2) up to the passage's end, the narrowest point's index
        and the end's (the first point past it with `narrow_m` again); None: none that near."""
        path = self.descent_path(ctg, x, y, max_m=within_m + 2.0)
        j, k = next(passages(self.clearance_at(path), narrow_m), (len(path), 0))
        if j == len(path):  # (none, or the way ends in it or runs on beyond what was searched)
            return None
        return (path[:j + 1], k, j) if walked_to(path, k) <= within_m else None

    def in_passage(self, pose: tuple[float, float, float], narrow_m: float = NARROW_M) -> bool:
        """Whether the chair's body at `pose` stands in a narrow passage (a door): at some
        point of its centre line, from the rear to the front, obstacles (or the map's edge) lie
        within `narrow_m` on both sides across it, as `passage_ahead`'s clearance under
        `narrow_m` reads a door, whichever way the way runs (H75: a walker's trail in the live
        map can close a door's exit, and the way from a chair standing in it then turns back:
        no passage lies ahead of it). Read every half cell, each point within half a cell of
        an obstacle (on the laser's map a jamb is a cell thick: read by cells alone, a line 5°
        off the door's axis passed it), the two sides up to a quarter of `narrow_m` apart
        along the body (lines across a chair standing askew in a door meet the two jambs of a
        thin wall at different points of it: ±14° at 0.6 m)."""
        x, y, yaw = pose
        fp, half = self.footprint, self.map.resolution_m / 2
        c, s = math.cos(yaw), math.sin(yaw)
        along = np.arange(-fp.rear_m, fp.front_m + 1e-9, half)
        across = np.arange(half, narrow_m + 1e-9, half)
        window = 2 * math.ceil(narrow_m / 4 / half) + 1
        walled = np.ones(along.size, dtype=np.bool_)
        for side in (1.0, -1.0):
            px = x + along[:, None] * c - side * across[None, :] * s
            py = y + along[:, None] * s + side * across[None, :] * c
            walled &= ndi.maximum_filter1d((self.clearance_xy(px, py) <= half).any(1),
                                           window, mode="constant")
        return bool(walled.any())

    def start_cost(self, ctg: CostToGo, x: float, y: float, search_m: float = 0.3) -> float:
        """Cost-to-go from the chair at (x, y): φ there if the axle stands on a reachable
        cell, else the least φ + distance over reachable cells within `search_m` (the chair may
        stand a little closer to a wall than the pass bound); inf if there is none."""
        c = self.cell(x, y)
        if c is None:
            return math.inf
        if ctg.reachable[c]:
            return float(ctg.at(self.map, np.array([x, y])))
        gm = self.map
        r = math.ceil(search_m / gm.resolution_m)
        iy0, ix0 = max(c[0] - r, 0), max(c[1] - r, 0)
        win = ctg.reachable[iy0:c[0] + r + 1, ix0:c[1] + r + 1]
        if not win.any():
            return math.inf
        iy, ix = np.nonzero(win)
        cx, cy = gm.centre(ix + ix0, iy + iy0)
        phi = ctg.phi[iy + iy0, ix + ix0] + np.hypot(cx - x, cy - y)
        return float(phi.min())
