"""The simulated chair: joystick voltages in, true motion and encoder counts out (pure, no clock).

Public API (stable; the control-law evaluation runs it in lockstep with the pure cores):

- `ChairParams`: geometry (wheel radius 0.049 m, base 0.367 m, 10000 counts/rev), plant
  parameters, optional noise. Frozen dataclass; override with `dataclasses.replace`.
- `ChairModel(params=ChairParams())`, `step(longitudinal_v, angular_v, dt)`: advance `dt`
  seconds with the two joystick voltages held (2.5 V neutral; longitudinal > 2.5 V = forward,
  angular > 2.5 V = turn left / counter-clockwise).
- State after each step: `t` (s), true pose `x`, `y` (m, world frame) and `yaw` (rad, REP-103,
  wrapped to (-pi, pi]), `v` (m/s), `omega` (rad/s), `v_left`/`v_right` (wheel surface speed,
  m/s) and encoder counts `left_counts`/`right_counts` (unbounded Python ints, quantised from
  the encoder wheels' travel; the firmware wraps them to u32).
- `effort(volts)`: joystick voltage to effort C = (V - 2.5)/1.5; `volts(effort)` the inverse.
- `ziegler_nichols(model_factory, axis)`: the thesis's tuning experiment, run on the model.

Drift (`drift=True`, off by default): the encoders count the rotation of encoder wheels whose
diameters differ (`diameter_ratio`), the chair turns about a base longer than the nominal one
(`base_ratio`), and the chair moves less over ground than its wheels roll: in turns (skid,
growing with |omega|) and when accelerating (spin, growing with |a|), plus seeded noise. The
true pose (x, y, yaw) follows the ground motion; the counts follow the wheels. Odometry with
the nominal geometry thus drifts like a real chair's, while the ground truth stays true.

Plant, per channel (longitudinal v, angular omega), in signal order:
  effort C -> saturation |C| <= 1 -> dead band (|C| < dead_band -> 0, rescaled beyond) ->
  full-stick speed K*C -> transport delay -> controller lag (per channel) -> wheel speed
  commands v -/+ omega*b/2 -> per-wheel drive lag -> body inertia.
The inertia couples the two wheels through the chair's mass and yaw inertia, so in mode
coordinates it is one lag for translation and another for rotation; the two channels thus have
different dynamics, as the thesis's different ultimate periods say they do.

Calibration: the thesis's Ku (1.5 / 1.2) with full-stick speeds near 1.8 means a loop gain of
only ~2.7 / ~2.2 at the ultimate frequency, and two or three lags cannot give -180 deg of phase
at such a low gain; hence ~0.25 s of transport delay besides the lags. The defaults were fitted
so `ziegler_nichols` gives Ku/Tu close to the thesis (figures in README.md, "Simulator").
"""

from __future__ import annotations

import math
import random
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

from autochair.geometry import wrap_angle
from autochair_msgs.keys import DRIVE_RATE_HZ  # the thesis's controller ran at 100 Hz too

NEUTRAL_V = 2.5
VOLTS_PER_EFFORT = 1.5


def effort(volts: float) -> float:
    return (volts - NEUTRAL_V) / VOLTS_PER_EFFORT


def volts(c: float) -> float:
    return NEUTRAL_V + VOLTS_PER_EFFORT * c


@dataclass(frozen=True, slots=True)
class ChairParams:
    wheel_radius_m: float = 0.049  # encoder wheel
    base_m: float = 0.367  # encoder wheel track
    counts_per_rev: int = 10000  # quadrature counts per encoder-wheel revolution
    v_full_mps: float = 1.75  # longitudinal speed at full stick (C = 1)
    omega_full_radps: float = 1.8  # yaw rate at full stick
    dead_band: float = 0.05  # |C| below this is no motion (controller's joystick dead band)
    delay_s: float = 0.25  # transport delay, joystick to controller output
    tau_v_s: float = 0.38  # controller lag, longitudinal channel
    tau_omega_s: float = 0.26  # controller lag, angular channel
    tau_drive_s: float = 0.20  # per-wheel motor drive lag
    tau_translation_s: float = 0.24  # inertia, common mode (mass)
    tau_rotation_s: float = 0.08  # inertia, differential mode (yaw inertia)
    # Optional noise (seeded): wheel-speed process noise and encoder-wheel slip.
    noise: bool = False
    seed: int = 0
    wheel_noise_mps: float = 0.01  # std of white noise on each wheel's speed
    slip_std: float = 0.01  # std of the relative error of encoder travel per step
    # Optional systematic odometry errors (UMBmark kind; seeded). The odometry's nominal
    # geometry stays wheel_radius_m/base_m; the chair's true geometry differs from it:
    drift: bool = False
    diameter_ratio: float = 1.004  # E_d = D_right / D_left of the encoder wheels (mean nominal)
    base_ratio: float = 1.02  # E_b = true effective base / base_m
    slip_turn_per_radps: float = 0.015  # rotation lost to skid, per rad/s of yaw rate
    slip_accel_per_mps2: float = 0.01  # travel lost to wheel spin, per m/s² of acceleration
    slip_noise: float = 0.003  # std of the random part of both slips, per step


