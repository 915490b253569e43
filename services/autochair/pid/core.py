"""Pure PID (after simple-pid and control_toolbox) and the two-axis velocity controller.

Derivative on measurement through a first-order filter (time constant Td/N), Ki inside the
integral (gain changes are bumpless), clamping anti-windup, output saturation; dt is passed in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

NEUTRAL_V = 2.5
VOLTS_PER_EFFORT = 1.5  # thesis eq. 5.17: V = 1.5·C + 2.5


@dataclass
class PID:
    kp: float
    ki: float
    kd: float
    out_min: float = -1.0
    out_max: float = 1.0
    d_filter_n: float = 10.0  # derivative filter: Tf = (Kd/Kp)/N
    integral: float = 0.0  # already multiplied by Ki
    _d: float = 0.0  # filtered derivative of the measurement
    _prev_meas: float | None = None

    def reset(self, measurement: float | None = None, output: float = 0.0) -> None:
        """Bumpless restart: the next output continues from `output` with no derivative kick."""
        self._d = 0.0
        self._prev_meas = measurement
        self.integral = min(max(output, self.out_min), self.out_max)

    def update(self, setpoint: float, measurement: float, dt: float) -> float:
        if dt <= 0:
            raise ValueError("dt must be > 0")
        error = setpoint - measurement
        if self._prev_meas is not None and self.kd > 0:
            tf = (self.kd / self.kp) / self.d_filter_n if self.kp > 0 else 0.0
            raw = -(measurement - self._prev_meas) / dt  # derivative on measurement: no kick
            alpha = dt / (tf + dt)
            self._d += alpha * (raw - self._d)
        self._prev_meas = measurement
        p, d = self.kp * error, self.kd * self._d
        candidate = self.integral + self.ki * error * dt
        # Clamping anti-windup: integrate only if that does not push further into saturation.
        unsat = p + candidate + d
        if not ((unsat > self.out_max and error > 0) or (unsat < self.out_min and error < 0)):
            self.integral = min(max(candidate, self.out_min), self.out_max)
        return min(max(p + self.integral + d, self.out_min), self.out_max)


@dataclass(frozen=True)
class PidOutput:
    v_effort: float
    omega_effort: float
    longitudinal_v: float
    angular_v: float
    active: bool


@dataclass
class VelocityPidCore:
    """Two PIDs (longitudinal, angular) with the thesis's Ziegler–Nichols gains by default."""

    v_gains: tuple[float, float, float] = (0.90, 1.03, 0.20)
    omega_gains: tuple[float, float, float] = (0.72, 1.08, 0.12)
    min_v: float = 1.1  # joystick window, volts
    max_v: float = 3.9
    stale_s: float = 0.3  # desired velocity older than this → zero effort
    stop_eps: float = 0.02  # |desired| and |measured| below this with a zero goal → exact neutral
    require_limit: bool = False  # True: no fresh safety limit → desired (0, 0)
    limit_stale_s: float = 0.5
    owner: str = "autonomy"  # whose commands count: "autonomy" (CMD_VEL) or "teleop"
    v_pid: PID = field(init=False)
    omega_pid: PID = field(init=False)
    _desired: tuple[float, float] = (0.0, 0.0)
    _desired_t: float = -math.inf
    _active: bool = False
    _limit: tuple[float, float, float] | None = None  # fwd, rev (> 0), |ω| bounds
    _limit_t: float = -math.inf

    def __post_init__(self) -> None:
        lo = (self.min_v - NEUTRAL_V) / VOLTS_PER_EFFORT
        hi = (self.max_v - NEUTRAL_V) / VOLTS_PER_EFFORT
        self.v_pid = PID(*self.v_gains, out_min=lo, out_max=hi)
        self.omega_pid = PID(*self.omega_gains, out_min=lo, out_max=hi)

    def set_desired(self, v: float, omega: float, now_s: float,
                    source: str = "autonomy") -> str:
        """Take a desired velocity from `source`: "ok", "rejected" (not finite) or "not_owner"."""
        if not (math.isfinite(v) and math.isfinite(omega)):
            return "rejected"
        if source != self.owner:
            return "not_owner"
        self._desired, self._desired_t = (v, omega), now_s
        return "ok"

    def set_owner(self, owner: str) -> bool:
        """Hand the drive to "autonomy" or "teleop"; the previous owner's command is dropped."""
        if owner not in ("autonomy", "teleop"):
            return False
        if owner != self.owner:
            self.owner, self._desired_t = owner, -math.inf
        return True

    def set_limit(self, v_fwd: float, v_rev: float, omega: float, now_s: float) -> bool:
        if not all(math.isfinite(x) and x >= 0 for x in (v_fwd, v_rev, omega)):
            return False
        self._limit, self._limit_t = (v_fwd, v_rev, omega), now_s
        return True

    def desired(self, now_s: float) -> tuple[float, float] | None:
        """The desired velocity within the safety limit, or None when it is stale."""
        if now_s - self._desired_t > self.stale_s:
            return None
        v, omega = self._desired
        limit = self._limit if now_s - self._limit_t <= self.limit_stale_s else None
        if limit is None:
            return (0.0, 0.0) if self.require_limit else (v, omega)
        fwd, rev, w = limit
        return min(max(v, -rev), fwd), min(max(omega, -w), w)

    def update(self, v_meas: float, omega_meas: float, dt: float, now_s: float) -> PidOutput:
        desired = self.desired(now_s)
        at_rest = desired is not None and desired == (0.0, 0.0) and \
            abs(v_meas) < self.stop_eps and abs(omega_meas) < self.stop_eps
        if desired is None or at_rest or dt <= 0:
            # Stale or parked: exact neutral, integrators cleared for a bumpless restart.
            self._active = False
            self.v_pid.reset(v_meas)
            self.omega_pid.reset(omega_meas)
            return PidOutput(0.0, 0.0, NEUTRAL_V, NEUTRAL_V, False)
        if not self._active:
            self._active = True
            self.v_pid.reset(v_meas)
            self.omega_pid.reset(omega_meas)
        cv = self.v_pid.update(desired[0], v_meas, dt)
        cw = self.omega_pid.update(desired[1], omega_meas, dt)
        return PidOutput(cv, cw, effort_to_volts(cv, self.min_v, self.max_v),
                         effort_to_volts(cw, self.min_v, self.max_v), True)


def effort_to_volts(c: float, min_v: float = 1.1, max_v: float = 3.9) -> float:
    return min(max(VOLTS_PER_EFFORT * c + NEUTRAL_V, min_v), max_v)
