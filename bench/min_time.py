"""The honest reference for the control-law suite: the least time ANY controller could take to
move a unicycle chair from rest at one pose to rest at another under the comfort limits.

Model (the chair as the limiter commands it, no drive-chain lag): x' = v cos θ, y' = v sin θ,
θ' = ω; v' = a, a' = j_v; ω' = α, α' = j_ω, with |a| ≤ a_max, |j_v| ≤ jerk_max, |ω| ≤ ω_max,
|α| ≤ ω̇_max, |j_ω| ≤ ω-jerk max, and 0 ≤ v ≤ v_max: forward only, because autonomy may not
reverse where the laser cannot see (safety/core.py: `v_rev_autonomy` = 0 unless the rear is
seen or `blind_reverse_autonomy_mps` allows it; the scan does not cover the back of the chair).
`v_min` < 0 gives the reference with reversing allowed, for comparison.

Method: direct multiple-shooting-free control parametrisation (single shooting): the jerks are
piecewise constant over N equal segments of the free final time T; within a segment v, a, θ,
ω, α are exact polynomials and x, y are integrated by 3-point Gauss–Legendre. SLSQP minimises
T subject to the end pose and rest, the bounds on the jerks, and the bounds on v, a, ω, α at the
segment ends (a and α are linear within a segment, so theirs are exact; v and ω are checked
densely afterwards). Gradients: forward differences of a batched (numpy) simulation. Starts:
turn–drive–turn S-curve profiles (both turn directions where that matters), solved on a coarse
grid, then refined. It is a local method: the result is the best local optimum found, an upper
bound on the true minimum (and piecewise-constant jerks on a grid add a little); checked on
cases with a known answer (tests/test_min_time.py: a straight line gives the S-curve bound,
an in-place turn the rotational one).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import minimize

from autochair.control.core import ControlConfig

Array = np.ndarray[Any, Any]
CACHE = Path(__file__).parent / "results" / "min_time.json"  # solved once: ~10 min for 28
GL_T = np.array([0.5 - math.sqrt(15) / 10, 0.5, 0.5 + math.sqrt(15) / 10])  # nodes in [0, 1]
GL_W = np.array([5.0, 8.0, 5.0]) / 18.0


@dataclass(frozen=True)
class Limits:
    v_max: float
    a_max: float
    jerk_max: float
    w_max: float
    wdot_max: float
    wjerk_max: float
    v_min: float = 0.0  # forward only (see the module doc)

    @classmethod
    def of(cls, cfg: ControlConfig | None = None) -> Limits:
        """The comfort limits the control law runs with (one source: ControlConfig)."""
        c = cfg or ControlConfig()
        return cls(c.vmax_mps, c.a_max_mps2, c.jerk_max_mps3, c.omega_max_radps,
                   c.omega_acc_max_radps2, c.omega_jerk_max_radps3)


@dataclass(frozen=True)
class Result:
    time_s: float
    ok: bool
    end_error: float  # worst of the end-pose (m, rad) and rest errors
    violation: float  # worst relative bound excess, sampled densely (0 = none)
    detail: str


def scurve_phases(dist: float, vmax: float, amax: float, jmax: float) -> list[tuple[float, float]]:
    """Rest-to-rest S-curve over |dist| as (duration, jerk) phases, jerk signed as dist."""
    d = abs(dist)
    if d <= 0.0:
        return []
    s = 1.0 if dist > 0 else -1.0

    def shape(vp: float) -> tuple[float, float]:  # (jerk time, constant-acceleration time)
        if vp >= amax * amax / jmax:
            return amax / jmax, vp / amax - amax / jmax
        return math.sqrt(vp / jmax), 0.0

    def covered(vp: float) -> float:
        tj, ta = shape(vp)
        return vp * (2 * tj + ta)

    if covered(vmax) <= d:
        vp, tv = vmax, (d - covered(vmax)) / vmax
    else:
        lo, hi = 0.0, vmax
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if covered(mid) < d else (lo, mid)
        vp, tv = lo, 0.0
    tj, ta = shape(vp)
    j = s * jmax
    return [(tj, j), (ta, 0.0), (tj, -j), (tv, 0.0), (tj, -j), (ta, 0.0), (tj, j)]


def simulate(T: Array, uv: Array, uw: Array, start: tuple[float, float, float]) -> dict[str, Array]:
    """Batched: T (B,), jerks (B, N). Node values (B, N+1) of every state."""
    B, N = uv.shape
    h = (T / N)[:, None] if np.ndim(T) else np.full((B, 1), T / N)
    h = h[:, 0]
    x = np.full(B, start[0])
    y = np.full(B, start[1])
    th = np.full(B, start[2])
    v = np.zeros(B)
    a = np.zeros(B)
    w = np.zeros(B)
    al = np.zeros(B)
    out = {k: np.zeros((B, N + 1)) for k in ("x", "y", "th", "v", "a", "w", "al")}
    for k, val in (("x", x), ("y", y), ("th", th)):
        out[k][:, 0] = val
    tq = h[:, None] * GL_T[None, :]  # (B, 3)
    for i in range(N):
        jv, jw = uv[:, i], uw[:, i]
        vq = v[:, None] + a[:, None] * tq + jv[:, None] * tq ** 2 / 2
        thq = th[:, None] + w[:, None] * tq + al[:, None] * tq ** 2 / 2 + jw[:, None] * tq ** 3 / 6
        x = x + h * np.sum(GL_W * vq * np.cos(thq), axis=1)
        y = y + h * np.sum(GL_W * vq * np.sin(thq), axis=1)
        th = th + w * h + al * h ** 2 / 2 + jw * h ** 3 / 6
        w = w + al * h + jw * h ** 2 / 2
        al = al + jw * h
        v = v + a * h + jv * h ** 2 / 2
        a = a + jv * h
        for k, val in (("x", x), ("y", y), ("th", th), ("v", v), ("a", a), ("w", w),
                       ("al", al)):
            out[k][:, i + 1] = val
    return out


class Problem:
    def __init__(self, start: tuple[float, float, float], goal: tuple[float, float, float],
                 lim: Limits, n: int) -> None:
        self.start, self.goal, self.lim, self.n = start, goal, lim, n

    def unpack(self, z: Array) -> tuple[Array, Array, Array]:
        """Rows of z: [T, sv (N), sw (N)], jerks scaled to [-1, 1]."""
        z = np.atleast_2d(z)
        n = self.n
        return z[:, 0], z[:, 1:n + 1] * self.lim.jerk_max, z[:, n + 1:] * self.lim.wjerk_max

    def constraints(self, z: Array) -> tuple[Array, Array]:
        """(equalities, inequalities ≥ 0), batched over rows of z: shapes (B, ·)."""
        T, uv, uw = self.unpack(z)
        s = simulate(T, uv, uw, self.start)
        g, L = self.goal, self.lim
        eq = np.stack([s["x"][:, -1] - g[0], s["y"][:, -1] - g[1], s["th"][:, -1] - g[2],
                       s["v"][:, -1], s["a"][:, -1], s["w"][:, -1], s["al"][:, -1]], axis=1)
        v, a, w, al = (s[k][:, 1:-1] for k in ("v", "a", "w", "al"))
        ineq = np.concatenate([(L.v_max - v) / L.v_max, (v - L.v_min) / L.v_max,
                               1 - a / L.a_max, 1 + a / L.a_max,
                               1 - w / L.w_max, 1 + w / L.w_max,
                               1 - al / L.wdot_max, 1 + al / L.wdot_max], axis=1)
        return eq, ineq

    def jacobians(self, z: Array, eps: float = 1e-7) -> tuple[Array, Array, Array, Array]:
        zz = np.vstack([z, z + eps * np.eye(len(z))])
        eq, ineq = self.constraints(zz)
        return eq[0], ineq[0], ((eq[1:] - eq[0]) / eps).T, ((ineq[1:] - ineq[0]) / eps).T

    def solve(self, z0: Array, maxiter: int = 300) -> Array:
        cache: dict[str, Any] = {}

        def get(z: Array) -> tuple[Array, Array, Array, Array]:
            key = z.tobytes()
            if cache.get("key") != key:
                cache["key"], cache["val"] = key, self.jacobians(z)
            return cache["val"]  # type: ignore[no-any-return]

        n = self.n
        bounds = [(0.05, 120.0)] + [(-1.0, 1.0)] * (2 * n)
        res = minimize(lambda z: z[0], z0, jac=lambda z: np.eye(len(z))[0], method="SLSQP",
                       bounds=bounds, options={"maxiter": maxiter, "ftol": 1e-9},
                       constraints=[{"type": "eq", "fun": lambda z: get(z)[0],
                                     "jac": lambda z: get(z)[2]},
                                    {"type": "ineq", "fun": lambda z: get(z)[1],
                                     "jac": lambda z: get(z)[3]}])
        return np.asarray(res.x)

    def check(self, z: Array, dense: int = 40) -> tuple[float, float]:
        """(end error, worst relative bound excess on a grid `dense` times finer)."""
        T, uv, uw = self.unpack(z)
        eq, _ = self.constraints(z)
        fine = Problem(self.start, self.goal, self.lim, self.n * dense)
        s = simulate(T, np.repeat(uv, dense, axis=1), np.repeat(uw, dense, axis=1), self.start)
        L = fine.lim
        exc = max(float(np.max(s["v"])) / L.v_max - 1,
                  (L.v_min - float(np.min(s["v"]))) / L.v_max,
                  float(np.max(np.abs(s["a"]))) / L.a_max - 1,
                  float(np.max(np.abs(s["w"]))) / L.w_max - 1,
                  float(np.max(np.abs(s["al"]))) / L.wdot_max - 1)
        return float(np.max(np.abs(eq))), max(exc, 0.0)


def resample(phases: list[tuple[float, float, float]], T: float, n: int) -> tuple[Array, Array]:
    """(duration, jerk_v, jerk_w) phases → the mean jerks over n equal segments of T."""
    edges = np.cumsum([0.0] + [p[0] for p in phases])
    grid = np.linspace(0.0, T, n + 1)
    out = np.zeros((2, n))
    for (d, jv, jw), t0 in zip(phases, edges[:-1], strict=True):
        if d <= 0:
            continue
        lo = np.clip(grid[:-1], t0, t0 + d)
        hi = np.clip(grid[1:], t0, t0 + d)
        out[0] += jv * (hi - lo) / (T / n)
        out[1] += jw * (hi - lo) / (T / n)
    return out[0], out[1]


def tdt_start(start: tuple[float, float, float], goal: tuple[float, float, float], lim: Limits,
              flip: int) -> tuple[float, list[tuple[float, float, float]], float]:
    """A turn–drive–turn initial guess: (T, phases, the goal yaw's unwrapped value). `flip`
    turns the first (±1) or last (±2) turn the long way round."""
    (sx, sy, syaw), (gx, gy, gyaw) = start, goal
    d = math.hypot(gx - sx, gy - sy)
    head = math.atan2(gy - sy, gx - sx) if d > 1e-6 else syaw
    t1 = math.remainder(head - syaw, 2 * math.pi)
    if d <= 1e-6:
        t1 = 0.0
    t2 = math.remainder(gyaw - head, 2 * math.pi)
    if abs(flip) == 1 and t1:
        t1 -= math.copysign(2 * math.pi, t1)
    if abs(flip) == 2 and t2:
        t2 -= math.copysign(2 * math.pi, t2)
    ph: list[tuple[float, float, float]] = []
    ph += [(t, 0.0, j) for t, j in scurve_phases(t1, lim.w_max, lim.wdot_max, lim.wjerk_max)]
    ph += [(t, j, 0.0) for t, j in scurve_phases(d, lim.v_max, lim.a_max, lim.jerk_max)]
    ph += [(t, 0.0, j) for t, j in scurve_phases(t2, lim.w_max, lim.wdot_max, lim.wjerk_max)]
    T = sum(p[0] for p in ph)
    return T, ph, syaw + t1 + t2


def _near_half_turn(start: tuple[float, float, float], goal: tuple[float, float, float],
                    flip: int) -> bool:
    d = math.hypot(goal[0] - start[0], goal[1] - start[1])
    head = math.atan2(goal[1] - start[1], goal[0] - start[0]) if d > 1e-6 else start[2]
    if d <= 1e-6:
        return flip == 2 and abs(math.remainder(goal[2] - start[2], 2 * math.pi)) > 2.5
    turn = head - start[2] if flip == 1 else goal[2] - head
    return abs(math.remainder(turn, 2 * math.pi)) > 2.5


def min_time(start: tuple[float, float, float], goal: tuple[float, float, float],
             lim: Limits | None = None, n: int = 48, coarse: int = 24) -> Result:
    """The least rest-to-rest time found (see the module doc)."""
    lim = lim or Limits.of()
    best: Result | None = None
    for flip in (0, 1, 2):
        if flip and not _near_half_turn(start, goal, flip):
            continue  # the long way round only competes for a turn of about half a circle
        T0, ph, gyaw = tdt_start(start, goal, lim, flip)
        if T0 <= 0:
            return Result(0.0, True, 0.0, 0.0, "already there")
        g = (goal[0], goal[1], gyaw)
        z: Array | None = None
        for m in (coarse, n):
            pb = Problem(start, g, lim, m)
            if z is None:
                uv, uw = resample(ph, T0 * 1.05, m)  # a little slack: the grid blurs phases
                z0 = np.concatenate([[T0 * 1.05], uv / lim.jerk_max, uw / lim.wjerk_max])
            else:  # refine: each coarse segment split in two (same controls, same T)
                k = m // (len(z) // 2)
                z0 = np.concatenate([[z[0]], np.repeat(z[1:coarse + 1], k),
                                     np.repeat(z[coarse + 1:], k)])
            z = pb.solve(np.clip(z0, [0.05] + [-1] * 2 * m, [120] + [1] * 2 * m))
        assert z is not None
        err, exc = Problem(start, g, lim, n).check(z)
        r = Result(float(z[0]), err < 1e-3 and exc < 0.02, err, exc, f"start {flip}")
        if best is None or (r.ok and (not best.ok or r.time_s < best.time_s)):
            best = r
    assert best is not None
    return best


Pose = tuple[float, float, float]


def _key(start: Pose, goal: Pose, lim: Limits) -> str:
    return json.dumps([list(start), list(goal), asdict(lim)])


def cached(start: Pose, goal: Pose, lim: Limits, path: Path = CACHE) -> Result:
    """min_time, from the cache file when this case and these limits were solved before
    (else solved now, slowly, and added)."""
    data: dict[str, Any] = json.loads(path.read_text()) if path.exists() else {}
    k = _key(start, goal, lim)
    if k not in data:
        data[k] = asdict(min_time(start, goal, lim))
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(data, indent=0) + "\n")
    return Result(**data[k])


def lookup(start: Pose, goal: Pose, lim: Limits, path: Path = CACHE) -> Result | None:
    """min_time from the cache file, None if this case and these limits were not solved."""
    data = json.loads(path.read_text()) if path.exists() else {}
    r = data.get(_key(start, goal, lim))
    return None if r is None else Result(**r)


def main(argv: list[str] | None = None) -> int:
    """Solve (or read) the reference for the suite's cases whose names contain an argument."""
    import sys
    import time

    from .control_eval import suite

    args = sys.argv[1:] if argv is None else argv
    for name, s, g in suite():
        if args and not any(a in name for a in args):
            continue
        t0 = time.perf_counter()
        r = cached(s, g, Limits.of())
        print(f"{name:32s} {r.time_s:6.3f} s ok={r.ok} err={r.end_error:.1e} "
              f"exc={r.violation:.3f} {r.detail} ({time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
