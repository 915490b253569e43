"""Scan-to-map registration, pure numpy/scipy: a distance field of the map's occupied cells,
Gauss-Newton refinement of a pose on it, and a brute-force (correlative) search for when the
pose is unknown or lost.

Poses are (x, y, yaw) arrays of the chair in the map frame; scan points are (N, 2) in the chair
frame (the laser mount already applied).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy import ndimage

F64 = npt.NDArray[np.float64]
BoolGrid = npt.NDArray[np.bool_]


def transform(pose: F64, pts: F64) -> F64:
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.column_stack((pose[0] + c * pts[:, 0] - s * pts[:, 1],
                            pose[1] + s * pts[:, 0] + c * pts[:, 1]))


def rotate(yaw: float, vecs: F64) -> F64:
    """(N, 2) vectors turned by `yaw`."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.column_stack((c * vecs[:, 0] - s * vecs[:, 1], s * vecs[:, 0] + c * vecs[:, 1]))


def compose(a: F64, b: F64) -> F64:
    """a ∘ b: pose b, given in a's frame, in a's parent frame."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1],
                     math.atan2(math.sin(a[2] + b[2]), math.cos(a[2] + b[2]))])


def inverse(a: F64) -> F64:
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([-c * a[0] - s * a[1], s * a[0] - c * a[1], -a[2]])


def between(a: F64, b: F64) -> F64:
    """b in a's frame: a⁻¹ ∘ b."""
    return compose(inverse(a), b)


@dataclass(frozen=True)
class GridFrame:
    resolution_m: float
    origin_x_m: float  # map position of cell (0, 0)'s corner
    origin_y_m: float


class DistanceField:
    """Distance (m) from every cell centre to the nearest occupied cell, clipped at
    `max_dist_m`; sampled bilinearly with its gradient. Beyond the grid: max_dist_m."""

    def __init__(self, occupied: BoolGrid, frame: GridFrame, max_dist_m: float = 0.5) -> None:
        self.frame, self.max_dist_m = frame, max_dist_m
        self.res = frame.resolution_m
        self.h, self.w = occupied.shape
        if occupied.any():
            d = ndimage.distance_transform_edt(~occupied) * self.res
        else:
            d = np.full(occupied.shape, max_dist_m)
        self.dist = np.minimum(np.asarray(d, dtype=np.float64), max_dist_m)
        self.occupied = occupied

    def sample(self, pts: F64) -> tuple[F64, F64, F64]:
        """Distance and its x, y gradient at (N, 2) map points."""
        fx = (pts[:, 0] - self.frame.origin_x_m) / self.res - 0.5
        fy = (pts[:, 1] - self.frame.origin_y_m) / self.res - 0.5
        ix, iy = np.floor(fx).astype(np.int64), np.floor(fy).astype(np.int64)
        inside = (ix >= 0) & (iy >= 0) & (ix < self.w - 1) & (iy < self.h - 1)
        ix, iy = np.where(inside, ix, 0), np.where(inside, iy, 0)
        ax, ay = fx - ix, fy - iy
        g = self.dist
        d00, d10, d01, d11 = g[iy, ix], g[iy, ix + 1], g[iy + 1, ix], g[iy + 1, ix + 1]
        d = (d00 * (1 - ax) + d10 * ax) * (1 - ay) + (d01 * (1 - ax) + d11 * ax) * ay
        gx = ((d10 - d00) * (1 - ay) + (d11 - d01) * ay) / self.res
        gy = ((d01 - d00) * (1 - ax) + (d11 - d10) * ax) / self.res
        far = self.max_dist_m
        return np.where(inside, d, far), np.where(inside, gx, 0.0), np.where(inside, gy, 0.0)


