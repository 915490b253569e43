"""Pure safety-monitor core: speed bounds from a laser scan and the current motion.

The chair's footprint is a rectangle in the chair frame (origin at the drive-axle centre, x
forward, y left): `front_m` ahead of the axle, `rear_m` behind it, `half_width_m` to each side,
grown by `padding_m`. For each direction of motion (forward, reverse, turn in place
counter-clockwise, clockwise) the core sweeps that rectangle along the path in small steps and
finds the free extent: how far (m, or rad) the chair can move before a scan point is inside it.
A point already inside the padded rectangle only blocks a direction that takes it deeper, so
the chair can always back or turn away from something it is touching.

Forward and reverse follow the current arc (curvature ω/v from odometry while moving in that
direction, else straight). The bound for a free extent d is the largest speed that still stops
within d − stop_margin after a reaction latency t_r at decel a:  v·t_r + v²/(2a) = d − margin.
The same with angular decel for ω (one symmetric bound: SafetyLimit has a single |ω| field).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

F64 = npt.NDArray[np.float64]


@dataclass(frozen=True)
class SafetyParams:
    front_m: float = 0.95  # footprint ahead of the drive axle (the laser sits at x = 0.86 m)
    rear_m: float = 0.25  # behind the axle
    half_width_m: float = 0.35  # 0.7 m wide
    padding_m: float = 0.05  # grown on every side (laser noise, mounting tolerance)
    decel_mps2: float = 1.0  # planned braking deceleration (comfort limit ~1 m/s²)
    reaction_s: float = 1.0  # latency margin: scan age + PID + chair controller lag (~1 s)
    stop_margin_m: float = 0.10  # stop this short of the obstacle
    alpha_radps2: float = 1.5  # planned angular deceleration
    stop_margin_rad: float = 0.05
    v_max_fwd_mps: float = 1.2  # caps of the published bounds (no obstacle in view)
    v_max_rev_mps: float = 0.5  # the laser cannot see behind the chair: back up slowly
    omega_max_radps: float = 1.0
    kappa_max_per_m: float = 3.0  # arc curvature is clamped to this (|ω/v| at low speed)
    moving_mps: float = 0.05  # |v| above this follows the arc, below it the path is straight
    step_m: float = 0.02  # sweep resolution
    step_rad: float = 0.02
    estop_decel_mps2: float = 2.0  # faster than this could not stop: imminent collision

    def check(self) -> str:
        """"" if sane, else why not (one line)."""
        for name in ("front_m", "rear_m", "half_width_m", "decel_mps2", "alpha_radps2",
                     "step_m", "step_rad", "estop_decel_mps2"):
            if not getattr(self, name) > 0:
                return f"{name} must be > 0"
        for name in ("padding_m", "reaction_s", "stop_margin_m", "stop_margin_rad",
                     "v_max_fwd_mps", "v_max_rev_mps", "omega_max_radps", "kappa_max_per_m",
                     "moving_mps"):
            if not getattr(self, name) >= 0:
                return f"{name} must be ≥ 0"
        return ""


@dataclass(frozen=True)
class Limit:
    v_fwd: float
    v_rev: float
    omega: float
    free_fwd_m: float  # free extent along the forward path (inf = beyond the horizon)
    free_rev_m: float
    free_ccw_rad: float
    free_cw_rad: float
    nearest_m: float  # nearest scan point to the unpadded footprint (inf: none)
    imminent: bool  # moving faster than could stop within the free extent at estop_decel
    reason: str


def scan_points(ranges: F64, angle_min: float, angle_inc: float, range_min: float,
                range_max: float, mount: tuple[float, float, float]) -> F64:
    """Valid beams (finite, within the device's range window) as (N, 2) chair-frame points."""
    r = np.asarray(ranges, dtype=np.float64)
    a = angle_min + angle_inc * np.arange(r.size)
    ok = np.isfinite(r) & (r >= range_min) & (r <= range_max)
    r, a = r[ok], a[ok] + mount[2]
    return np.column_stack((mount[0] + r * np.cos(a), mount[1] + r * np.sin(a)))


def stop_speed(free: float, decel: float, latency: float, margin: float) -> float:
    """Largest speed that stops within free − margin after `latency` at `decel`."""
    d = free - margin
    if d <= 0:
        return 0.0
    if math.isinf(d):
        return math.inf
    return -decel * latency + math.sqrt((decel * latency) ** 2 + 2 * decel * d)


class SafetyCore:
    def __init__(self, params: SafetyParams) -> None:
        err = params.check()
        if err:
            raise ValueError(err)
        self.p = params
        p = params
        lin = p.v_max_fwd_mps * p.reaction_s + p.v_max_fwd_mps ** 2 / (2 * p.decel_mps2)
        self.horizon_m = lin + p.stop_margin_m + 0.5  # a little beyond the longest stop
        self.horizon_rad = min(math.pi, p.omega_max_radps * p.reaction_s
                               + p.omega_max_radps ** 2 / (2 * p.alpha_radps2)
                               + p.stop_margin_rad + 0.2)
        # No pose of any sweep puts the padded footprint beyond this distance from the axle:
        # points farther away cannot block, and dropping them first saves most of the work.
        self.reach_m = self.horizon_m + math.hypot(max(p.front_m, p.rear_m) + p.padding_m,
                                                   p.half_width_m + p.padding_m)

    def _penetration(self, pts: F64, x: F64, y: F64, th: F64, pad: float) -> F64:
        """(K, N): how deep each point is inside the rectangle at each pose (> 0 inside)."""
        p = self.p
        dx = pts[None, :, 0] - x[:, None]
        dy = pts[None, :, 1] - y[:, None]
        c, s = np.cos(th)[:, None], np.sin(th)[:, None]
        lx, ly = c * dx + s * dy, -s * dx + c * dy
        return np.minimum(np.minimum(p.front_m + pad - lx, lx + p.rear_m + pad),
                          p.half_width_m + pad - np.abs(ly))

    def _free(self, pts: F64, x: F64, y: F64, th: F64, steps: F64) -> float:
        """Free extent along poses (x, y, th)[k] reached after steps[k] (steps[0] = 0)."""
        if pts.shape[0] == 0:
            return math.inf
        pen = self._penetration(pts, x, y, th, self.p.padding_m)
        start = pen[0]
        blocked = (pen[1:] > 0) & ((start <= 0)[None, :] | (pen[1:] > start[None, :] + 1e-9))
        hit = np.flatnonzero(blocked.any(axis=1))
        return math.inf if hit.size == 0 else float(steps[hit[0]])  # last free step

    def _arc(self, kappa: float, sign: float) -> tuple[F64, F64, F64, F64]:
        s = np.arange(0.0, self.horizon_m + self.p.step_m, self.p.step_m)
        d = sign * s
        if abs(kappa) < 1e-6:
            return d, np.zeros_like(d), np.zeros_like(d), s
        th = kappa * d
        return np.sin(th) / kappa, (1 - np.cos(th)) / kappa, th, s

    def limit(self, pts: F64, v: float, omega: float) -> Limit:
        """Bounds for chair-frame scan points `pts` (N, 2) while moving at (v, ω)."""
        p = self.p
        close = pts[np.hypot(pts[:, 0], pts[:, 1]) <= self.reach_m]
        kappa = 0.0
        if abs(v) > p.moving_mps:
            kappa = max(-p.kappa_max_per_m, min(p.kappa_max_per_m, omega / v))
        free_fwd = self._free(close, *self._arc(kappa if v > 0 else 0.0, 1.0))
        free_rev = self._free(close, *self._arc(kappa if v < 0 else 0.0, -1.0))
        phi = np.arange(0.0, self.horizon_rad + p.step_rad, p.step_rad)
        zero = np.zeros_like(phi)
        free_ccw = self._free(close, zero, zero, phi, phi)
        free_cw = self._free(close, zero, zero, -phi, phi)
        v_fwd = min(p.v_max_fwd_mps, stop_speed(free_fwd, p.decel_mps2, p.reaction_s,
                                                p.stop_margin_m))
        v_rev = min(p.v_max_rev_mps, stop_speed(free_rev, p.decel_mps2, p.reaction_s,
                                                p.stop_margin_m))
        w = min(p.omega_max_radps, stop_speed(min(free_ccw, free_cw), p.alpha_radps2,
                                              p.reaction_s, p.stop_margin_rad))
        nearest = math.inf
        if pts.shape[0]:
            nearest = max(0.0, -float(self._penetration(
                pts, np.zeros(1), np.zeros(1), np.zeros(1), 0.0).max()))
        # Could not stop even braking at estop_decel with no latency: a collision is imminent.
        free = free_fwd if v > 0 else free_rev
        imminent = abs(v) > p.moving_mps and v * v > 2 * p.estop_decel_mps2 * free
        reason = ("clear" if min(free_fwd, free_rev) == math.inf and w >= p.omega_max_radps
                  else f"free fwd {free_fwd:.2f} m rev {free_rev:.2f} m "
                       f"turn {min(free_ccw, free_cw):.2f} rad")
        return Limit(v_fwd=v_fwd, v_rev=v_rev, omega=w, free_fwd_m=free_fwd,
                     free_rev_m=free_rev, free_ccw_rad=free_ccw, free_cw_rad=free_cw,
                     nearest_m=nearest, imminent=imminent, reason=reason)