def _lag(x: float, target: float, dt: float, tau: float) -> float:
    """Exact first-order lag update for a target held over dt."""
    return target if tau <= 0.0 else x + (target - x) * (1.0 - math.exp(-dt / tau))


class ChairModel:
    """True motion of the chair under two joystick voltages. Time is passed in (dt)."""

    def __init__(self, params: ChairParams | None = None) -> None:
        self.params = p = params or ChairParams()
        self._rng = random.Random(p.seed)
        self.t = 0.0
        self.x = 0.0
        self.y = 0.0
        self.yaw = 0.0
        self.v = 0.0
        self.omega = 0.0
        self.v_left = 0.0
        self.v_right = 0.0
        self.left_counts = 0
        self.right_counts = 0
        self._left_travel_m = 0.0  # encoder-wheel travel, unquantised
        self._right_travel_m = 0.0
        self._queue: deque[tuple[float, float, float]] = deque()  # (due time, v, omega)
        self._delayed = (0.0, 0.0)
        self._ctrl_v = 0.0  # controller lag outputs
        self._ctrl_w = 0.0
        self._drive_l = 0.0  # drive lag outputs (wheel speeds wanted of the inertia)
        self._drive_r = 0.0

    def _shape(self, c: float, full: float) -> float:
        c = max(-1.0, min(1.0, c))
        db = self.params.dead_band
        if abs(c) <= db:
            return 0.0
        return math.copysign((abs(c) - db) / (1.0 - db), c) * full

    def step(self, longitudinal_v: float, angular_v: float, dt: float) -> None:
        if dt <= 0.0:
            raise ValueError(f"dt must be > 0, got {dt}")
        p = self.params
        self._queue.append((self.t + p.delay_s,
                            self._shape(effort(longitudinal_v), p.v_full_mps),
                            self._shape(effort(angular_v), p.omega_full_radps)))
        self.t += dt
        # Transport delay: the latest target whose due time has come (zero-order hold).
        while self._queue and self._queue[0][0] <= self.t + 1e-9:
            _, vd, wd = self._queue.popleft()
            self._delayed = (vd, wd)
        vd, wd = self._delayed
        self._ctrl_v = _lag(self._ctrl_v, vd, dt, p.tau_v_s)
        self._ctrl_w = _lag(self._ctrl_w, wd, dt, p.tau_omega_s)
        half = 0.5 * p.base_m
        self._drive_l = _lag(self._drive_l, self._ctrl_v - self._ctrl_w * half, dt, p.tau_drive_s)
        self._drive_r = _lag(self._drive_r, self._ctrl_v + self._ctrl_w * half, dt, p.tau_drive_s)
        # Inertia in mode coordinates: translation (mean) and rotation (difference).
        v_target = 0.5 * (self._drive_l + self._drive_r)
        diff_target = self._drive_r - self._drive_l
        v_new = _lag(0.5 * (self.v_left + self.v_right), v_target, dt, p.tau_translation_s)
        diff_new = _lag(self.v_right - self.v_left, diff_target, dt, p.tau_rotation_s)
        vl, vr = v_new - 0.5 * diff_new, v_new + 0.5 * diff_new
        if p.noise:
            vl += self._rng.gauss(0.0, p.wheel_noise_mps)
            vr += self._rng.gauss(0.0, p.wheel_noise_mps)
        self._integrate(vl, vr, dt)

    def _slip(self, vl: float, vr: float, dt: float) -> tuple[float, float]:
        """Ground travel / wheel travel and ground rotation / wheel rotation (nominal base)
        for the new wheel speeds vl, vr: 1, 1 without drift."""
        p = self.params
        if not p.drift:
            return 1.0, 1.0
        accel = abs(0.5 * (vl + vr) - 0.5 * (self.v_left + self.v_right)) / dt
        rate = abs(vr - vl) / (p.base_m * p.base_ratio)
        s_turn = p.slip_turn_per_radps * rate + self._rng.gauss(0.0, p.slip_noise)
        s_acc = p.slip_accel_per_mps2 * accel + self._rng.gauss(0.0, p.slip_noise)
        return 1.0 - s_acc, (1.0 - s_turn) / p.base_ratio

    def _integrate(self, vl: float, vr: float, dt: float) -> None:
        p = self.params
        # Trapezoidal wheel travel over the step, then the exact arc for the pose.
        dl = 0.5 * (self.v_left + vl) * dt
        dr = 0.5 * (self.v_right + vr) * dt
        k_d, k_psi = self._slip(vl, vr, dt)
        self.v_left, self.v_right = vl, vr
        self.v = 0.5 * (vl + vr) * k_d
        self.omega = (vr - vl) / p.base_m * k_psi
        d = 0.5 * (dl + dr) * k_d
        dpsi = (dr - dl) / p.base_m * k_psi
        yaw0 = self.yaw
        if abs(dpsi) < 1e-9:
            self.x += d * math.cos(yaw0)
            self.y += d * math.sin(yaw0)
        else:
            yaw1 = yaw0 + dpsi
            self.x += d / dpsi * (math.sin(yaw1) - math.sin(yaw0))
            self.y -= d / dpsi * (math.cos(yaw1) - math.cos(yaw0))
        self.yaw = wrap_angle(yaw0 + dpsi)
        if p.noise:
            dl *= 1.0 + self._rng.gauss(0.0, p.slip_std)
            dr *= 1.0 + self._rng.gauss(0.0, p.slip_std)
        self._left_travel_m += dl
        self._right_travel_m += dr
        r_left = r_right = p.wheel_radius_m
        if p.drift:  # encoder-wheel diameters differ, their mean is the nominal one
            r_left, r_right = (2.0 * p.wheel_radius_m / (1.0 + p.diameter_ratio),
                               2.0 * p.wheel_radius_m * p.diameter_ratio / (1.0 + p.diameter_ratio))
        turns = p.counts_per_rev / (2.0 * math.pi)
        self.left_counts = math.floor(self._left_travel_m / r_left * turns)
        self.right_counts = math.floor(self._right_travel_m / r_right * turns)


