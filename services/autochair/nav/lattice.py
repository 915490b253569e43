"""Heading-aware navigation function near the goal: costs-to-go over (x, y, θ). PURE (numpy, scipy).

The 2-D navigation function (field.py) is for the axle: it says nothing about the heading the
chair needs where the last turn has no room (an in-place turn sweeps 1.01 m round the axle, the
front is 0.95 m ahead of it). Here a window round the goal is a lattice of cells (0.1 m) ×
`headings` directions. A state is free when the chair's real rectangle there clears obstacles
by `min_clear_m` (configuration-space obstacles: the grid's "too close" cells correlated with
the rectangle rasterised at each heading, by FFT (scipy.fft; the rectangle's transforms kept
per window size): ~0.1 s, where sampling the outline per state took ~1 s). Forward-only motions
(the safety monitor forbids blind reversing): a straight step, an arc of one heading step, and
an in-place turn of one heading step where the swept body is free (the half step checked too).
Costs are metres at full speed, slowed near walls as the 2-D field's (so the two agree in open
space); a turn costs vmax/ω max metres per radian. Costs-to-go from every state to the goal
region (the goal's cell and those within the tolerance, at the two headings round the goal's
yaw, each seeded with its remaining distance and turn) by Dijkstra over the reversed graph
(scipy.sparse.csgraph, in C: ~10⁵ states in tens of ms).

MPEPC (mpepc.py) measures progress on this where it is finite and on the 2-D field (+ the
median offset between the two) elsewhere, and seeds candidates along the lattice's best path.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.fft as sfft
import scipy.ndimage as ndi
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import breadth_first_order, dijkstra

from autochair.safety.core import SafetyTuning

from . import gil
from .field import Footprint, NavField, place_xy

F64 = npt.NDArray[np.float64]
Bool = npt.NDArray[np.bool_]
I64 = npt.NDArray[np.intp]


@dataclass(frozen=True)
class LatticeParams:
    half_m: float = 3.0  # window half size round the goal
    # ... stretched towards the chair (this far round it), at most this far from the goal:
    # entering the window mid-room left the chair where the lattice's only way was too
    # tight for the law's curves (the cluttered room).
    start_margin_m: float = 1.5
    reach_m: float = 8.0
    # Lattice cell (a multiple of the map's). 0.1 m (and 32 headings) was too coarse: tight
    # goals (office A's far corner, the cluttered room's far corner) had no way in.
    resolution_m: float = 0.05
    headings: int = 16
    min_clear_m: float = 0.04  # the footprint's clearance in a free state
    # Clearance-aware costs (as Nav2's inflation): a move whose states (or an in-place turn's
    # swept half step) keep less than `roomy_clear_m` costs `tight_factor` times more. The
    # least-cost way then turns where there is room when there is any: exact ways with 4 cm
    # to spare are ways the law's tracking (a few cm) cannot follow, and beside them lie
    # states costing metres more (office B's desk: the 90° turn at the goal clears by 5 cm,
    # 6 cm to the side by 10; measured). 0: off (the refusal's lattice, planner.py).
    roomy_clear_m: float = 0.10
    tight_factor: float = 1.0
    arc_radius_m: float = 0.6
    # An arc's cost over its length: the law cannot follow chains of tight arcs (S-bends
    # before a door, a zig-zag in clutter) that the lattice finds cheap.
    arc_factor: float = 2.0
    # The goal region: the goal's own cell and those within this distance (the position
    # tolerance) seed the search. 0.1 m made a chair 10 cm beside the goal "there" (the
    # lateral step a forward-only chair makes by turning, driving and turning back).
    goal_radius_m: float = 0.05
    # A goal-region state off the goal's yaw counts only if its turn onto that yaw keeps this
    # (MPEPC's contact_m, which the goal's hand-over checks: Mpepc.goal_turn_clearance),
    # sampled every `goal_turn_step_m` at the far corners: else the way ended 31° off at
    # office B's desk, where the turn (0.033 m) was neither handed over nor had a stage
    # (nav_eval seed 2; measured).
    goal_turn_clear_m: float = 0.05
    goal_turn_step_m: float = 0.01
    turn_m_per_rad: float = 1.33  # an in-place turn's cost: vmax / ω max
    max_cost: float = 1e3  # the window's "no way" (finite, so interpolation stays defined)
    # With the safety monitor: the region ahead of the body (a rectangle in the chair frame,
    # `ahead_of`) that a forward move's end state keeps clear: where it is not, the monitor
    # bounds forward motion to 0 and the PID latches a stop (the cabinet's and office A's
    # far corner's ways in, session 27). None: not checked (no monitor).
    ahead: Footprint | None = None


def ahead_of(fp: Footprint, pad_m: float, stop_m: float, cell_m: float = 0.0) -> Footprint:
    """The strip the safety monitor sweeps straight ahead of `fp` grown by `pad_m` before it
    bounds forward motion to 0 (its free extent ≤ `stop_m`: the stop margin plus one sweep
    step), as a rectangle from the bare front on (rear_m = −front_m); less half a map cell
    (`cell_m`) each way, which `footprint_kernel` grows it by again. (Against the monitor's
    own core on noiseless scans round the cabinet's, office A's and the cluttered room's far
    corners: 91-95 % of states agree; the full strip, grown, also caught walls alongside 3 cm
    clear of the padded body and refused the cluttered room's far corner, which is reached:
    docs/experiments/monitor-envelope-way-in-s28.md.)"""
    return Footprint(front_m=fp.front_m + pad_m + stop_m - cell_m / 2, rear_m=-fp.front_m,
                     half_width_m=fp.half_width_m + pad_m - cell_m / 2)


def monitor_ahead(fld: NavField, tuning: SafetyTuning | None = None) -> Footprint:
    """`ahead_of` for the safety monitor's `tuning` (default: its defaults) on this field's
    chair and cells."""
    t = tuning or SafetyTuning()
    return ahead_of(fld.footprint, t.padding_m, t.stop_margin_m + t.step_m,
                    fld.map.resolution_m)


def footprint_kernel(fld: NavField, yaw: float, shift: tuple[float, float] = (0.0, 0.0),
                     fp: Footprint | None = None) -> tuple[npt.NDArray[np.float64], int]:
    """(2K+1)² mask of the map cells under the chair's rectangle (or `fp`'s) at `yaw` round
    the axle's cell (centre K, K), grown by half a cell (a cell counts if it may overlap);
    the axle `shift` (x, y, within half a cell) off that cell's centre."""
    fp, res = fp or fld.footprint, fld.map.resolution_m
    k = math.ceil((fp.reach_m + res) / res)
    off = np.arange(-k, k + 1) * res
    px, py = np.meshgrid(off - shift[0], off - shift[1])
    c, s = math.cos(yaw), math.sin(yaw)
    u, v = c * px + s * py, -s * px + c * py  # into the chair frame
    g = res * 0.5 * (abs(c) + abs(s))  # half a cell's extent along the chair's axes
    inside = (u >= -fp.rear_m - g) & (u <= fp.front_m + g) & (np.abs(v) <= fp.half_width_m + g)
    return inside.astype(np.float64), k