def scan_normals(pts: F64, spans: tuple[int, ...] = (2, 4, 8, 16), min_chord_m: float = 0.15,
                 max_gap_m: float = 0.25, max_bend_m: float = 0.025) -> F64:
    """Unit normals (N, 2) of points in scan order, from the chord between the ±span-th
    neighbours, with the smallest span whose chord is ≥ `min_chord_m` (1 cm range noise on a
    shorter chord turns it by degrees); NaN where no such chord has the point on it (a gap, a
    corner, an edge). Neighbours in the scan, not in space: a wall seen at a grazing angle has
    its points 10–15 cm apart, too sparse for a normal from a spatial neighbourhood."""
    n = len(pts)
    out = np.full((n, 2), np.nan)
    done = np.zeros(n, dtype=np.bool_)
    gap = np.hypot(*np.diff(pts, axis=0).T) if n > 1 else np.zeros(0)
    for span in spans:
        if n < 2 * span + 1:
            break
        # window k spans the gaps between points k … k + 2·span: centre k + span
        ok_gap = np.lib.stride_tricks.sliding_window_view(gap, 2 * span).max(axis=1) <= max_gap_m
        i = np.arange(span, n - span)
        a, d = pts[i - span], pts[i + span] - pts[i - span]
        length = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)
        nrm = np.column_stack((-d[:, 1], d[:, 0])) / length[:, None]
        bend = np.abs(np.sum((pts[i] - a) * nrm, axis=1))
        ready = ~done[i] & (length >= min_chord_m)
        good = ready & ok_gap & (bend <= max_bend_m)
        out[i[good]] = nrm[good]
        done[i[ready]] = True  # the first long-enough chord decides: longer ones cross corners
    return out


def _cell_sums(inv: npt.NDArray[np.int64], k: int, cols: tuple[F64, ...]) -> F64:
    """Sums of each of `cols` per cell (`inv`: the cell number of every point)."""
    return np.column_stack([np.bincount(inv, v, k) for v in cols]).astype(np.float64)


def _box_sums(cells: npt.NDArray[np.int64], w: int, own: F64, r: int = 1) -> F64:
    """Per occupied cell (`cells`: sorted flat indices), the sums of `own` rows over the
    (2r+1)² cells round it."""
    k = cells.size
    out = np.zeros_like(own)
    if not k:
        return out
    cy, cx = cells // w, cells % w
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            nb = (cy + dy) * w + cx + dx
            pos = np.minimum(np.searchsorted(cells, nb), k - 1)
            hit = (cx + dx >= 0) & (cx + dx < w) & (cells[pos] == nb)
            out[hit] += own[pos[hit]]
    return out