# --- Ziegler–Nichols experiment ---------------------------------------------------------------

Axis = Literal["longitudinal", "angular"]


def p_control_trace(model: ChairModel, axis: Axis, kp: float, setpoint: float, step: float,
                    duration_s: float, dt: float, preroll_s: float = 20.0,
                    preroll_ki: float = 0.2) -> tuple[list[float], bool]:
    """The thesis's tuning run: settle at `setpoint` with a slow integral loop (the "manual
    reset"), freeze its effort C0 as bias, step the setpoint by `step` and run the P-only loop
    C = C0 + kp*(setpoint + step - measured), C in [-1, 1], for `duration_s`.

    Returns the measured velocity of every P-loop step and whether the effort left the linear
    range (saturation or dead band) in the last two thirds of the run. The bias keeps the loop
    small-signal, so the dead band does not turn growth into a limit cycle. The other axis is
    held neutral.
    """

    def measure() -> float:
        return model.v if axis == "longitudinal" else model.omega

    def apply(c: float) -> None:
        if axis == "longitudinal":
            model.step(volts(c), NEUTRAL_V, dt)
        else:
            model.step(NEUTRAL_V, volts(c), dt)

    c0 = 0.0
    for _ in range(round(preroll_s / dt)):
        c0 = max(-1.0, min(1.0, c0 + preroll_ki * (setpoint - measure()) * dt))
        apply(c0)
    out: list[float] = []
    nonlinear = False
    n = round(duration_s / dt)
    for i in range(n):
        measured = measure()
        c = c0 + kp * (setpoint + step - measured)
        if i > n // 3 and (abs(c) >= 1.0 or abs(c) <= model.params.dead_band):
            nonlinear = True
        apply(max(-1.0, min(1.0, c)))
        out.append(measured)
    return out, nonlinear


def _swing(trace: list[float]) -> float:
    return max(trace) - min(trace)


def _period(trace: list[float], dt: float) -> float:
    mean = sum(trace) / len(trace)
    ups = [i for i in range(1, len(trace)) if trace[i - 1] < mean <= trace[i]]
    if len(ups) < 2:
        return math.nan
    return (ups[-1] - ups[0]) * dt / (len(ups) - 1)


def ziegler_nichols(model_factory: Callable[[], ChairModel], axis: Axis, *,
                    setpoint: float = 0.5, step: float = 0.1, dt: float = 1.0 / DRIVE_RATE_HZ,
                    duration_s: float = 30.0, kp_lo: float = 0.1, kp_hi: float = 10.0,
                    iterations: int = 16) -> tuple[float, float]:
    """Ultimate gain and period (Ku, Tu) of `axis`, found like the thesis did it: raise Kp
    until the oscillation neither decays nor grows. Bisection on the growth of the swing
    between the middle and the last third of a P-only run (see `p_control_trace`); the
    period is from the mean crossings of the run at the upper bracket."""

    def growing(kp: float) -> tuple[bool, list[float]]:
        trace, nonlinear = p_control_trace(model_factory(), axis, kp, setpoint, step,
                                           duration_s, dt)
        n = len(trace) // 3
        grows = _swing(trace[2 * n:]) > max(_swing(trace[n:2 * n]), 1e-9)
        return nonlinear or grows, trace[n:]

    if growing(kp_lo)[0] or not growing(kp_hi)[0]:
        raise ValueError(f"no ultimate gain for {axis} in [{kp_lo}, {kp_hi}]")
    lo, hi = kp_lo, kp_hi
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        if growing(mid)[0]:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi), _period(growing(hi)[1], dt)