@dataclass(frozen=True)
class Moves:
    """Per heading k: successor headings, lattice offsets (di rows = y, dj cols = x), path
    lengths (m) and whether the move is an in-place turn."""

    k2: I64
    di: I64
    dj: I64
    length: F64
    turn: Bool


def moves(p: LatticeParams) -> list[Moves]:
    n, res = p.headings, p.resolution_m
    step = 2 * math.pi / n
    chord = 2 * p.arc_radius_m * math.sin(step / 2)
    out = []
    for k in range(n):
        th = k * step
        rows: list[tuple[int, int, int, float, bool]] = []
        # straight: the nearest lattice vector of ~0.2 m along the heading
        dj, di = round(2 * math.cos(th)), round(2 * math.sin(th))
        if abs(dj) == 2 and abs(di) == 2:
            dj, di = dj // 2, di // 2
        rows.append((k, di, dj, math.hypot(di, dj) * res, False))
        for s in (1, -1):  # an arc of one heading step
            a = th + s * step / 2
            rows.append(((k + s) % n, round(chord * math.sin(a) / res),
                         round(chord * math.cos(a) / res),
                         p.arc_radius_m * step * p.arc_factor, False))
            rows.append(((k + s) % n, 0, 0, p.turn_m_per_rad * step, True))  # in place
        out.append(Moves(np.array([r[0] for r in rows]), np.array([r[1] for r in rows]),
                         np.array([r[2] for r in rows]), np.array([r[3] for r in rows]),
                         np.array([r[4] for r in rows])))
    return out


