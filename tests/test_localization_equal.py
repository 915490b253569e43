"""Issue 11 (CPU, pure): the per-scan shortcuts of mapping mode give the same numbers, bit for
bit, as the computations they replace: LineField's precomputed nearest-cell lookup, Slam's
kept per-keyframe beam arrays (`_seen`), refine's scalar clip."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest
from bench import loc_eval
from scipy import ndimage

from autochair.localization.matching import LineField, _clip
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
