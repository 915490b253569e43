"""Comfort limiter: jerk-limited (S-curve) tracking of the desired (v, ω). PURE, dt injected.

Not clipping: each axis is a double integrator (value, rate) driven by a bounded third
derivative, so the rate (acceleration) is continuous and bounded. The rate is steered onto the
discrete braking curve: the rate from which the remaining error can still be removed by ramping
the rate down at the jerk limit, which is what makes it stop on the commanded value without
overshoot (for any target it can reach in time). v is limited first; ω is then rescaled by the
factor v was limited by, so the curvature (the path) is kept while the chair speeds up or brakes.

Point-to-point (`move`): an in-place turn to a yaw, a straight final onto a goal. Each axis
covers a given distance time-optimally and ends at rest, with the same limits, by ruckig's
position interface (Berscheid & Kröger 2021: the time-optimal third-order profile from any
state), replanned every step from the axis's own state and the distance left. The tracker
above cannot do this: steering the rate onto a braking curve for a *velocity* leaves a position
target to a √-profile with a derated brake and an exponential tail (measured: a 45° turn took
4.2 s against 1.56 s for the jerk-limited optimum).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from ruckig import ControlInterface, InputParameter, Result, Ruckig, RuckigError, Trajectory


@dataclass(frozen=True)
class ComfortLimits:
    v_max_mps: float = 1.2
    a_max_mps2: float = 1.0
    jerk_max_mps3: float = 2.0
    omega_max_radps: float = 0.9
    omega_acc_max_radps2: float = 2.8
    omega_jerk_max_radps3: float = 7.7  # ω̈ bound of the 2011 wheelchair paper


# An SCurveAxis's state: (value, rate), its move's profile state and what its last move step
# left (SCurveAxis.save)
AxisState = tuple[float, float, tuple[float, float], tuple[float, float]]


class SCurveAxis:
    """One axis: |value| ≤ vmax, |rate| ≤ amax, |Δrate/dt| ≤ jmax."""

    def __init__(self, vmax: float, amax: float, jmax: float) -> None:
        if not (vmax > 0 and amax > 0 and jmax > 0):
            raise ValueError("limits must be > 0")
        self.vmax, self.amax, self.jmax = vmax, amax, jmax
        self.value = 0.0
        self.rate = 0.0
        self._otg = Ruckig(1)
        self._inp = InputParameter(1)
        self._traj = Trajectory(1)
        # move's inputs that are the same every step, set once (setting ruckig's inputs is
        # much of a move's cost: MPEPC steps hundreds a planning cycle, Mpepc.spin_step);
        # amax and jmax are not changed after this (cap_omega changes vmax only); the bounds
        # are set again only when a move's `lim` differs from what they hold (_move_lim)
        inp = self._inp
        inp.current_position, inp.target_velocity, inp.target_acceleration = [0.0], [0.0], [0.0]
        inp.max_acceleration, inp.max_jerk = [amax], [jmax]
        self._move_lim = (amax, jmax)  # what move's inputs hold
        # The profile's own (velocity, acceleration) at the end of the last move step, and the
        # (value, rate) that step left: the plan continues from the former while nothing else
        # has stepped the axis since.
        self._plan_state = (0.0, 0.0)
        self._left = (math.nan, math.nan)

    def reset(self, value: float = 0.0, rate: float = 0.0) -> None:
        self.value = max(-self.vmax, min(self.vmax, value))
        self.rate = max(-self.amax, min(self.amax, rate))

    def save(self) -> AxisState:
        """The axis's whole state (a move under way included), for `load`: one axis can
        step many in turn (MPEPC's in-place candidates: making an axis costs ~5 moves)."""
        return self.value, self.rate, self._plan_state, self._left

    def load(self, state: AxisState) -> None:
        self.value, self.rate, self._plan_state, self._left = state

    def __deepcopy__(self, memo: dict[int, object]) -> SCurveAxis:
        """The same axis state (ruckig's objects cannot be copied; each move re-plans anyway)."""
        c = SCurveAxis(self.vmax, self.amax, self.jmax)
        c.load(self.save())
        return c

    def braking_rate(self, error: float, dt: float,
                     lim: tuple[float, float] | None = None) -> float:
        """Largest rate (signed as `error`) from which jerk-limited braking ends on the target
        (|rate|, |jerk| ≤ `lim`, default the axis's).

        Applying rate m·J·dt, then (m−1)·J·dt, … 0 moves the value by J·dt²·m(m+1)/2; solve for m.
        """
        amax, jmax = (self.amax, self.jmax) if lim is None else lim
        e = abs(error)
        jd = jmax * dt
        # whole steps (floor): a fractional last step would overshoot the target slightly
        m = math.floor(-0.5 + math.sqrt(0.25 + 2.0 * e / (jd * dt)) + 1e-9)
        return math.copysign(min(amax, m * jd), error)

    def step(self, target: float, dt: float, lim: tuple[float, float] | None = None) -> float:
        """One step towards `target` (|rate|, |jerk| ≤ `lim`, default the axis's)."""
        if dt <= 0.0:
            return self.value
        amax, jmax = (self.amax, self.jmax) if lim is None else lim
        target = max(-self.vmax, min(self.vmax, target))
        e = target - self.value
        jd = jmax * dt
        land = e / dt  # the rate that lands exactly on the target this step
        if abs(land) <= jd and abs(land - self.rate) <= jd:
            self.value, self.rate = target, land  # the next step then takes the rate to 0
            return self.value
        want = self.braking_rate(e, dt, (amax, jmax))
        rate = self.rate + max(-jd, min(jd, want - self.rate))
        self.rate = max(-amax, min(amax, rate))
        self.value = max(-self.vmax, min(self.vmax, self.value + self.rate * dt))
        return self.value


    @property
    def moving(self) -> bool:
        """A move (below) is under way: the axis was last stepped by it and it has not ended."""
        return self._left == (self.value, self.rate) and self._plan_state != (0.0, 0.0)

    def move(self, distance: float, dt: float, vmax: float | None = None,
             lim: tuple[float, float] | None = None) -> float:
        """One step of the time-optimal move that covers `distance` from the current (value,
        rate) and ends at rest, never moving against `distance` (|value| ≤ `vmax`, default the
        axis's bound; |rate|, |jerk| ≤ `lim`, default the axis's). Moving away from it, or
        unable to stop on it without turning back, it brakes to rest by the shortest
        jerk-limited stop (and never turns back)."""
        if dt <= 0.0:
            return self.value
        vm = min(self.vmax, self.vmax if vmax is None else vmax)
        lim = (self.amax, self.jmax) if lim is None else lim
        if lim != self._move_lim:
            self._inp.max_acceleration, self._inp.max_jerk = [lim[0]], [lim[1]]
            self._move_lim = lim
        # From the tracker (values held over a step, rate = their difference): the velocity at
        # the step's end is half a step of rate beyond the value held over it.
        pv, pa = self._plan_state if self._left == (self.value, self.rate) else (
            self.value + 0.5 * self.rate * dt, self.rate)
        inp = self._inp
        inp.current_velocity, inp.current_acceleration = [pv], [pa]
        inp.target_position = [distance]
        # One-signed velocity: the profile never turns back (no overshoot reversal).
        inp.max_velocity, inp.min_velocity = ([vm], [0.0]) if distance >= 0 else ([0.0], [-vm])
        inp.control_interface = ControlInterface.Position
        if distance * pv < 0.0 or not self._plan():
            # Too close to stop on it without turning back (the prediction moved the goal by
            # more than the time-optimal profile's zero slack): the shortest stop instead, by
            # the same exact integration, so the jerk stays bounded across the switch.
            inp.control_interface = ControlInterface.Velocity
            inp.max_velocity, inp.min_velocity = [self.vmax], [-self.vmax]
            if not self._plan():
                return self.step(0.0, dt)
        # Sent: the mean velocity over the step, so that the command, held for the step as the
        # chair is commanded, covers exactly what the profile does (the end value would leave
        # a remainder each step that the next plan chases in a creeping tail). The rate is
        # that of what is sent (the tracker's convention, so a hand-over to it is smooth);
        # the profile's own state is kept for the next plan.
        old = self.value
        if self._traj.duration <= dt:  # it ends within this step: cover the rest, then rest
            pos = self._traj.at_time(self._traj.duration)[0][0]
            self.value = pos / dt if abs(pos) > 1e-9 else 0.0
            self._plan_state = (0.0, 0.0)
        else:
            pos, vel, acc = (x[0] for x in self._traj.at_time(dt))
            self.value = max(-self.vmax, min(self.vmax, pos / dt))
            self._plan_state = (vel, acc)
        self.rate = max(-self.amax, min(self.amax, (self.value - old) / dt))
        self._left = (self.value, self.rate)
        return self.value

    def _plan(self) -> bool:
        try:
            return self._otg.calculate(self._inp, self._traj) in (Result.Working, Result.Finished)
        except RuckigError:
            return False


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

    def move(self, v_to: float | None, w_to: float | None, dt: float,
             vmax: float | None = None, v_lim: tuple[float, float] | None = None
             ) -> tuple[float, float]:
        """Point-to-point: an axis given a distance covers it time-optimally and ends at rest
        (SCurveAxis.move; v at most `vmax`, its acceleration and jerk within `v_lim`); an axis
        given None brakes to rest."""
        v = self.v.step(0.0, dt, v_lim) if v_to is None else self.v.move(v_to, dt, vmax, v_lim)
        w = self.w.step(0.0, dt) if w_to is None else self.w.move(w_to, dt)
        return v, w

    def step(self, v_des: float, omega_des: float, dt: float,
             v_lim: tuple[float, float] | None = None) -> tuple[float, float]:
        """(v, ω) one step towards (v_des, ω_des) within the limits (v's acceleration and jerk
        within `v_lim`, default its axis's)."""
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
        v = self.v.step(v_des, dt, v_lim)
        # Keep κ = ω/v while v is still ramping (start, braking); in-place turns (v_des ≈ 0)
        # track ω directly.
        w_t = omega_des * (v / v_des) if abs(v_des) > 1e-3 else omega_des
        return v, self.w.step(w_t, dt)