@dataclass(frozen=True)
class HeadingField:
    """Costs-to-go (metres at full speed) to one goal pose over a window's (x, y, θ) states."""

    cost: F64  # (K, H, W); p.max_cost: no way from there (or not free)
    free: Bool  # (K, H, W)
    origin_x_m: float  # world position of cell (0, 0)'s centre
    origin_y_m: float
    params: LatticeParams
    offset: float  # median of (least cost over headings − 2-D φ) on the window's border
    goal: tuple[float, float, float]

    @property
    def step(self) -> float:
        return 2 * math.pi / self.params.headings

    def at(self, x: F64, y: F64, yaw: F64) -> tuple[F64, Bool]:
        """Costs-to-go at poses (...): bilinear in position, linear in heading, over the
        reachable of the eight neighbouring states; and where that is defined (inside the
        window, reachable neighbours carry ≥ 1/4 of the weight)."""
        k, h, w = self.cost.shape
        res = self.params.resolution_m
        fx = (np.asarray(x) - self.origin_x_m) / res
        fy = (np.asarray(y) - self.origin_y_m) / res
        inside = (fx >= 0) & (fx <= w - 1) & (fy >= 0) & (fy <= h - 1)
        fx, fy = np.clip(fx, 0, w - 1.0001), np.clip(fy, 0, h - 1.0001)
        x0, y0 = fx.astype(np.intp), fy.astype(np.intp)
        ax, ay = fx - x0, fy - y0
        fk = np.remainder(np.asarray(yaw) / self.step, k)
        k0 = np.floor(fk).astype(np.intp) % k
        k1 = (k0 + 1) % k
        ak = fk - np.floor(fk)
        c, cap = self.cost, self.params.max_cost
        total = np.zeros(np.shape(fx))
        weight = np.zeros(np.shape(fx))
        for kk, wk in ((k0, 1 - ak), (k1, ak)):
            for dy, wy in ((0, 1 - ay), (1, ay)):
                for dx, wx in ((0, 1 - ax), (1, ax)):
                    v = c[kk, y0 + dy, x0 + dx]
                    wt = np.where(v < cap, wk * wy * wx, 0.0)
                    total += wt * np.minimum(v, cap)
                    weight += wt
        # (over the reachable neighbours only: near walls some of the eight are not free)
        ok = inside & (weight >= 0.25)
        return np.where(ok, total / np.maximum(weight, 1e-9), cap), ok

    def way_in(self, x: float, y: float, yaw: float, near_m: float = 0.1) -> bool:
        """Whether a forward-only way into the goal pose starts where the chair can be: at a
        state within `near_m` and one heading step of the chair's pose (if it lies in the
        window), or at a free state on the window's border (the chair comes in from there).
        False: every state with a way in lies inside the window, none at the chair (e.g. a
        goal pose the chair could only back into)."""
        c, cap = self.cost, self.params.max_cost
        kk, h, w = c.shape
        s = self.state(x, y, yaw)
        if s is not None:
            r = max(1, round(near_m / self.params.resolution_m))
            ks = [(s[0] + dk) % kk for dk in (-1, 0, 1)]
            i0, j0 = max(s[1] - r, 0), max(s[2] - r, 0)
            if (c[ks, i0:s[1] + r + 1, j0:s[2] + r + 1] < cap).any():
                return True
        ring = np.zeros((h, w), dtype=np.bool_)
        ring[0], ring[-1], ring[:, 0], ring[:, -1] = True, True, True, True
        return bool((c[:, ring] < cap).any())

    def inside(self, x: F64, y: F64) -> npt.NDArray[np.bool_]:
        _, h, w = self.cost.shape
        res = self.params.resolution_m
        fx = (np.asarray(x) - self.origin_x_m) / res
        fy = (np.asarray(y) - self.origin_y_m) / res
        return (fx >= 0) & (fx <= w - 1) & (fy >= 0) & (fy <= h - 1)  # type: ignore[no-any-return]

    def state(self, x: float, y: float, yaw: float) -> tuple[int, int, int] | None:
        k, h, w = self.cost.shape
        res = self.params.resolution_m
        j = round((x - self.origin_x_m) / res)
        i = round((y - self.origin_y_m) / res)
        if not (0 <= i < h and 0 <= j < w):
            return None
        return round(yaw / self.step) % k, i, j

    def pose(self, s: tuple[int, int, int]) -> tuple[float, float, float]:
        res = self.params.resolution_m
        return (self.origin_x_m + s[2] * res, self.origin_y_m + s[1] * res,
                float(np.remainder(s[0] * self.step + math.pi, 2 * math.pi) - math.pi))

    def best_path(self, x: float, y: float, yaw: float, max_steps: int = 80
                  ) -> list[tuple[tuple[float, float, float], bool]]:
        """The lattice's best way from the state nearest the pose: (pose, reached by an
        in-place turn) per step, greedily down the costs-to-go; [] if that state has none."""
        s = self.state(x, y, yaw)
        if s is None:
            return []
        c = self.cost
        kk, h, w = c.shape
        if c[s] >= self.params.max_cost:  # the nearest state is not free: the best neighbour
            best = None
            for dk in (-1, 0, 1):
                for di in (-1, 0, 1):
                    for dj in (-1, 0, 1):
                        t = ((s[0] + dk) % kk, s[1] + di, s[2] + dj)
                        if 0 <= t[1] < h and 0 <= t[2] < w and c[t] < self.params.max_cost \
                                and (best is None or c[t] < c[best]):
                            best = t
            if best is None:
                return []
            s = best
        mv = moves(self.params)
        out: list[tuple[tuple[float, float, float], bool]] = []
        for _ in range(max_steps):
            m = mv[s[0]]
            ii, jj = s[1] + m.di, s[2] + m.dj
            ok = (ii >= 0) & (ii < h) & (jj >= 0) & (jj < w)
            if not ok.any():
                break
            cand = np.full(len(m.k2), np.inf)
            cand[ok] = c[m.k2[ok], ii[ok], jj[ok]]
            j = int(np.argmin(cand))
            if not cand[j] < c[s]:  # the goal region (cost = its seed) or a plateau
                break
            s = (int(m.k2[j]), int(ii[j]), int(jj[j]))
            out.append((self.pose(s), bool(m.turn[j])))
        return out


