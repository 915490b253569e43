"""Comfort limiter: jerk-limited (S-curve) tracking of the desired (v, ω). PURE, dt injected.

Not clipping: each axis is a double integrator (value, rate) driven by a bounded third
derivative, so the rate (acceleration) is continuous and bounded. The rate is steered onto the
discrete braking curve: the rate from which the remaining error can still be removed by ramping
the rate down at the jerk limit, which is what makes it stop on the commanded value without
overshoot (for any target it can reach in time). v is limited first; ω is then rescaled by the
factor v was limited by, so the curvature (the path) is kept while the chair speeds up or brakes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace


@dataclass(frozen=True)
class ComfortLimits:
    v_max_mps: float = 1.2
    a_max_mps2: float = 1.0
    jerk_max_mps3: float = 2.0
    omega_max_radps: float = 0.9
    omega_acc_max_radps2: float = 2.8
    omega_jerk_max_radps3: float = 7.7  # ω̈ bound of the 2011 wheelchair paper


class SCurveAxis:
    """One axis: |value| ≤ vmax, |rate| ≤ amax, |Δrate/dt| ≤ jmax."""

    def __init__(self, vmax: float, amax: float, jmax: float) -> None:
        if not (vmax > 0 and amax > 0 and jmax > 0):
            raise ValueError("limits must be > 0")
        self.vmax, self.amax, self.jmax = vmax, amax, jmax
        self.value = 0.0
        self.rate = 0.0

    def reset(self, value: float = 0.0, rate: float = 0.0) -> None:
        self.value = max(-self.vmax, min(self.vmax, value))
        self.rate = max(-self.amax, min(self.amax, rate))

    def braking_rate(self, error: float, dt: float) -> float:
        """Largest rate (signed as `error`) from which jerk-limited braking ends on the target.

        Applying rate m·J·dt, then (m−1)·J·dt, … 0 moves the value by J·dt²·m(m+1)/2; solve for m.
        """
        e = abs(error)
        jd = self.jmax * dt
        # whole steps (floor): a fractional last step would overshoot the target slightly
        m = math.floor(-0.5 + math.sqrt(0.25 + 2.0 * e / (jd * dt)) + 1e-9)
        return math.copysign(min(self.amax, m * jd), error)

    def step(self, target: float, dt: float) -> float:
        if dt <= 0.0:
            return self.value
        target = max(-self.vmax, min(self.vmax, target))
        e = target - self.value
        jd = self.jmax * dt
        land = e / dt  # the rate that lands exactly on the target this step
        if abs(land) <= jd and abs(land - self.rate) <= jd:
            self.value, self.rate = target, land  # the next step then takes the rate to 0
            return self.value
        want = self.braking_rate(e, dt)
        rate = self.rate + max(-jd, min(jd, want - self.rate))
        self.rate = max(-self.amax, min(self.amax, rate))
        self.value = max(-self.vmax, min(self.vmax, self.value + self.rate * dt))
        return self.value


class ComfortLimiter:
    """Both axes, curvature-preserving."""

    def __init__(self, lim: ComfortLimits | None = None, lookahead_s: float = 0.2) -> None:
        self.lim = self.base = lim or ComfortLimits()
        self.lookahead_s = lookahead_s
        self.v = SCurveAxis(self.lim.v_max_mps, self.lim.a_max_mps2, self.lim.jerk_max_mps3)
        self.w = SCurveAxis(self.lim.omega_max_radps, self.lim.omega_acc_max_radps2,
                            self.lim.omega_jerk_max_radps3)

    def reset(self, v: float = 0.0, omega: float = 0.0) -> None:
        self.v.reset(v)
        self.w.reset(omega)

    def cap_omega(self, omega_max: float) -> None:
        """Bound |ω| below the comfort limit (e.g. by the safety monitor's turn-rate bound), so
        the curvature-preserving scaling slows v too instead of a clamp downstream bending
        the path; a larger value restores the comfort limit."""
        w = min(self.base.omega_max_radps, max(omega_max, 0.0))
        if w != self.lim.omega_max_radps:
            self.lim = replace(self.lim, omega_max_radps=w)
            self.w.vmax = w

    @property
    def at_rest(self) -> bool:
        return self.v.value == 0.0 and self.v.rate == 0.0 and self.w.value == 0.0 \
            and self.w.rate == 0.0

    def step(self, v_des: float, omega_des: float, dt: float) -> tuple[float, float]:
        # Over the speed or turn-rate bound: scale both, so the curvature is unchanged.
        s = 1.0
        if abs(omega_des) > self.lim.omega_max_radps:
            s = self.lim.omega_max_radps / abs(omega_des)
        if abs(v_des) * s > self.lim.v_max_mps:
            s = self.lim.v_max_mps / abs(v_des)
        # Slow down while the turn rate is still catching up with the curvature (e.g. turning
        # the other way): the chair then stays on the path instead of overshooting it, which
        # near the goal, where κ ~ 1/r, is what made the thesis's chair oscillate.
        kappa = omega_des / v_des if abs(v_des) * s > 1e-3 else 0.0
        if kappa != 0.0:  # (a denormal ω can make κ underflow to 0)
            # (signed as ω: backwards, ω and κ have opposite signs)
            reach = math.copysign(1.0, omega_des) * self.w.value \
                + self.w.amax * self.lookahead_s
            s = min(s, max(reach, 0.0) / abs(kappa) / abs(v_des))
        v_des, omega_des = v_des * s, omega_des * s
        v = self.v.step(v_des, dt)
        # Keep κ = ω/v while v is still ramping (start, braking); in-place turns (v_des ≈ 0)
        # track ω directly.
        w_t = omega_des * (v / v_des) if abs(v_des) > 1e-3 else omega_des
        return v, self.w.step(w_t, dt)