class LineField(DistanceField):
    """A distance field of points whose `sample` is sub-cell: the distance from a query point
    to the local line through the map points nearest to it (point-to-line; point-to-point at
    corners and where no normal is known). Each occupied cell holds the centroid of the points
    in its 3 × 3 neighbourhood and the mean direction of their normals (`scan_normals`,
    structure tensor); the EDT's nearest-cell index finds the cell for a query.

    Why: `DistanceField` is zero at occupied cell *centres*, so a wall is located only to its
    cell (±2.5 cm at 5 cm), with a flat band where it spreads over two cells, and its gradient
    along a wall is quantisation noise, read as information along a corridor. Measured on
    scans at known poses in the loop world (15-scan submaps): across-corridor error std
    1.0 → 0.16 cm, yaw 0.22° → 0.03°. `dist` (for the correlative search) is unchanged."""

    def __init__(self, world_pts: F64, normals: F64, frame: GridFrame,
                 shape: tuple[int, int], max_dist_m: float = 0.5, line_ratio: float = 0.2
                 ) -> None:
        res, (h, w) = frame.resolution_m, shape
        lx, ly = world_pts[:, 0] - frame.origin_x_m, world_pts[:, 1] - frame.origin_y_m
        ix, iy = (lx / res).astype(np.int64), (ly / res).astype(np.int64)
        keep = (ix >= 0) & (iy >= 0) & (ix < w) & (iy < h)
        lx, ly = lx[keep], ly[keep]
        cells, inv = np.unique(iy[keep] * w + ix[keep], return_inverse=True)
        occ = np.zeros((h, w), dtype=np.bool_)
        occ.ravel()[cells] = True
        self.frame, self.max_dist_m, self.res, self.h, self.w = frame, max_dist_m, res, h, w
        self.occupied = occ
        if cells.size:  # one feature transform: the distances and the nearest cells
            d, (near_y, near_x) = ndimage.distance_transform_edt(~occ, return_indices=True)
        else:
            d, near_y, near_x = np.full((h, w), np.inf), np.zeros((h, w), np.int32), \
                np.zeros((h, w), np.int32)
        self.dist = np.minimum(np.asarray(d, dtype=np.float64) * res, max_dist_m)
        # Sums per occupied cell, then over its 3 × 3 neighbourhood (sparse: the grid of a
        # long-range scanner is mostly empty, a dense convolution cost 0.1 s a submap).
        k = cells.size
        nn = normals[keep]
        has = np.isfinite(nn[:, 0])
        nx, ny = np.where(has, nn[:, 0], 0.0), np.where(has, nn[:, 1], 0.0)
        mom = _box_sums(cells, w, _cell_sums(inv, k, (np.ones_like(lx), lx, ly, has * 1.0,
                                                      nx * nx, nx * ny, ny * ny)))
        cnt, nk = np.maximum(mom[:, 0], 1.0), np.maximum(mom[:, 3], 1.0)
        self._cx, self._cy = mom[:, 1] / cnt, mom[:, 2] / cnt
        txx, txy, tyy = mom[:, 4] / nk, mom[:, 5] / nk, mom[:, 6] / nk
        th = 0.5 * np.arctan2(2 * txy, txx - tyy)  # direction of the mean normal (tensor)
        half, dev = 0.5 * (txx + tyy), np.hypot(0.5 * (txx - tyy), txy)
        self._nrm_x, self._nrm_y = np.cos(th), np.sin(th)
        # Points without a normal (the sparse ends of what a scan saw, gaps) say where
        # something is, not which way it faces: snapping onto them drags the chair along a
        # corridor past the ends of the submap's walls. They count for the fit, not the pose.
        self._pull = mom[:, 3] >= 1
        self._line = self._pull & (half - dev <= line_ratio * (half + dev))  # else a corner
        lut = np.zeros(h * w, dtype=np.int64)  # flat cell → occupied cell number
        lut[cells] = np.arange(k)
        # Per cell, the occupied cell nearest to it (its number) and whether it is near enough
        # to count: looked up once per query point, not composed from the EDT's indices there.
        self._nearest = lut[near_y.astype(np.int64) * w + near_x]
        self._near = self.dist < max_dist_m * 0.9

    def sample(self, pts: F64) -> tuple[F64, F64, F64]:
        fr = self.frame
        lx, ly = pts[:, 0] - fr.origin_x_m, pts[:, 1] - fr.origin_y_m
        ix, iy = np.floor(lx / self.res).astype(np.int64), np.floor(ly / self.res).astype(np.int64)
        inside = (ix >= 0) & (iy >= 0) & (ix < self.w) & (iy < self.h)
        ix, iy = np.where(inside, ix, 0), np.where(inside, iy, 0)
        ok = inside & self._near[iy, ix]
        far = self.max_dist_m
        if not self._line.size:
            return np.full(len(pts), far), np.zeros(len(pts)), np.zeros(len(pts))
        c = self._nearest[iy, ix]
        rx, ry = lx - self._cx[c], ly - self._cy[c]
        nx, ny = self._nrm_x[c], self._nrm_y[c]
        signed = nx * rx + ny * ry
        dp = np.hypot(rx, ry)
        line = self._line[c]
        d = np.where(line, np.abs(signed), dp)
        sgn = np.where(signed >= 0, 1.0, -1.0)
        safe = np.maximum(dp, 1e-9)
        gx = np.where(line, sgn * nx, rx / safe)
        gy = np.where(line, sgn * ny, ry / safe)
        pull = ok & self._pull[c]
        return np.where(ok, d, far), np.where(pull, gx, 0.0), np.where(pull, gy, 0.0)


