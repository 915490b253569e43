"""The least time to drive a given path at the comfort limits, forward only (nav_eval's reference).

The chair (a unicycle: x' = v cos θ, y' = v sin θ, θ' = ω) starts at rest at the path's start
facing `yaw0`, turns in place onto the path's first heading, drives the path from rest to rest,
and turns in place onto the goal's yaw. The turns are rest-to-rest S-curves (|ω| ≤ ω_max,
|ω̇| ≤ ω̇_max, |ω jerk| ≤ its max: bench/control_eval.py `scurve_time`, the shorter way round).
The drive is the least-time speed profile along the path (a time-optimal path parameterisation)
with 0 ≤ v ≤ v_max, |a| ≤ a_max, |jerk| ≤ jerk_max and, as ω = v·κ on a path of curvature κ,
|ω| ≤ ω_max, |ω̇| ≤ ω̇_max and |ω jerk| ≤ its max (the limits of bench/min_time.py `Limits`).

The path's bends (`bends`): a polyline's turn at each joint is smoothed along it (a Gaussian of
σ metres, one per turn; what would fall past an end joins that end's turn in place, and a turn
in place may be spread forwards into the path), then any turn sharper than `kappa_max` is
spread, half to each neighbour, until none is, and all are eased over `SETTLE_M` (a step in
curvature is a step in ω = v·κ, so v = 0 there, and the grid would decide how much of it
counts). The total turn is kept; the path those turns give is sheared to end on the goal and
returned with its own turns, for the caller to check against the map (`fit`: per turn the
largest σ of a ladder that keeps the path clear).

Speed profile (`drive_time`): v at nodes (`grid`: 2 mm apart at the ends, where from rest v
grows as t² and a coarse grid fits worst, growing ×1.3 to 0.1 m within a metre of a bend and
0.25 m elsewhere), v = 0 at both ends. Between nodes the acceleration is constant (a = Δ(v²)/2h,
the time 2h/(v_i + v_i+1)) and ω is the interval's heading change (κ linear between the joints,
integrated) over its time; jerk and ω̇ are the changes of a and ω from one interval to the next
over the time between their centres (from and to 0 at rest), ω jerk the change of ω̇ across an
interval. SLSQP minimises the time from an acceleration-limited start. Checked on analytic
cases (tests/test_path_time.py): a straight line against the S-curve (±0.2 % from 0.3 m), an
arc against the S-curve at the limits the arc leaves (v ≤ ω_max·r, a ≤ ω̇_max·r, jerk ≤ ω-jerk
max·r; ±0.5 %), turn–drive–turn against the sum of the three S-curves. On nav_eval's paths the
0.1 m spacing reads up to 2.5 % faster than 0.05 m (a doorway's bends; ≤ 0.5 % elsewhere).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.optimize import minimize

from autochair.geometry import wrap_angle as wrap
from bench.control_eval import scurve_time
from bench.min_time import Limits

Array = np.ndarray[Any, Any]
H_BEND, H_STRAIGHT = 0.1, 0.25  # node spacing (m) near bends and elsewhere
# Every path's turns are smoothed over this (σ, m) after the spread: a step in curvature would
# ask for a step in ω (ω = v·κ), so for v = 0 there, and the grid would decide how much of it
# the speed profile sees.
SETTLE_M = 0.1
V_FLOOR = 1e-3  # interior nodes stay moving (the time 2h/(v_i + v_i+1) must stay finite)


def turn_time(angle: float, lim: Limits) -> float:
    """Rest-to-rest in-place turn by `angle`, the shorter way round (jerk-limited S-curve)."""
    return scurve_time(abs(wrap(angle)), lim.w_max, lim.wdot_max, lim.wjerk_max)


def _rates(v: Array, dtheta: Array, h: Array) -> tuple[Array, ...]:
    """Batched over rows of v (B, N+1), the speeds at the nodes: per interval its time, a and ω
    (its heading change `dtheta` over its time); jerk and ω̇ at the nodes (the change of a, ω
    from one interval to the next over the time between their centres; 0 beyond the ends, at
    rest); ω jerk per interval (the change of ω̇ across it over its time)."""
    t = 2 * h / (v[:, :-1] + v[:, 1:])
    a = (v[:, 1:] ** 2 - v[:, :-1] ** 2) / (2 * h)
    w = dtheta / t
    z = np.zeros((len(v), 1))
    gap = 0.5 * (np.hstack([z, t]) + np.hstack([t, z]))

    def change(x: Array) -> Array:
        return np.asarray(np.diff(np.hstack([z, x, z]), axis=1) / gap)

    wd = change(w)
    return t, a, w, change(a), wd, np.diff(wd, axis=1) / t


def grid(length: float, h_max: Any = H_BEND, h_end: float = 0.002, growth: float = 1.3) -> Array:
    """Node arc lengths from 0 to `length`: h_end apart at both ends (from rest, where v grows
    as t² and constant-acceleration intervals fit worst), growing by `growth` up to h_max
    (metres, or a function of the arc length)."""
    cap = h_max if callable(h_max) else (lambda _s: h_max)
    s = [0.0]
    while True:
        h = min(cap(s[-1]), h_end + (growth - 1) * min(s[-1], length - s[-1]))
        if s[-1] + 1.5 * h >= length:
            break
        s.append(s[-1] + h)
    s.append(length)
    out: Array = np.array(s)
    return out


def drive_time(s: Array, dtheta: Array, lim: Limits) -> tuple[float, Array]:
    """Least rest-to-rest time along a path with nodes at arc lengths `s` (N+1) turning by
    `dtheta` (rad) between them (N), and the speed at the nodes."""
    n = len(s) - 1
    h = np.diff(s)
    dtheta = np.where(np.abs(dtheta) < 1e-7, 0.0, dtheta)  # (straight: no ω rows, below)
    # |ω| ≤ ω_max over an interval: v_i + v_i+1 ≤ 2h ω_max / |Δθ|, so each v under that
    side = 2 * h * lim.w_max / np.maximum(np.abs(dtheta), 1e-12)
    vcap = np.minimum(lim.v_max, np.minimum(np.append(side, np.inf), np.insert(side, 0, np.inf)))
    # start: forward-backward passes at half the acceleration (jerk-feasible enough to begin)
    v = vcap.copy()
    v[0] = v[-1] = 0.0
    for idx in (range(1, n + 1), range(n - 1, -1, -1)):
        for i in idx:
            j = i - 1 if idx.step == 1 else i + 1
            v[i] = min(v[i], math.sqrt(v[j] ** 2 + lim.a_max * h[min(i, j)]))
    scale = np.array([lim.a_max, lim.w_max, lim.jerk_max, lim.wdot_max, lim.wjerk_max])

    def full(x: Array) -> Array:
        x = np.atleast_2d(x)
        z = np.zeros((len(x), 1))
        return np.hstack([z, x, z])

    def rows(x: Array) -> Array:  # ≥ 0: a, ω, jerk, ω̇, ω jerk within their limits
        _, *r = _rates(full(x), dtheta[None], h)
        return np.hstack([c for q, sc in zip(r, scale, strict=True)
                          for c in (1 - q / sc, 1 + q / sc)])

    def jac(x: Array, keep: Any = slice(None), eps: float = 1e-7) -> Array:
        c = rows(np.vstack([x, x + eps * np.eye(len(x))]))[:, keep]  # forward differences
        return np.asarray((c[1:] - c[0]) / eps).T

    x0 = np.maximum(v[1:-1], V_FLOOR)
    # Rows that no speed changes (ω on the straight: 0) are left out: SLSQP's time grows
    # with their number.
    live = np.any(jac(x0) != 0.0, axis=1)

    def cons(x: Array) -> Array:
        return rows(x)[:, live]

    def cons_jac(x: Array) -> Array:
        return jac(x, live)

    def time_of(x: Array) -> float:
        return float(np.sum(2 * h / (full(x)[0, :-1] + full(x)[0, 1:])))

    def time_jac(x: Array) -> Array:
        vf = full(x)[0]
        g = -2 * h / (vf[:-1] + vf[1:]) ** 2  # d(interval time)/d(either end's v)
        return np.asarray(g[:-1] + g[1:])

    res = minimize(time_of, x0, jac=time_jac, method="SLSQP",
                   bounds=[(V_FLOOR, c) for c in vcap[1:-1]],
                   constraints=[{"type": "ineq", "fun": lambda x: cons(x)[0],
                                 "jac": cons_jac}],
                   options={"maxiter": 500, "ftol": 1e-10})
    x = np.asarray(res.x)
    # (SLSQP may stop at its line search's precision, feasible: its result is kept if so)
    assert res.success or cons(x).min() > -1e-3, res.message
    return time_of(x), full(x)[0]


def smooth_turns(turns: Array, at: Array, length: float, sigma: Array) -> Array:
    """Turns (rad): [in place at the start, at the joints `at` (arc length) of a path `length`
    long, in place at the end], each spread as a Gaussian of its own σ (`sigma`, m, one per
    turn; 0: kept where it is) over the joints. What falls past an end joins that end's turn
    in place; a turn in place is spread forwards from its end (half a Gaussian) into the
    path. The total turn is kept."""
    from scipy.special import erfc

    sg = np.maximum(sigma, 1e-9)[None, :]
    src = np.concatenate([[0.0], at, [length]])[None, :]
    w = np.exp(-0.5 * ((at[:, None] - src) / sg) ** 2)  # (to joint, from turn)
    lo = 0.5 * erfc(src / (sg * math.sqrt(2)))[0]  # the tails past the ends
    hi = 0.5 * erfc((length - src) / (sg * math.sqrt(2)))[0]
    lo[0] = hi[-1] = 0.0  # (a turn in place goes wholly into the path)
    w *= (1 - lo - hi) / np.maximum(w.sum(axis=0), 1e-300)
    out: Array = np.concatenate([[lo @ turns], w @ turns, [hi @ turns]])
    keep = sigma <= 0
    out[1:-1] -= w[:, keep] @ turns[keep]
    out[0] -= lo[keep] @ turns[keep]
    out[-1] -= hi[keep] @ turns[keep]
    return out + np.where(keep, turns, 0.0)


def spread_turns(turns: Array, room: Array) -> Array:
    """Turns (rad) at a path's joints, each over its `room` moved in halves to its neighbours
    until none is (inf at the ends: the in-place turns take what reaches them)."""
    d: Array = turns.astype(float).copy()
    for _ in range(100000):
        e = np.sign(d) * np.maximum(np.abs(d) - room, 0.0)
        if not np.any(np.abs(e) > 1e-9):
            break
        d -= e
        d[:-1] += e[1:] / 2
        d[1:] += e[:-1] / 2
    return d


def _segments(xy: Array) -> tuple[Array, Array]:
    """A polyline's segments (M, 2) and their lengths, repeated points dropped."""
    seg = np.diff(xy, axis=0)
    ell = np.hypot(*seg.T)
    return seg[ell > 1e-6], ell[ell > 1e-6]