_KERNELS: dict[tuple[object, ...], npt.NDArray[np.complex64]] = {}


def free_states(fld: NavField, box: tuple[int, int, int, int], f: int, n: int,
                min_clear_m: float, shift: tuple[float, float] = (0.0, 0.0),
                extra: Bool | None = None, fp: Footprint | None = None) -> Bool:
    """(2n, H, W) free states at 2n orientations (the headings and the half steps between)
    at every f-th map cell of rows i0..i1, columns j0..j1 (box, inclusive; cells off the map
    and `extra` map cells count as obstacles), the axle `shift` off the cells' centres; the
    chair's rectangle, or `fp`'s. The rectangle's transforms are kept per window shape."""
    gm, fp = fld.map, fp or fld.footprint
    i0, i1, j0, j1 = box
    near = fld.clearance < min_clear_m  # includes the obstacles themselves
    if extra is not None:
        near = near | extra
    k = math.ceil((fp.reach_m + gm.resolution_m) / gm.resolution_m)
    rows, cols = i1 - i0 + 1 + 2 * k, j1 - j0 + 1 + 2 * k
    # Single precision: the correlation counts cells (≤ (2k+1)², ~2000), so its rounding error
    # (~1e-3) cannot cross the 0.5 threshold; half the work of double (the same states).
    win = np.ones((rows, cols), dtype=np.float32)
    mh, mw = near.shape
    a0, a1 = max(i0 - k, 0), min(i1 + k + 1, mh)
    b0, b1 = max(j0 - k, 0), min(j1 + k + 1, mw)
    if a0 < a1 and b0 < b1:
        win[a0 - (i0 - k):a1 - (i0 - k), b0 - (j0 - k):b1 - (j0 - k)] = near[a0:a1, b0:b1]
    shape = (sfft.next_fast_len(rows, True), sfft.next_fast_len(cols, True))
    key = (shape, gm.resolution_m, fp, n, k, shift)
    kers = _KERNELS.get(key)
    if kers is None:
        stack = []
        for j in range(2 * n):
            ker, _ = footprint_kernel(fld, j * math.pi / n, shift, fp)
            stack.append(sfft.rfft2(ker[::-1, ::-1].astype(np.float32), shape))
        kers = _KERNELS[key] = np.stack(stack)
        if len(_KERNELS) > 8:
            _KERNELS.pop(next(iter(_KERNELS)))
    spec = sfft.rfft2(win, shape)
    hits = sfft.irfft2(kers * spec[None], shape, axes=(-2, -1))
    # circular correlation, valid where it did not wrap: from 2k on
    return hits[:, 2 * k:rows:f, 2 * k:cols:f] < 0.5  # type: ignore[no-any-return]


