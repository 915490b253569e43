"""Issue 11 (CPU, pure): the per-scan shortcuts of mapping mode give the same numbers, bit for
bit, as the computations they replace: LineField's precomputed nearest-cell lookup, Slam's
kept per-keyframe beam arrays (`_seen`), refine's scalar clip, score_grid's separable grid."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from bench import loc_eval
from scipy import ndimage

from autochair.localization.matching import (
    BoolGrid,
    DistanceField,
    LineField,
    _clip,
    score_grid,
)
from autochair.localization.node import localizer_for
from autochair.localization.slam import Slam

F64 = np.ndarray


def _mapped(slam: Slam, minutes: float) -> Iterator[F64]:
    slam.pose = np.array(loc_eval.ROUTES["hallway"][0], dtype=np.float64)
    for tick in loc_eval.drive("hallway", minutes, skew=True):
        e = slam.update(tick.odom, tick.scan)
        yield np.concatenate((e.pose, e.correction, [e.quality]))


def _old_sample(f: LineField, pts: F64) -> tuple[F64, F64, F64]:
    """LineField.sample as it was: the nearest occupied cell from the EDT's indices at each
    query, its number through a flat lookup table."""
    _, (ny, nx) = ndimage.distance_transform_edt(~f.occupied, return_indices=True)
    lut = np.zeros(f.h * f.w, dtype=np.int64)
    lut[np.flatnonzero(f.occupied)] = np.arange(int(f.occupied.sum()))
    fr = f.frame
    lx, ly = pts[:, 0] - fr.origin_x_m, pts[:, 1] - fr.origin_y_m
    ix, iy = np.floor(lx / f.res).astype(np.int64), np.floor(ly / f.res).astype(np.int64)
    inside = (ix >= 0) & (iy >= 0) & (ix < f.w) & (iy < f.h)
    ix, iy = np.where(inside, ix, 0), np.where(inside, iy, 0)
    ok = inside & (f.dist[iy, ix] < f.max_dist_m * 0.9)
    c = lut[ny[iy, ix].astype(np.int64) * f.w + nx[iy, ix]]
    rx, ry = lx - f._cx[c], ly - f._cy[c]
    nrx, nry = f._nrm_x[c], f._nrm_y[c]
    signed = nrx * rx + nry * ry
    dp = np.hypot(rx, ry)
    line = f._line[c]
    d = np.where(line, np.abs(signed), dp)
    sgn = np.where(signed >= 0, 1.0, -1.0)
    safe = np.maximum(dp, 1e-9)
    gx = np.where(line, sgn * nrx, rx / safe)
    gy = np.where(line, sgn * nry, ry / safe)
    pull = ok & f._pull[c]
    return (np.where(ok, d, f.max_dist_m), np.where(pull, gx, 0.0),
            np.where(pull, gy, 0.0))


def test_line_field_sample_equals_the_edt_index_lookup() -> None:
    slam = Slam()
    for _ in _mapped(slam, 0.3):
        pass
    field = slam._submap_of(slam._submap_ids)
    assert isinstance(field, LineField)
    rng = np.random.default_rng(3)
    fr = field.frame
    lo = np.array([fr.origin_x_m, fr.origin_y_m]) - 0.5  # some queries off the grid too
    hi = np.array([fr.origin_x_m + field.w * field.res, fr.origin_y_m + field.h * field.res])
    q = lo + rng.random((20000, 2)) * (hi + 0.5 - lo)
    new, old = field.sample(q), _old_sample(field, q)
    for a, b in zip(new, old, strict=True):
        assert np.array_equal(a, b)
    # The queries reach every branch: near a line, near a corner, far, off the grid.
    d, gx, _ = new
    assert (d < field.max_dist_m).sum() > 1000 and (d == field.max_dist_m).sum() > 1000
    near = d < field.max_dist_m
    assert 0 < np.count_nonzero(near & (gx != 0.0)) < near.sum()


class _Uncached(Slam):
    def _beams_of(self, ids: range) -> tuple[F64, F64, F64, F64, F64, F64]:
        self._beams = None  # every call computes afresh, as before the cache
        return super()._beams_of(ids)


def test_kept_keyframe_beams_give_the_same_map_as_computing_them_each_scan() -> None:
    cached, fresh = Slam(), _Uncached()
    for a, b in zip(_mapped(cached, 0.6), _mapped(fresh, 0.6), strict=True):
        assert np.array_equal(a, b)
    assert cached.stats.keyframes > 20 and cached.stats.loop_tries > 0  # loop searches ran
    assert all(np.array_equal(a, b) for a, b in zip(cached.graph.nodes, fresh.graph.nodes,
                                                    strict=True))


def test_kept_keyframe_beams_follow_keyframes_that_moved() -> None:
    """A loop closure replaces the graph's poses (optimize) and could change one in place: the
    kept arrays must not outlive either."""
    slam = Slam()
    for _ in _mapped(slam, 0.3):
        pass
    ids, pose = slam._submap_ids, slam.pose.copy()
    pts = slam.kfs[-1].pts
    before = slam._seen(pose, pts, ids)
    assert slam._beams is not None and slam._beams[0] == ids

    def fresh() -> np.ndarray:
        slam._beams = None
        return slam._seen(pose, pts, ids)

    slam.graph.nodes = [n + np.array([0.4, -0.3, 0.2]) for n in slam.graph.nodes]  # optimize
    moved = slam._seen(pose, pts, ids)
    assert np.array_equal(moved, fresh()) and not np.array_equal(moved, before)
    slam.graph.nodes[ids.start][:] = (0.0, 0.0, math.pi)  # in place
    assert np.array_equal(slam._seen(pose, pts, ids), fresh())


@pytest.mark.parametrize("v", [0.0, -0.0, 0.05, -0.05, 0.2, -0.2, 0.3, -7.0, math.inf,
                               -math.inf, math.nan])
def test_scalar_clip_is_numpys(v: float) -> None:
    for limit in (0.1, 0.2):
        got, want = _clip(np.float64(v), limit), float(np.clip(np.float64(v), -limit, limit))
        assert (math.isnan(got) and math.isnan(want)) or (
            got == want and math.copysign(1.0, got) == math.copysign(1.0, want))


def _old_score_grid(field: DistanceField, pts: F64, centre: F64, *, half_xy_m: float,
                    half_yaw: float, step_xy_m: float, step_yaw: float, inlier_m: float,
                    max_points: int = 80, free: BoolGrid | None = None) -> tuple[F64, F64]:
    """score_grid as it was: every candidate's cells computed for every point."""
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