def _turns(seg: Array, yaw0: float, yaw1: float) -> Array:
    """[the turn in place onto the first segment, the turn at each joint, the turn in place
    from the last segment onto yaw1] (rad)."""
    th = np.unwrap(np.arctan2(seg[:, 1], seg[:, 0]))
    return np.concatenate([[wrap(th[0] - yaw0)], np.diff(th), [wrap(yaw1 - th[-1])]])


def bends(xy: Array, yaw0: float, yaw1: float, kappa_max: float, sigma: Array | float
          ) -> tuple[Array, Array]:
    """The polyline `xy` (N, 2) driven from heading yaw0 to yaw1, its bends smoothed: (turns,
    path). Its turns ([in place at the start, at each joint, in place at the end]) are smoothed
    (σ `sigma` m, one for all or one per turn: `smooth_turns`) and spread to curvature ≤
    `kappa_max`; the path they give (the same segment lengths) is sheared to end where `xy`
    ends, and the turns returned are that path's own."""
    seg, ell = _segments(xy)
    if len(ell) == 0:
        return np.array([0.0, wrap(yaw1 - yaw0)]), xy
    turns = _turns(seg, yaw0, yaw1)
    if np.any(np.asarray(sigma) > 0) and len(ell) > 1:
        at = np.cumsum(ell)[:-1]
        turns = smooth_turns(turns, at, float(ell.sum()), np.broadcast_to(sigma, turns.shape))
    room = np.concatenate([[np.inf], kappa_max * (ell[:-1] + ell[1:]) / 2, [np.inf]])
    d = spread_turns(turns, room)
    if len(ell) > 1:  # the curvature made continuous (an average of values ≤ kappa_max)
        sig = np.full(d.shape, SETTLE_M)
        sig[0] = sig[-1] = 0.0
        d = smooth_turns(d, np.cumsum(ell)[:-1], float(ell.sum()), sig)
    heading = yaw0 + np.cumsum(d[:-1])
    steps = ell[:, None] * np.stack([np.cos(heading), np.sin(heading)], axis=1)
    path = xy[0] + np.concatenate([[[0.0, 0.0]], np.cumsum(steps, axis=0)])
    frac = np.concatenate([[0.0], np.cumsum(ell)]) / ell.sum()
    path += frac[:, None] * (xy[-1] - path[-1])
    return _turns(np.diff(path, axis=0), yaw0, yaw1), path