def window(fld: NavField, goal: tuple[float, float, float],
           start: tuple[float, float, float] | None, p: LatticeParams, f: int
           ) -> tuple[int, int, int, int]:
    """Map-cell box (i0, i1, j0, j1) of the lattice: `half_m` round the goal, stretched
    towards the chair (to `start_margin_m` round it) up to `reach_m` from the goal; sizes
    rounded up to whole metres (the rectangle's transforms are kept per shape); the goal's
    cell on the lattice."""
    gm = fld.map
    res = gm.resolution_m
    g = (math.floor((goal[1] - gm.origin_y_m) / res), math.floor((goal[0] - gm.origin_x_m) / res))
    s = (g if start is None else (math.floor((start[1] - gm.origin_y_m) / res),
                                  math.floor((start[0] - gm.origin_x_m) / res)))
    half, margin, reach = (round(v / res) for v in (p.half_m, p.start_margin_m, p.reach_m))
    step = f * round(1.0 / (f * res)) if f * res <= 1.0 else f  # whole metres, in cells
    out = []
    for gc, sc in zip(g, s, strict=True):
        lo = min(gc - half, max(sc - margin, gc - reach))
        hi = max(gc + half, min(sc + margin, gc + reach))
        lo = gc - math.ceil((gc - lo) / step) * step
        hi = gc + math.ceil((hi - gc) / step) * step
        out += [lo, hi]
    return out[0], out[1], out[2], out[3]


Slices = tuple[slice, slice]


def legal_moves(full: Bool, half_steps: Bool, p: LatticeParams,
                turns: tuple[Bool, Bool] | None = None
                ) -> Iterator[tuple[int, int, Slices, Slices, Bool, float, bool]]:
    """Per motion (heading k → k2, an offset): the window slices of its start states (a) and
    end states (b), where it is legal (both free; an in-place turn's swept half step free too,
    and with `turns`, free states and half steps for in-place turns, its end and half step
    free there too), its length and whether it turns in place."""
    n, h, w = full.shape
    for k, m in enumerate(moves(p)):
        for k2, di, dj, length, turn in zip(m.k2, m.di, m.dj, m.length, m.turn, strict=True):
            a = (slice(max(0, -di), h - max(0, di)), slice(max(0, -dj), w - max(0, dj)))
            b = (slice(max(0, di), h - max(0, -di)), slice(max(0, dj), w - max(0, -dj)))
            ok = full[k][a] & full[k2][b]
            if turn:  # the swept body: the half step between the two headings
                mid = k if k2 == (k + 1) % n else int(k2)
                ok &= half_steps[mid][a]
                if turns is not None:
                    ok &= turns[1][mid][a] & turns[0][k2][b]
            yield k, int(k2), a, b, ok, float(length), bool(turn)


