"""The planner's fast paths against their plain definitions, bit for bit (pure, no processes):
the outline sampled in batches and in place, people's distances in the same batches, both
axes braked in one call. Each must give exactly the numbers of the plain formula (nav_eval's
figures are compared to the plan cycle: any difference would show there as chaos)."""

from __future__ import annotations

from typing import Any

import numpy as np

from autochair.control.core import ControlConfig
from autochair.nav import field as nav_field
from autochair.nav.field import Footprint, GridMap, NavField, bilinear_xy, place_xy
from autochair.nav.mpepc import Mpepc, MpepcParams, Person, move, scurve, wall_turn

FP = Footprint()


def room() -> NavField:
    """A 6 × 4 m room with a post: points can lie inside, near the edges and off the map."""
    segs = np.array([[0, 0, 6, 0], [6, 0, 6, 4], [6, 4, 0, 4], [0, 4, 0, 0]], dtype=float)
    return NavField(GridMap.from_shapes(segs, np.array([[3.0, 2.0, 0.3]])), FP)


def plain_place(points: np.ndarray, x: np.ndarray, y: np.ndarray, yaw: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    x, y, yaw = x[..., None], y[..., None], yaw[..., None]
    c, s = np.cos(yaw), np.sin(yaw)
    px, py = points[:, 0], points[:, 1]
    return x + c * px - s * py, y + s * px + c * py


def plain_bilinear(grid: np.ndarray, gm: GridMap, x: np.ndarray, y: np.ndarray,
                   outside: float) -> np.ndarray:
    h, w = grid.shape
    fx = (x - gm.origin_x_m) / gm.resolution_m - 0.5
    fy = (y - gm.origin_y_m) / gm.resolution_m - 0.5
    inside = (fx >= 0) & (fx <= w - 1) & (fy >= 0) & (fy <= h - 1)
    fx = np.minimum(np.maximum(fx, 0), w - 1.0001)
    fy = np.minimum(np.maximum(fy, 0), h - 1.0001)
    x0, y0 = fx.astype(np.intp), fy.astype(np.intp)
    ax, ay = fx - x0, fy - y0
    g = grid
    v = (g[y0, x0] * (1 - ax) * (1 - ay) + g[y0, x0 + 1] * ax * (1 - ay)
         + g[y0 + 1, x0] * (1 - ax) * ay + g[y0 + 1, x0 + 1] * ax * ay)
    return np.where(inside, v, outside)


def plain_reading(fld: NavField, x: np.ndarray, y: np.ndarray,
                  below: float = nav_field.EXACT_BELOW_M) -> np.ndarray:
    """NavField.clearance_xy written plainly: the bilinear reading, and under EXACT_BELOW_M
    (and `below`; not 0: off the map) the least of it and the exact distance to the nearest
    of the obstacle squares nearest to the cell centres round the point (EXACT_BLOCK; the
    same operations, 2-D indices), except where the bilinear one is exact (`col`, `row`)."""
    gm, (h, w) = fld.map, fld.clearance.shape
    v = plain_bilinear(fld.clearance, gm, x, y, 0.0)
    fx = np.minimum(np.maximum((x - gm.origin_x_m) / gm.resolution_m - 0.5, 0), w - 1.0001)
    fy = np.minimum(np.maximum((y - gm.origin_y_m) / gm.resolution_m - 0.5, 0), h - 1.0001)
    x0, y0 = fx.astype(np.intp), fy.astype(np.intp)
    ax, ay = fx - x0, fy - y0
    best = np.full(v.shape, np.inf)
    for ox, oy in nav_field.EXACT_BLOCK:
        cy, cx = y0 + oy, x0 + ox
        real = (cy >= 0) & (cy < h) & (cx >= 0) & (cx < w)
        cy, cx = np.clip(cy, 0, h - 1), np.clip(cx, 0, w - 1)
        ny, nx = fld._nearest[0][cy, cx], fld._nearest[1][cy, cx]
        gx = np.maximum(np.abs(ax - (nx - x0).astype(np.float64)) - 0.5, 0.0)
        gy = np.maximum(np.abs(ay - (ny - y0).astype(np.float64)) - 0.5, 0.0)
        best = np.where(real, np.minimum(best, gx * gx + gy * gy), best)
    exact = np.sqrt(best) * gm.resolution_m
    # (not where the four centres' nearest obstacles lie straight across, in one column or
    # row beyond them: there the bilinear reading is the distance to their face)
    ny, nx = fld._nearest
    quad = [(y0 + oy, x0 + ox) for oy in (0, 1) for ox in (0, 1)]
    col = np.all([(nx[q] == nx[quad[0]]) & (ny[q] == q[0]) for q in quad], 0) & (
        (nx[quad[0]] < x0) | (nx[quad[0]] > x0 + 1))
    row = np.all([(ny[q] == ny[quad[0]]) & (nx[q] == q[1]) for q in quad], 0) & (
        (ny[quad[0]] < y0) | (ny[quad[0]] > y0 + 1))
    return np.asarray(np.where((v > 0) & (v < min(below, nav_field.EXACT_BELOW_M)) & ~col & ~row,
                               np.minimum(v, exact), v))


def poses(n: int, t: int, seed: int, off_map: bool) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    lo, hi = (-2.0, 8.0) if off_map else (1.0, 5.0)
    return (rng.uniform(lo, hi, (n, t)), rng.uniform(lo * 0.5 + 0.5, hi * 0.5 + 0.5, (n, t)),
            rng.uniform(-4.0, 4.0, (n, t)))


def test_placing_and_sampling_the_outline_give_the_plain_numbers() -> None:
    fld = room()
    for off_map in (False, True):
        x, y, yaw = poses(7, 5, 1, off_map)
        px, py = place_xy(fld.outline, x, y, yaw)
        qx, qy = plain_place(fld.outline, x, y, yaw)
        assert np.array_equal(px, qx) and np.array_equal(py, qy)
        # scalar poses broadcast as before
        sx, sy = place_xy(fld.outline, 2.0, 1.5, yaw)
        assert np.array_equal(sx, plain_place(fld.outline, np.full(yaw.shape, 2.0),
                                              np.full(yaw.shape, 1.5), yaw)[0])
        assert sy.shape == (*yaw.shape, len(fld.outline))
        got = bilinear_xy(fld.clearance, fld.map, px, py, 0.0)
        assert np.array_equal(got, plain_bilinear(fld.clearance, fld.map, qx, qy, 0.0))


def test_the_batched_footprint_clearance_is_the_plain_one() -> None:
    fld = room()
    step = nav_field.BATCH_POINTS // len(fld.outline)
    for off_map in (False, True):
        # more poses than one batch holds, not a multiple of it: several batches and a rest
        x, y, yaw = poses(3 * step // 25 + 7, 25, 2, off_map)
        want = plain_clearance(fld, x, y, yaw)
        assert (want < nav_field.REFINE_BELOW_M).any() and (want > 0.3).any()  # both tiers
        got = fld.footprint_clearance(x, y, yaw)
        assert got.shape == x.shape and np.array_equal(got, want)
        if off_map:  # (some outline points off the map: the clamped path, 0 there)
            assert (got == 0.0).any() and (got > 0.0).any()
        # the in-place sampling of given outline points (its scratch overwritten)
        px, py = plain_place(fld.outline, x[:3], y[:3], yaw[:3])
        assert np.array_equal(fld.outline_clearance(px.copy(), py.copy()),
                              plain_reading(fld, px, py).min(-1))
    # a single pose and a sweep of yaws at one point (broadcast) as before
    assert float(fld.footprint_clearance(2.0, 1.0, 0.3)) == float(plain_clearance(
        fld, np.array([2.0]), np.array([1.0]), np.array([0.3]))[0])
    yaws = np.linspace(-3.0, 3.0, 2000)
    want = plain_clearance(fld, np.full(yaws.size, 1.5), np.full(yaws.size, 1.0), yaws)
    assert np.array_equal(fld.footprint_clearance(1.5, 1.0, yaws), want)


def test_reading_for_a_threshold_decides_as_reading_all() -> None:
    """NavField.footprint_clearance(need=, upto=) refines only the readings that could cross
    `upto` (the planner's committed sweeps): every pose it puts under `need`, and every one it
    puts at `upto` or more, the fine outline everywhere puts there too."""
    fld = room()
    x, y, yaw = poses(400, 25, 5, False)
    full = np.minimum(*(plain_reading(fld, *plain_place(o, x, y, yaw)).min(-1)
                        for o in (fld.outline, fld.outline_fine)))
    for need, upto in ((0.05, 0.05), (0.05, 0.09), (0.02, 0.02)):
        got = fld.footprint_clearance(x, y, yaw, need=need, upto=upto)
        assert ((full < need) & (full < got)).any()  # (coarse under need, left coarse)
        assert np.array_equal(got < need, full < need)
        assert np.array_equal(got >= upto, full >= upto)


def plain_clearance(fld: NavField, x: np.ndarray, y: np.ndarray, yaw: np.ndarray
                    ) -> np.ndarray:
    """The two-tier outline clearance, written plainly: the coarse outline everywhere, the
    fine one too where the coarse reads under REFINE_BELOW_M."""
    coarse = plain_reading(fld, *plain_place(fld.outline, x, y, yaw)).min(-1)
    fine = plain_reading(fld, *plain_place(fld.outline_fine, x, y, yaw)).min(-1)
    return np.asarray(np.where(coarse < nav_field.REFINE_BELOW_M, np.minimum(coarse, fine),
                               coarse))


def test_people_distances_in_batches_are_the_plain_ones() -> None:
    fld = room()
    mp = Mpepc(fld, ControlConfig().law(0.025), MpepcParams())
    x, y, yaw = poses(140, mp.steps, 3, True)
    people = [Person(2.0, 1.0, 0.5, -0.2, 0.25), Person(4.5, 3.0, 0.0, 0.0, 0.3)]
    t = np.asarray((np.arange(mp.steps) + 1) * mp.p.dt_s, dtype=np.float64)
    d, near = mp.outline_distances(x, y, yaw, people, t)
    px, py = plain_place(fld.outline, x, y, yaw)
    # (the prediction's clearance: the coarse outline, NavField.footprint_clearance(fine=False))
    # (read exactly under contact_m and half a cell: Mpepc.predict_below)
    assert np.array_equal(d, plain_reading(fld, px, py, mp.predict_below).min(-1))
    assert np.array_equal(d, fld.footprint_clearance(x, y, yaw, fine=False,
                                                     below=mp.predict_below))
    assert ((d > 0.0) & (d < mp.predict_below)).any()
    turned = 0
    for p, (to_path, to_here) in zip(people, near, strict=True):
        cx, cy = p.x_m + p.vx_mps * t, p.y_m + p.vy_mps * t
        on = np.hypot(px - cx[:, None], py - cy[:, None]).min(-1)
        turn = wall_turn(p, fld, float(t[-1]))
        if turn is not None:  # (or turned back short of a wall: to the segment, each step)
            turned += 1
            for k in np.nonzero(t >= turn.from_s)[0]:
                ax, ay, bx, by = (float(e[0]) for e in turn.span(p, t[k:k + 1]))
                a, b = np.array([ax, ay]), np.array([bx, by])
                q = np.stack([px[:, k], py[:, k]], -1) - a  # (N, P, 2)
                u = np.clip(q @ (b - a) / max(float((b - a) @ (b - a)), 1e-12), 0.0, 1.0)
                seg = np.linalg.norm(q - u[..., None] * (b - a), axis=-1).min(-1)
                on[:, k] = np.minimum(on[:, k], seg)
        assert np.allclose(to_path, on, rtol=0.0, atol=1e-12)
        assert np.array_equal(to_here, np.hypot(px - p.x_m, py - p.y_m).min(-1))
    assert turned == 1  # (the first walks into the room's wall within the horizon)
    d0, none = mp.outline_distances(x, y, yaw, [], t)
    assert none == [] and np.array_equal(d0, d)


def test_braking_both_axes_in_one_call_is_braking_each() -> None:
    law = ControlConfig().law(0.025)
    mp = Mpepc(room(), law, MpepcParams())
    rng = np.random.default_rng(4)
    n = 50
    st0 = np.stack([rng.uniform(-0.2, 1.2, n), rng.uniform(-1.0, 1.0, n),
                    rng.uniform(-0.9, 0.9, n), rng.uniform(-2.0, 2.0, n)])
    st0[:, :3] = 0.0  # some already at rest
    x, y, yaw = rng.uniform(1, 5, n), rng.uniform(1, 3, n), rng.uniform(-3, 3, n)
    got = mp.braking(x, y, yaw, st0.copy())
    # the plain loop: each axis its own S-curve, every step kept every 0.1 s, until at rest
    h, st, zero, kept = mp.p.exact_dt_s, st0.copy(), np.zeros(n), []
    every = max(1, round(0.5 * mp.p.dt_s / h))
    steps = int(np.ceil((law.vmax_mps / law.a_mps2 + 2 * law.a_mps2 / law.jerk_mps3) / h))
    for k in range(steps):
        v_old, w_old = st[0].copy(), st[2].copy()
        st[0], st[1] = scurve(st[0], st[1], zero, law.vmax_mps, law.a_mps2, law.jerk_mps3, h)
        st[2], st[3] = scurve(st[2], st[3], zero, law.omega_max_radps, law.omega_acc_radps2,
                              law.omega_jerk_radps3, h)
        x, y, yaw = move(x, y, yaw, v_old, w_old, st, h)
        done = not st.any()
        if (k + 1) % every == 0 or k == steps - 1 or done:
            kept.append(np.stack([x, y, yaw]))
        if done:
            break
    want = np.stack(kept, -1)
    assert got.shape == want.shape and np.array_equal(got, want)
    assert np.abs(np.diff(got[0], axis=1)).max() > 0.01  # (positive control: it moved)


def test_descent_at_one_point_is_the_batched_one() -> None:
    """CostToGo.descent_xy (the descent paths' point-by-point steps) gives descent's number,
    bit for bit, inside the map, on its last cell centres and off it (clamped, then 0)."""
    fld = room()
    ctg = fld.cost_to_go(1.0, 1.0)
    assert ctg is not None
    gm, (h, w) = fld.map, fld.clearance.shape
    rng = np.random.default_rng(6)
    pts = [(float(x), float(y)) for x, y in rng.uniform(-1.0, 8.0, (3000, 2))]
    # (on the edges' cell centres, where _sample_at's clamp and `inside` part)
    for fx, fy in ((0.0, 0.0), (w - 1.0, h - 1.0), (w - 1.00005, 3.0), (-1e-12, 2.0)):
        pts.append((gm.origin_x_m + (fx + 0.5) * gm.resolution_m,
                    gm.origin_y_m + (fy + 0.5) * gm.resolution_m))
    got = np.array([ctg.descent_xy(gm, x, y) for x, y in pts])
    want = np.array([float(ctg.descent(gm, np.array([x, y]))) for x, y in pts])
    assert np.array_equal(got.view(np.int64), want.view(np.int64))
    assert any(fld.cell(x, y) is None for x, y in pts)  # (off the map: ∇ 0, ±π)
    assert (np.abs(want) == np.pi).any() and (np.abs(want) < 3.0).any()


def test_a_stop_beside_the_law_brakes_as_one_with_vmax_0() -> None:
    """Mpepc.law_step(law_upto=k): the candidates from k on brake without the law worked out
    for them, to the same numbers as the law with their vmax 0 (simulate's stops); and
    braking without its poses gives the same commands."""
    mp = Mpepc(room(), ControlConfig().law(0.025), MpepcParams())
    rng = np.random.default_rng(7)
    n, k = 60, 35
    x, y, yaw = rng.uniform(1, 5, n), rng.uniform(1, 3, n), rng.uniform(-3, 3, n)
    tgt = np.stack([rng.uniform(0, 6, n), rng.uniform(0, 4, n), rng.uniform(-3, 3, n)], 1)
    vmax = rng.uniform(0.15, 1.2, n)
    vmax[3] = 0.0  # (the stop seed among the law's)
    st0 = np.stack([rng.uniform(-0.2, 1.2, n), rng.uniform(-1.0, 1.0, n),
                    rng.uniform(-0.9, 0.9, n), rng.uniform(-2.0, 2.0, n)])
    turning0 = rng.random(n) < 0.3
    halted = vmax.copy()
    halted[k:] = 0.0
    out = []
    for upto, vm in ((None, halted), (k, vmax)):
        st, turning, arrived = st0.copy(), turning0.copy(), np.zeros(n, dtype=np.bool_)
        pose = mp.law_step(x, y, yaw, st, tgt, vm, turning, arrived, None, 0.05,
                           jerk_from=20, law_upto=upto)
        out.append((np.stack(pose), st, turning[:k], arrived[:k]))
    for a, b in zip(*out, strict=True):
        assert np.array_equal(a, b)
    cmds: list[list[np.ndarray]] = [[], []]
    for poses, c in zip((True, False), cmds, strict=True):
        got = mp.braking(x, y, yaw, st0.copy(), cmds=c, poses=poses)
        assert got.shape[:2] == (3, n) and (got.shape[2] > 0) == poses
    assert len(cmds[0]) == len(cmds[1]) > 10
    assert all(np.array_equal(a, b) for a, b in zip(*cmds, strict=True))


def test_the_timing_band_read_in_one_call_is_read_move_by_move() -> None:
    """Mpepc._banded reads both moves of the start (±stop_timing_s·v0) in one call: the
    numbers of reading each in turn."""
    fld = room()
    mp = Mpepc(fld, ControlConfig().law(0.025), MpepcParams())
    x, y, yaw = (a.ravel() for a in poses(300, 1, 8, False))
    need, band, v0, pose = 0.05, 0.09, 0.8, (2.0, 1.0, 0.4)
    d = fld.footprint_clearance(x, y, yaw, need=need, upto=band)
    near = d < band
    assert near.any() and not near.all()
    want = d.copy()
    e = mp.p.stop_timing_s
    for ds in (e * v0, -e * v0):
        want[near] = np.minimum(want[near], fld.footprint_clearance(
            x[near] + ds * np.cos(pose[2]), y[near] + ds * np.sin(pose[2]), yaw[near],
            need=need))
    got = mp._banded(pose, v0, x, y, yaw, d.copy(), need, band, False)
    assert np.array_equal(got, want) and (got < d).any()
    # (the start pose's readings kept per pose and keywords: the same numbers)
    kws: list[dict[str, Any]] = [{}, {"fine": False, "below": mp.predict_below},
                                 {"need": need, "upto": band}]
    for kw in kws:
        for p in (pose, (2.0, 1.0, -0.4)):
            assert mp.pose_clearance(p, **kw) == float(fld.footprint_clearance(*p, **kw))
