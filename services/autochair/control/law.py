"""Park & Kuipers smooth local control law (ICRA 2011), as written in REFERENCE.md. PURE.

    α = atan2(yT − y, xT − x);  θ = wrap(ψT − α);  δ = wrap(ψ − α);  r = distance
    κ = −(1/r)·[k2·(δ − atan(−k1·θ)) + (1 + k1/(1 + (k1·θ)²))·sin δ];  ω = κ·v
    v = vmax / (1 + β·|κ|^λ);  near the goal v = min(vmax·r/r_thresh, v)

Unlike the thesis code (appendix B): atan2 (not atan, which flips the bearing of any goal
behind the chair), angles wrapped into (−π, π], and no ×4 fudge on ω.

Beyond the paper (documented in README "Smooth control law"):
- `align_omega`: the law is singular at r = 0 (κ ~ 1/r, α undefined), so once the position is
  inside the capture radius the goal manager stops translating and turns in place to the goal
  yaw with this braking-aware profile. The paper leaves the last centimetres to the feedback law,
  which is where the thesis saw oscillation.
- `omega_floor`: the law leaves v free (any v > 0 converges), but the paper's v(κ) makes
  |ω| = |κ|·v ≈ vmax/(β·|κ|) → 0 on tight curves, so a chair close to a goal but badly
  misaligned (goal just behind or beside it) creeps for tens of seconds. Raising v to keep
  |ω| ≥ omega_floor keeps the same curvature (the same manifold path), only faster.
- `braking_speed`: the paper's slowdown v = vmax·r/r_thresh asks for a deceleration of
  vmax/r_thresh·v (1.2 m/s² at full speed), more than the comfort limits allow, so the limited
  chair overran the goal. The goal manager also caps v at the speed from which a jerk-limited
  stop (derated limits, leaving the S-curve tracker headroom) ends on the goal.
- `slowdown=False` for pass-through waypoints (the chair should not stop at them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import msgspec
import numpy as np
import numpy.typing as npt

from autochair.geometry import wrap_angle as wrap


class Gains(msgspec.Struct, frozen=True):
    """Thesis / Park & Kuipers values: written once here; MPEPC's LawParams and the [control]
    section (ControlConfig) extend this."""

    k1: float = 1.5
    k2: float = 3.0
    beta: float = 0.4
    lam: float = 2.0
    vmax_mps: float = 1.2
    r_thresh_m: float = 1.2


@dataclass(frozen=True)
class LawOutput:
    v_mps: float
    omega_radps: float
    kappa_1pm: float  # curvature, 1/m
    r_m: float
    theta_rad: float
    delta_rad: float


def egocentric(x: float, y: float, yaw: float,
               xt: float, yt: float, yawt: float) -> tuple[float, float, float]:
    """(r, θ, δ) of the chair pose relative to the target pose."""
    alpha = math.atan2(yt - y, xt - x)
    return math.hypot(xt - x, yt - y), wrap(yawt - alpha), wrap(yaw - alpha)


def curvature(r: float, theta: float, delta: float, g: Gains) -> float:
    k1t = g.k1 * theta
    return -(1.0 / r) * (g.k2 * (delta - math.atan(-k1t))
                         + (1.0 + g.k1 / (1.0 + k1t * k1t)) * math.sin(delta))


def speed(kappa: float, r: float, g: Gains, vmax: float | None = None,
          slowdown: bool = True, omega_floor: float = 0.0) -> float:
    """v(κ) with the slowdown; `omega_floor` > 0 raises v (never above vmax or the slowdown)
    so that |ω| = |κ|·v stays ≥ omega_floor on tight curves (see module doc)."""
    vm = g.vmax_mps if vmax is None else vmax
    v = vm / (1.0 + g.beta * math.pow(abs(kappa), g.lam))
    if omega_floor > 0.0 and kappa != 0.0:
        v = max(v, min(vm, omega_floor / abs(kappa)))
    return min(vm * r / g.r_thresh_m, v) if slowdown else v


def park_kuipers(x: float, y: float, yaw: float, xt: float, yt: float, yawt: float,
                 g: Gains, vmax: float | None = None, slowdown: bool = True,
                 omega_floor: float = 0.0) -> LawOutput:
    """Desired (v, ω) towards the target pose. Zero at r = 0 (the law is undefined there)."""
    r, theta, delta = egocentric(x, y, yaw, xt, yt, yawt)
    if r < 1e-9:
        return LawOutput(0.0, 0.0, 0.0, r, theta, delta)
    kappa = curvature(r, theta, delta, g)
    v = speed(kappa, r, g, vmax, slowdown, omega_floor)
    return LawOutput(v, kappa * v, kappa, r, theta, delta)


def braking_speed(distance: float, a: float, j: float) -> float:
    """Highest speed from which a jerk-limited stop (|accel| ≤ a, |jerk| ≤ j, starting at zero
    acceleration) ends within `distance`: the inverse of d(v) = v·T/2 with T = v/a + a/j
    (or 2·√(v/j) when v < a²/j, where the acceleration never reaches a)."""
    if distance <= 0.0:
        return 0.0
    v = math.pow(distance * math.sqrt(j), 2.0 / 3.0)
    if v <= a * a / j:
        return v
    return 0.5 * (-a * a / j + math.sqrt((a * a / j) ** 2 + 8.0 * a * distance))


def heads_for(along: npt.ArrayLike, lateral: npt.ArrayLike, yaw_error: npt.ArrayLike,
              v: npt.ArrayLike, tol_m: float, omega_acc: float) -> npt.NDArray[np.bool_]:
    """Whether a chair at v heads for a goal `along` ahead of it and `lateral` beside its
    heading, whose yaw is `yaw_error` from its own: facing its way (within 90°: against it,
    the law loops round to it), on its line (within two tolerances) or able still to steer
    onto it before passing it (an S-turn at ω̇ = `omega_acc` shifts the chair 2·v·ω̇·T³
    sideways over 4T, i.e. ω̇·along³/32v² within `along`). Elementwise: the core asks it of
    the chair, MPEPC of each candidate it rolls out (Mpepc._law), the same test."""
    along, v, lat = np.asarray(along), np.asarray(v), np.abs(lateral)
    return np.asarray((along > 0.0) & (np.cos(yaw_error) > 0.0) & (
        (lat < 2.0 * tol_m) | (32.0 * lat * v * v <= omega_acc * np.maximum(along, 0.0) ** 3)))


def align_omega(yaw_error: float, omega_max: float, brake_radps2: float,
                gain_1ps: float) -> float:
    """In-place turn rate to remove `yaw_error` (goal yaw − yaw, wrapped).

    min of: the rate limit; the rate from which the chair can still brake to rest at the goal
    with `brake_radps2` (√(2·α·|e|), no overshoot); and a linear tail `gain·|e|` so the command
    reaches zero smoothly (a pure √ profile has infinite slope at e = 0 and chatters).
    """
    e = abs(yaw_error)
    w = min(omega_max, math.sqrt(2.0 * brake_radps2 * e), gain_1ps * e)
    return math.copysign(w, yaw_error) if e > 0.0 else 0.0