def graph(shape: tuple[int, int, int], deg: int,
          edges: Iterable[tuple[int, int, Slices, Slices, Bool, F64 | float]], reverse: bool,
          virtual: I64, virtual_cost: F64 | float) -> csr_matrix:
    """The lattice's motions (`edges`: per motion as `legal_moves` gives it, with its costs)
    as a graph over the states (flat index) and one virtual node after them, joined to the
    states `virtual`. Written straight into CSR form: every state's row holds its `deg` moves
    (out of it, or with `reverse` into it), a move not legal there a loop onto the state
    itself, which no search takes. (A COO matrix sorted into CSR cost more than the search.)"""
    n, h, w = shape
    nv = n * h * w
    idx = np.arange(nv, dtype=np.int32).reshape(shape)
    cols = np.empty(nv * deg + virtual.size, dtype=np.int32)
    data = np.ones(cols.size)
    cols_s = cols[:nv * deg].reshape(n, h, w, deg)
    data_s = data[:nv * deg].reshape(n, h, w, deg)
    cols_s[...] = idx[..., None]
    slot = [0] * n
    for k, k2, a, b, ok, c in edges:
        (rk, ra), (ck, ca) = ((k2, b), (k, a)) if reverse else ((k, a), (k2, b))
        into = (*ra, slot[rk])  # (a view: the masked writes land in cols, data)
        cols_s[rk][into][ok] = idx[ck][ca][ok]
        data_s[rk][into][ok] = c
        slot[rk] += 1
    cols[nv * deg:] = virtual
    data[nv * deg:] = virtual_cost
    indptr = np.append(np.arange(0, nv * deg + 1, deg), cols.size).astype(np.int32)
    return csr_matrix((data, cols, indptr), shape=(nv + 1, nv + 1))