def _clip(v: float, limit: float) -> float:
    """np.clip(v, −limit, limit) of a scalar, without numpy's per-call cost."""
    return min(max(v, -limit), limit)


@dataclass(frozen=True)
class Match:
    pose: F64
    information: F64  # (3, 3) JᵀJ/σ² of the final step: inverse covariance
    inliers: float  # fraction of scan points within `inlier_m` of the map: the quality
    rms_m: float  # RMS distance of the inliers
    iterations: int


def refine(field: DistanceField, pts: F64, init: F64, *, iterations: int = 12,
           inlier_m: float = 0.1, huber_m: float = 0.05, sigma_floor_m: float = 0.02,
           prior_m: float | None = None) -> Match:
    """Gauss-Newton on Σ ρ(d(T·p)) from `init`, Huber-weighted; points in the far band of the
    field (no map near) get no weight. `prior_m`: a weak pull of the position back to `init`
    (σ in m) in the steps only, not in the returned information: with a point-to-line field
    a corridor leaves the along axis (almost) singular, and unregularised steps wandered
    20–50 cm along it."""
    pose = np.array(init, dtype=np.float64)
    prior = 0.0 if prior_m is None else (sigma_floor_m / prior_m) ** 2  # in the steps' units
    prior_h, damp = np.diag([prior, prior, 0.0]), np.eye(3) * 1e-6
    px, py = pts[:, 0], pts[:, 1]
    info = np.zeros((3, 3))
    it = 0
    for it in range(1, iterations + 1):  # noqa: B007 (it is reported)
        c, s = math.cos(pose[2]), math.sin(pose[2])
        d, gx, gy = field.sample(transform(pose, pts))
        w = np.where(d < field.max_dist_m * 0.9, 1.0, 0.0)
        w *= np.where(d > huber_m, huber_m / np.maximum(d, 1e-9), 1.0)
        jt = gx * (-s * px - c * py) + gy * (c * px - s * py)
        jac = np.column_stack((gx, gy, jt))
        jw = jac * w[:, None]
        h = jw.T @ jac
        g = jw.T @ d
        info = h
        hp = h + prior_h
        gp = g + prior * np.array([pose[0] - init[0], pose[1] - init[1], 0.0])
        try:
            step = -np.linalg.solve(hp + damp * (np.trace(h) + 1e-9), gp)
        except np.linalg.LinAlgError:
            break
        # trust region: a cell-sized field is local
        step[0], step[1] = _clip(step[0], 0.2), _clip(step[1], 0.2)
        step[2] = _clip(step[2], 0.1)
        pose += step
        if abs(step[0]) + abs(step[1]) < 1e-4 and abs(step[2]) < 1e-4:
            break
    pose[2] = math.atan2(math.sin(pose[2]), math.cos(pose[2]))
    d, _, _ = field.sample(transform(pose, pts))
    near = d < inlier_m
    rms = float(np.sqrt(np.mean(d[near] ** 2))) if near.any() else inlier_m
    sigma = max(rms, sigma_floor_m)
    return Match(pose, info / sigma**2, float(near.mean()) if len(d) else 0.0, rms, it)


def search(field: DistanceField, pts: F64, centre: F64, *, half_xy_m: float, half_yaw: float,
           step_xy_m: float = 0.1, step_yaw: float = math.radians(3.0),
           inlier_m: float = 0.1, max_points: int = 80,
           free: BoolGrid | None = None) -> tuple[F64, float]:
    """Best pose (by fraction of points within `inlier_m` of the map) on a grid of poses
    around `centre`; `free` (map cells), if given, keeps candidates on known free space."""
    poses, scores = score_grid(field, pts, centre, half_xy_m=half_xy_m, half_yaw=half_yaw,
                               step_xy_m=step_xy_m, step_yaw=step_yaw, inlier_m=inlier_m,
                               max_points=max_points, free=free)
    if not scores.size:
        return np.array(centre, dtype=np.float64), -1.0
    k = int(scores.argmax())
    return poses[k].copy(), float(scores[k])