def fit(xy: Array, yaw0: float, yaw1: float, kappa_max: float, ladder: tuple[float, ...],
        clear: Any) -> tuple[Array, Array, Array]:
    """Turns smoothed as much as the geometry allows: each turn's σ the largest of `ladder`
    (descending, ending in 0) for which the path `bends` gives keeps clear(path) ≥ 0 at every
    point; a turn's σ is lowered while a point within 3σ of it is not clear. Returns (turns,
    path, σ per turn)."""
    ell = _segments(xy)[1]
    n = len(ell) + 1
    if n < 3:
        sigma = np.zeros(n)
        return *bends(xy, yaw0, yaw1, kappa_max, sigma), sigma
    at = np.concatenate([[0.0], np.cumsum(ell)])  # arc length of each turn (and point)
    level = np.zeros(n, dtype=int)
    while True:
        sigma = np.array(ladder)[level]
        turns, path = bends(xy, yaw0, yaw1, kappa_max, sigma)
        bad = at[clear(path) < 0]
        near = np.zeros(n, dtype=bool)
        for s in bad:
            near |= np.abs(at - s) <= 3 * sigma
        lower = near & (level < len(ladder) - 1)
        if not lower.any():
            return turns, path, sigma
        level[lower] += 1


def path_time(xy: Array, yaw0: float, yaw1: float, lim: Limits, turns: Array | None = None
              ) -> dict[str, Any]:
    """Turn in place onto the path, drive it, turn in place onto yaw1 (see the module doc).
    `xy` (N, 2): the path as a polyline from the start to the goal; `turns`: its turns as
    `bends` gives them (default: the polyline's own, unsmoothed)."""
    ell = _segments(xy)[1]
    if len(ell) == 0:
        turn = wrap(yaw1 - yaw0)
        return {"time_s": turn_time(turn, lim), "turn_start_rad": 0.0, "turn_end_rad": turn,
                "drive_s": 0.0, "length_m": 0.0}
    d = _turns(_segments(xy)[0], yaw0, yaw1) if turns is None else turns
    # The curvature along the path: each joint's turn over the half segments either side,
    # linear between the joints (a step in κ would be a step in ω at speed), flat to the
    # ends; each interval's heading change its integral, scaled to keep the total turn.
    at = np.cumsum(ell)[:-1]
    kappa = d[1:-1] / ((ell[:-1] + ell[1:]) / 2)
    bent = at[np.abs(kappa) > 0.02]

    def h_max(s: float) -> float:  # finer where the path bends (within a metre)
        return H_BEND if len(bent) and np.min(np.abs(bent - s)) < 1.0 else H_STRAIGHT

    s = grid(float(ell.sum()), h_max)
    k = np.interp(s, at, kappa) if len(at) else np.zeros(len(s))
    dtheta = (k[:-1] + k[1:]) / 2 * np.diff(s)
    if abs(dtheta.sum()) > 1e-9:
        dtheta *= d[1:-1].sum() / dtheta.sum()
    drive, v = drive_time(s, dtheta, lim)
    return {"time_s": turn_time(d[0], lim) + drive + turn_time(d[-1], lim),
            "turn_start_rad": float(d[0]), "turn_end_rad": float(d[-1]), "drive_s": drive,
            "length_m": float(ell.sum()), "s": s, "v": v}