def build(fld: NavField, goal: tuple[float, float, float], ctg_phi: F64 | None = None,
          params: LatticeParams | None = None, start: tuple[float, float, float] | None = None,
          costs: bool = True) -> HeadingField | None:
    """The heading-aware costs-to-go to `goal` in a window round it (and towards `start`);
    None if no free state lies in the goal region. `ctg_phi`: the 2-D costs-to-go (map
    grid) for the offset. Without `costs`, only which states have a way to the goal (cost 0,
    else `max_cost`), by a breadth-first search: a fifth of the time (the route check)."""
    p = params or LatticeParams()
    gm = fld.map
    f = max(1, round(p.resolution_m / gm.resolution_m))
    res = f * gm.resolution_m
    p = LatticeParams(**{**p.__dict__, "resolution_m": res})
    box = window(fld, goal, start, p, f)
    n = p.headings
    both = free_states(fld, box, f, n, p.min_clear_m)
    full, half_steps = both[0::2], both[1::2]
    # (any map obstacle in the strip: the monitor sees what the map holds, ~1 mm in)
    ahead = None if p.ahead is None else free_states(fld, box, f, n, 1e-3, fp=p.ahead)[0::2]
    tight = p.tight_factor > 0.0 and p.roomy_clear_m > p.min_clear_m
    if tight:
        roomy = free_states(fld, box, f, n, p.roomy_clear_m)
        roomy_full, roomy_half = roomy[0::2], roomy[1::2]
    _, h, w = full.shape
    i0, j0 = box[0], box[2]
    gi = math.floor((goal[1] - gm.origin_y_m) / gm.resolution_m)
    gj = math.floor((goal[0] - gm.origin_x_m) / gm.resolution_m)
    ii_map = np.clip(i0 + np.arange(h) * f, 0, gm.occupied.shape[0] - 1)
    jj_map = np.clip(j0 + np.arange(w) * f, 0, gm.occupied.shape[1] - 1)
    speed = fld.speed[np.ix_(ii_map, jj_map)]
    ox = gm.origin_x_m + (j0 + 0.5) * gm.resolution_m
    oy = gm.origin_y_m + (i0 + 0.5) * gm.resolution_m
    # The goal region: a virtual node joined to free states near the goal pose.
    gx, gy, gyaw = goal
    ii, jj = np.mgrid[0:h, 0:w]
    dist = np.hypot(ox + jj * res - gx, oy + ii * res - gy)
    near_cells = dist <= p.goal_radius_m + 1e-9
    near_cells[(gi - i0) // f, (gj - j0) // f] = True  # the goal's own cell
    step = 2 * math.pi / n
    kb = math.floor(gyaw / step)
    seeds_s: list[I64] = []
    seeds_c: list[F64] = []
    unchecked_s: list[I64] = []
    unchecked_c: list[F64] = []
    for kk in (kb % n, (kb + 1) % n):
        turn = abs(float(np.remainder(kk * step - gyaw + math.pi, 2 * math.pi) - math.pi))
        ok = near_cells & full[kk]
        unchecked_s.append(kk * h * w + np.flatnonzero(ok))
        unchecked_c.append(dist[ok] + p.turn_m_per_rad * turn)
        if turn > 1e-9 and ok.any():
            e = float(np.remainder(gyaw - kk * step + math.pi, 2 * math.pi) - math.pi)
            m = fld.footprint.turn_samples(e, p.goal_turn_step_m)
            ii_ok, jj_ok = np.nonzero(ok)
            yaws = kk * step + np.linspace(0.0, e, m)
            cx = (ox + jj_ok * res).astype(np.float64)[:, None]
            cy = (oy + ii_ok * res).astype(np.float64)[:, None]
            clear = fld.footprint_clearance(cx, cy, yaws[None, :])
            ok[ii_ok, jj_ok] = clear.min(-1) >= p.goal_turn_clear_m
        seeds_s.append(kk * h * w + np.flatnonzero(ok))  # (flat state index, as graph's)
        seeds_c.append(dist[ok] + p.turn_m_per_rad * turn)
    if not any(sd.size for sd in seeds_s):  # (the check never leaves a goal without a way)
        seeds_s, seeds_c = unchecked_s, unchecked_c
    s_seed = np.concatenate(seeds_s)
    if s_seed.size == 0:
        return None

    def edges() -> Iterator[tuple[int, int, Slices, Slices, Bool, F64]]:
        for k, k2, a, b, ok, length, in_place in legal_moves(full, half_steps, p):
            if ahead is not None and not in_place:
                ok = ok & ahead[k2][b]  # (ends where the monitor still lets it move on)
            c = np.full(int(ok.sum()), length) if in_place else \
                (length / np.minimum(speed[a], speed[b]))[ok]
            if tight:
                room = roomy_full[k][a] & roomy_full[k2][b]
                if in_place:
                    room &= roomy_half[k if k2 == (k + 1) % n else k2][a]
                c = c * np.where(room[ok], 1.0, 1.0 + p.tight_factor)
            yield k, k2, a, b, ok, c

    virtual = n * h * w  # the goal region, searched from over the reversed graph
    lat = graph((n, h, w), len(moves(p)[0].k2), edges(), True, s_seed,
                np.concatenate(seeds_c) + 1e-6)
    if costs:
        d = np.asarray(gil.run(dijkstra, lat, indices=virtual), dtype=np.float64)[:virtual]
        d = np.where(np.isfinite(d), d, p.max_cost).reshape(n, h, w)
    else:
        d = np.full(virtual + 1, p.max_cost)
        d[gil.run(breadth_first_order, lat, virtual, return_predecessors=False)] = 0.0
        d = d[:virtual].reshape(n, h, w)
    offset = 0.0
    if ctg_phi is not None and costs:  # where MPEPC moves from the 2-D field onto this: the border
        best = d.min(0)
        ring = np.zeros((h, w), dtype=np.bool_)
        bw = max(1, round(0.3 / res))
        ring[:bw], ring[-bw:], ring[:, :bw], ring[:, -bw:] = True, True, True, True
        use = ring & (best < p.max_cost)
        if not use.any():
            use = best < p.max_cost
        if use.any():
            phi2 = ctg_phi[np.ix_(ii_map, jj_map)]
            offset = float(np.median(best[use] - phi2[use]))
    return HeadingField(d, full, ox, oy, p, offset, goal)


def unreachable(fld: NavField, pose: tuple[float, float, float], half_m: float = 3.0,
                params: LatticeParams | None = None, sweep_rad: float = math.radians(2.0),
                grow_m: float = 0.3) -> Bool | None:
    """The map's cells (H, W) within `half_m` of the chair (a square) that its axle cannot get
    to from `pose` forward-only (this lattice's motions, its states clear by `min_clear_m`)
    without leaving the square; None if the chair has no free state. The 2-D field counts
    every cell the axle fits in, so its descent may point behind a chair that cannot turn
    there (the closed end of a corridor narrower than its 2.02 m turning circle) round an end
    it never gets to. The lattice is laid through the chair's exact position (a few cm decide
    whether it turns), at the headings its body sweeps to in place from its own yaw clear by
    `min_clear_m` (checked every `sweep_rad`) and the nearest one. The cells reached are grown
    by `grow_m`: the lattice's 22.5° steps cannot drift sideways along a corridor as the
    chair does (measured: in the L corridor, on the live map's 0.1 m cells, they reached a
    band 0.4 m wide where the axle fits in 0.8 m), and only routes the chair cannot take at
    all are to be given up, not the room it has on its way."""
    p = params or LatticeParams()
    gm = fld.map
    res_m = gm.resolution_m
    f = max(1, round(p.resolution_m / res_m))
    p = LatticeParams(**{**p.__dict__, "resolution_m": f * res_m, "half_m": half_m})
    box = window(fld, pose, None, p, f)
    ci = math.floor((pose[1] - gm.origin_y_m) / res_m)
    cj = math.floor((pose[0] - gm.origin_x_m) / res_m)
    shift = (round(pose[0] - gm.origin_x_m - (cj + 0.5) * res_m, 3),
             round(pose[1] - gm.origin_y_m - (ci + 0.5) * res_m, 3))
    both = free_states(fld, box, f, p.headings, p.min_clear_m, shift)
    full, half_steps = both[0::2], both[1::2]
    turns = None
    blind = np.zeros(gm.occupied.shape, dtype=np.bool_)
    if gm.unknown is not None:
        # No in-place turn sweeps the body over cells never observed (the chair's own
        # excepted: it stands there): they are behind the laser (its blind sector), and the
        # wall end the map lacks there is where the body would swing (the L corridor's
        # closed end: 1.01 m turning reach, 1.0 m to the unseen wall).
        under = np.zeros(gm.occupied.shape, dtype=np.bool_)
        under[fld.cells_under(*pose)] = True  # (and the cells its outline crosses)
        blind = gm.unknown & ~ndi.binary_dilation(under, np.ones((3, 3), dtype=np.bool_))
        seen = free_states(fld, box, f, p.headings, p.min_clear_m, shift, blind)
        turns = (seen[0::2], seen[1::2])
    n, h, w = full.shape
    i0, j0 = box[0], box[2]
    ci, cj = (ci - i0) // f, (cj - j0) // f  # (the window is centred on the chair's cell)
    step = 2 * math.pi / n
    heads = {round(pose[2] / step) % n}
    mh, mw = gm.occupied.shape
    for sign in (1.0, -1.0):  # in place either way, as far as the swept body stays clear
        angles = np.arange(0.0, math.pi + 1e-9, sweep_rad)
        yaws = pose[2] + sign * angles
        clear = fld.footprint_clearance(pose[0], pose[1], yaws) >= p.min_clear_m
        ox, oy = place_xy(fld.outline, pose[0], pose[1], yaws)  # (and not blind)
        ix = np.clip(np.floor((ox - gm.origin_x_m) / res_m).astype(np.intp), 0, mw - 1)
        iy = np.clip(np.floor((oy - gm.origin_y_m) / res_m).astype(np.intp), 0, mh - 1)
        clear &= ~blind[iy, ix].any(axis=-1)
        upto = float(angles[-1]) if clear.all() else float(angles[int(np.argmin(clear))])
        heads |= {k for k in range(n)
                  if np.remainder(sign * (k * step - pose[2]), 2 * math.pi) < upto}
    starts = [(k * h + ci) * w + cj for k in sorted(heads) if full[k, ci, cj]]  # flat
    if not starts:
        return None
    virtual = n * h * w  # the chair: joined to its start states
    lat = graph((n, h, w), len(moves(p)[0].k2),
                ((k, k2, a, b, ok, 1.0) for k, k2, a, b, ok, _, _ in
                 legal_moves(full, half_steps, p, turns)), False,
                np.array(starts, dtype=np.int32), 1.0)
    order = gil.run(breadth_first_order, lat, virtual, directed=True,
                    return_predecessors=False)
    got = np.zeros(virtual + 1, dtype=np.bool_)
    got[order] = True
    reached = got[:virtual].reshape(n, h, w).any(0)
    reached = ndi.distance_transform_edt(~reached) * p.resolution_m <= grow_m
    # lattice cell (a, b) is the map's (i0 + a·f, j0 + b·f): each covers f × f map cells
    up = np.repeat(np.repeat(reached, f, 0), f, 1)
    r0, c0 = i0 - f // 2, j0 - f // 2
    a0, a1 = max(r0, 0), min(r0 + up.shape[0], mh)
    b0, b1 = max(c0, 0), min(c0 + up.shape[1], mw)
    out = np.zeros((mh, mw), dtype=np.bool_)
    out[a0:a1, b0:b1] = ~up[a0 - r0:a1 - r0, b0 - c0:b1 - c0]
    return out & fld.passable