def score_grid(field: DistanceField, pts: F64, centre: F64, *, half_xy_m: float,
               half_yaw: float, step_xy_m: float, step_yaw: float, inlier_m: float,
               max_points: int = 80, free: BoolGrid | None = None) -> tuple[F64, F64]:
    """Every candidate pose of `search` (N, 3) with its score (N,): the fit landscape, for
    telling a unique fit from an ambiguous one (a corridor fits all along its length)."""
    if len(pts) > max_points:
        pts = pts[np.linspace(0, len(pts) - 1, max_points).astype(np.int64)]
    near = field.dist < inlier_m
    res, fr = field.res, field.frame
    n_xy = round(half_xy_m / step_xy_m)
    offs = np.arange(-n_xy, n_xy + 1) * step_xy_m
    xs, ys = centre[0] + offs, centre[1] + offs
    # Candidate p is (xs[col[p]], ys[row[p]]): the grid is separable, so each point's cell
    # column is computed once per x and its row once per y, not once per candidate.
    row, col = np.divmod(np.arange(xs.size * ys.size), xs.size)
    cx, cy = xs[col], ys[row]
    if free is not None:
        ix = np.floor((cx - fr.origin_x_m) / res).astype(np.int64)
        iy = np.floor((cy - fr.origin_y_m) / res).astype(np.int64)
        ok = (ix >= 0) & (iy >= 0) & (ix < field.w) & (iy < field.h)
        ok[ok] = free[iy[ok], ix[ok]]
        cx, cy, row, col = cx[ok], cy[ok], row[ok], col[ok]
    n_yaw = round(half_yaw / step_yaw)
    poses, scores = [], []
    for k in range(-n_yaw, n_yaw + 1):
        yaw = centre[2] + k * step_yaw
        c, s = math.cos(yaw), math.sin(yaw)
        rx, ry = c * pts[:, 0] - s * pts[:, 1], s * pts[:, 0] + c * pts[:, 1]
        ix = np.floor((xs[:, None] + rx[None, :] - fr.origin_x_m) / res).astype(np.int64)
        iy = np.floor((ys[:, None] + ry[None, :] - fr.origin_y_m) / res).astype(np.int64)
        in_x, in_y = (ix >= 0) & (ix < field.w), (iy >= 0) & (iy < field.h)
        hit = near[np.where(in_y, iy, 0)[row], np.where(in_x, ix, 0)[col]]
        hit &= in_y[row]
        hit &= in_x[col]
        scores.append(hit.mean(axis=1) if len(pts) else np.zeros(len(cx)))
        poses.append(np.column_stack((cx, cy, np.full(len(cx), math.atan2(s, c)))))
    return np.vstack(poses), np.concatenate(scores)


def search_wide(field: DistanceField, pts: F64, centre: F64, *, half_xy_m: float,
                half_yaw: float, free: BoolGrid | None = None, levels_step: int = 8,
                fine_xy_m: float = 0.1, fine_yaw: float = math.radians(2.0)) -> tuple[F64, float]:
    """Coarse to fine `search`: each level tries about (2·levels_step+1)² positions and
    2·levels_step+1 headings, scoring with an inlier distance of about half its step (a map
    blurred to the level's coarseness), then narrows round the best. Costs a few `search`es
    of fixed size whatever the window, so a lost chair can look metres and half turns away."""
    best, score = np.array(centre, dtype=np.float64), -1.0
    hxy, hyaw = half_xy_m, half_yaw
    while True:
        sxy, syaw = max(hxy / levels_step, fine_xy_m), max(hyaw / levels_step, fine_yaw)
        best, score = search(field, pts, best, half_xy_m=hxy, half_yaw=hyaw, step_xy_m=sxy,
                             step_yaw=syaw, inlier_m=max(0.1, 0.6 * sxy), free=free)
        if sxy <= fine_xy_m and syaw <= fine_yaw:
            return best, score
        hxy, hyaw = sxy, syaw
