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


@dataclass(frozen=True)
class Match:
    pose: F64
    information: F64  # (3, 3) JᵀJ/σ² of the final step: inverse covariance
    inliers: float  # fraction of scan points within `inlier_m` of the map: the quality
    rms_m: float  # RMS distance of the inliers
    iterations: int


def refine(field: DistanceField, pts: F64, init: F64, *, iterations: int = 12,
           inlier_m: float = 0.1, huber_m: float = 0.05, sigma_floor_m: float = 0.02) -> Match:
    """Gauss-Newton on Σ ρ(d(T·p)) from `init`, Huber-weighted; points in the far band of the
    field (no map near) get no weight."""
    pose = np.array(init, dtype=np.float64)
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
        try:
            step = -np.linalg.solve(h + np.eye(3) * 1e-6 * (np.trace(h) + 1e-9), g)
        except np.linalg.LinAlgError:
            break
        step[:2] = np.clip(step[:2], -0.2, 0.2)  # trust region: a cell-sized field is local
        step[2] = float(np.clip(step[2], -0.1, 0.1))
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
    cx, cy = np.meshgrid(centre[0] + offs, centre[1] + offs)
    cx, cy = cx.ravel(), cy.ravel()
    if free is not None:
        ix = np.floor((cx - fr.origin_x_m) / res).astype(np.int64)
        iy = np.floor((cy - fr.origin_y_m) / res).astype(np.int64)
        ok = (ix >= 0) & (iy >= 0) & (ix < field.w) & (iy < field.h)
        ok[ok] = free[iy[ok], ix[ok]]
        cx, cy = cx[ok], cy[ok]
    n_yaw = round(half_yaw / step_yaw)
    poses, scores = [], []
    for k in range(-n_yaw, n_yaw + 1):
        yaw = centre[2] + k * step_yaw
        c, s = math.cos(yaw), math.sin(yaw)
        rx, ry = c * pts[:, 0] - s * pts[:, 1], s * pts[:, 0] + c * pts[:, 1]
        ix = np.floor((cx[:, None] + rx[None, :] - fr.origin_x_m) / res).astype(np.int64)
        iy = np.floor((cy[:, None] + ry[None, :] - fr.origin_y_m) / res).astype(np.int64)
        ok = (ix >= 0) & (iy >= 0) & (ix < field.w) & (iy < field.h)
        hit = np.zeros(ix.shape, dtype=np.bool_)
        hit[ok] = near[iy[ok], ix[ok]]
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