def test_score_grid_equals_scoring_every_candidate_alone() -> None:
    """A loop closure's search on a submap (windows off its edge too), and a localizer's
    whole-map search kept on free cells."""
    slam = Slam()
    for _ in _mapped(slam, 0.3):
        pass
    sub = slam._submap_of(range(0, 8), crop=False)
    pts = slam.kfs[-1].pts
    win = dict(half_xy_m=1.0, half_yaw=0.2, step_xy_m=0.05, step_yaw=math.radians(1.5),
               inlier_m=0.05)
    off = dict(half_xy_m=3.0, half_yaw=0.1, step_xy_m=0.1, step_yaw=0.05, inlier_m=0.1)
    cases: list[tuple[DistanceField, F64, F64, dict[str, Any]]] = [
        (sub, pts, slam.pose, win),
        (sub, pts, slam.pose + np.array([5.0, 0.0, 0.0]), off),  # part off the grid
        (sub, pts[:0], slam.pose, win)]  # no points
    loc = localizer_for(loc_eval.surveyed_map("hallway"))
    f = loc.field.frame
    centre = np.array([f.origin_x_m + loc.field.w * loc.field.res / 2,
                       f.origin_y_m + loc.field.h * loc.field.res / 2, 0.0])
    cases.append((loc.field, pts, centre, dict(
        half_xy_m=max(loc.field.w, loc.field.h) * loc.field.res / 2, half_yaw=math.pi,
        step_xy_m=0.2, step_yaw=math.radians(5), inlier_m=0.1, max_points=40,
        free=loc.free)))
    fr = sub.frame
    edge = fr.origin_x_m + sub.w * sub.res
    assert (slam.pose[0] + 5.0 - 3.0 + pts[:, 0].min() < edge
            < slam.pose[0] + 5.0 + 3.0 + pts[:, 0].max())  # the second case straddles it
    for field, p, c, kw in cases:
        new, old = score_grid(field, p, c, **kw), _old_score_grid(field, p, c, **kw)
        assert new[0].shape == old[0].shape and new[0].shape[0] > 0
        assert np.array_equal(new[0], old[0]) and np.array_equal(new[1], old[1])
    assert new[1].max() > 0.5 and new[1].min() == 0.0  # the last (whole map): fits and misses
