"""Auto-tune of the velocity loops (PURE: no clock, no I/O; time and samples passed in).

Two open-loop probes of one axis around a settled operating point (setpoint r, effort u0):

- relay (Åström–Hägglund, with hysteresis ε): u = u0 ± d, switching when the error r − y leaves
  ±ε (ε above the measurement noise, so noise cannot chatter the relay). The loop settles
  into a limit cycle at about the ultimate frequency: Tu is its period and, by the describing
  function of the relay, Ku = 4d/(πa) with a the half peak-to-peak amplitude of y.
- step: u = u0 + Δ held; its response gives the model of the drive chain (`fit_step`).

Model structure: SOPDT, second-order plus dead time, per axis: y = K·(u − u_db)·e^{−θs} /
((τ1 s + 1)(τ2 s + 1)), where u_db is the joystick dead band seen as an effort offset. Why: the
chain is a transport delay (joystick controller) and a cascade of lags (controller filter, motor
drive, body inertia). A first-order model (FOPDT) lumps all but one lag into the dead time,
which is fine for PI rules but then its feed-forward would need an instant second derivative
and its prediction would be wrong in acceleration, the very quantity the comfort limits bound.
Two lags capture the acceleration/jerk shape; smaller lags go into θ and τ2 (Skogestad's half
rule does the same), so a third lag would be poorly identifiable from one step anyway.

Gain rules (parallel PID: u = Kp·e + Ki∫e + Kd·de/dt, as `autochair.pid.core.PID`):
- ZN: the thesis's table 5.1 (Kp = 0.6 Ku, Ki = 2 Kp/Tu, Kd = Kp·Tu/8).
- TL: Tyreus–Luyben (Kp = Ku/2.2, Ti = 2.2 Tu, Td = Tu/6.3), gentler, from the relay alone.
- SIMC: Skogestad's rule on the SOPDT model with τc = θ (Kc = τ1/(K(τc+θ)), τI = min(τ1,
  4(τc+θ)), τD = τ2, series form converted to parallel): the model-based choice.
"""

from __future__ import annotations

import enum
import itertools
import math
from dataclasses import dataclass, field

import numpy as np

AXES = ("longitudinal", "angular")


class ProbeKind(enum.Enum):
    RELAY = "relay"
    STEP = "step"


class ProbeState(enum.Enum):
    RUNNING = "running"
    DONE = "done"
    ABORTED = "aborted"


@dataclass
class Probe:
    """One open-loop probe of one axis: the effort offset from the bias u0 to apply now.

    Bounded by construction: the offset is ±amplitude at most, it ends after `duration_s`
    (relay: also after `cycles` whole periods), and `speed_bound` ends it (aborted) as soon as
    |y| exceeds it. It records (t, y, u) for the analysis."""

    kind: ProbeKind
    axis: str
    amplitude: float  # d (relay) or Δ (step), effort units
    hysteresis: float = 0.02  # ε, measurement units (relay)
    duration_s: float = 15.0
    cycles: int = 8  # relay: whole periods wanted
    speed_bound: float = 1.0  # |y| above this aborts
    setpoint: float = 0.0  # r, set when started
    bias: float = 0.0  # u0, set when started
    t0: float = 0.0
    state: ProbeState = ProbeState.RUNNING
    reason: str = ""
    trace: list[tuple[float, float, float]] = field(default_factory=list)  # (t − t0, y, u)
    _high: bool = True
    _rises: int = 0

    def check(self) -> str:
        """'' if the bounds make sense, else why not."""
        if self.axis not in AXES:
            return f"axis must be one of {AXES}, not {self.axis!r}"
        if not 0 < self.amplitude <= 0.5:
            return f"amplitude must be within (0, 0.5] of effort, not {self.amplitude}"
        if not 0 <= self.hysteresis <= 0.2:
            return f"hysteresis must be within [0, 0.2], not {self.hysteresis}"
        if not 0 < self.duration_s <= 60:
            return f"duration_s must be within (0, 60], not {self.duration_s}"
        if not 0 < self.speed_bound <= 1.5:
            return f"speed_bound must be within (0, 1.5], not {self.speed_bound}"
        return ""

    def start(self, setpoint: float, bias: float, now_s: float) -> None:
        self.setpoint, self.bias, self.t0 = setpoint, bias, now_s
        self._high = True  # the first half-cycle pushes towards larger y

    def effort(self, y: float, now_s: float) -> float | None:
        """The effort (bias + offset) for measurement y, or None once ended (see `state`)."""
        if self.state is not ProbeState.RUNNING:
            return None
        t = now_s - self.t0
        if not math.isfinite(y) or abs(y) > self.speed_bound:
            self.end(ProbeState.ABORTED, f"|y| {abs(y):.2f} beyond the bound "
                                         f"{self.speed_bound:g}")
            return None
        if t > self.duration_s:
            self.end(ProbeState.DONE, "duration")
            return None
        if self.kind is ProbeKind.STEP:
            u = self.bias + self.amplitude
        else:
            e = self.setpoint - y
            if e > self.hysteresis and not self._high:
                self._high = True
                self._rises += 1
                if self._rises > self.cycles:
                    self.end(ProbeState.DONE, "cycles")
                    return None
            elif e < -self.hysteresis:
                self._high = False
            u = self.bias + (self.amplitude if self._high else -self.amplitude)
        self.trace.append((t, y, u))
        return u

    def is_(self, state: ProbeState) -> bool:
        """(a call, so a type checker does not keep a narrowed state across updates)"""
        return self.state is state

    def end(self, state: ProbeState, reason: str) -> None:
        if self.state is ProbeState.RUNNING:
            self.state, self.reason = state, reason


# --- analysis ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class RelayResult:
    ku: float
    tu_s: float
    amplitude: float  # a: half peak-to-peak of y
    cycles: int  # periods used
    period_spread: float  # (max − min)/median of those periods: < ~0.1 = a steady limit cycle
    # The chain's frequency response at the cycle's frequency, from the first harmonics of y
    # and u over those whole periods: exact for a linear chain in a periodic cycle, where
    # Ku = 4d/(πa) is the describing function's approximation (harmonics inflate a).
    point: complex = complex(math.nan, math.nan)

    @property
    def ku_h1(self) -> float:
        """1/|G(jω)| at the cycle's frequency: the ultimate gain without the approximation."""
        return 1.0 / abs(self.point)


def relay_result(trace: list[tuple[float, float, float]], d: float, skip: int = 2) -> RelayResult:
    """Ku = 4d/(πa), Tu from the relay's rising switches, skipping the first `skip` periods
    (the transient from the operating point into the limit cycle)."""
    t = np.array([s[0] for s in trace])
    y = np.array([s[1] for s in trace])
    u = np.array([s[2] for s in trace])
    rises = np.flatnonzero(u[1:] > u[:-1])  # index before each low → high switch
    if len(rises) < skip + 2:
        raise ValueError(f"only {len(rises)} relay periods: no steady limit cycle")
    rises = rises[skip:]
    periods = np.diff(t[rises])
    amps = [0.5 * float(np.ptp(y[a:b + 1])) for a, b in itertools.pairwise(rises)]
    tu = float(np.median(periods))
    a = float(np.median(amps))
    first, last = rises[0] + 1, rises[-1] + 1  # whole periods, rising switch to rising switch
    w = 2.0 * math.pi * len(periods) / float(t[last] - t[first])
    e = np.exp(-1j * w * t[first:last])
    point = complex(np.sum(y[first:last] * e) / np.sum(u[first:last] * e))
    return RelayResult(4.0 * d / (math.pi * a), tu, a, len(periods),
                       float(np.ptp(periods) / tu), point)


@dataclass(frozen=True)
class ChainModel:
    """SOPDT of one axis: y = K·(u − u_db·sign)·e^{−θs}/((τ1 s + 1)(τ2 s + 1)), τ1 ≥ τ2."""

    gain: float  # K, (m/s or rad/s) per unit effort, beyond the dead band
    dead_band: float  # u_db, effort
    tau1_s: float
    tau2_s: float
    delay_s: float  # θ

    def effort_for(self, y: float) -> float:
        """Static inverse: the steady effort that holds y (dead band stepped over, linearly
        faded in below 2 % of full speed so the inverse stays continuous through 0)."""
        lin = y / self.gain
        edge = 0.02 * self.gain
        return lin + self.dead_band * (max(-1.0, min(1.0, y / edge)) if edge > 0 else 0.0)

    def output_for(self, u: float) -> float:
        """Static forward map (the inverse of `effort_for`): the steady y effort u holds."""
        edge = 0.02 * self.gain
        k = self.dead_band / edge + 1.0 / self.gain if edge > 0 else 1.0 / self.gain
        if abs(u) <= k * edge:  # the faded-in part of effort_for is linear in y
            return u / k
        return (u - math.copysign(self.dead_band, u)) * self.gain

    def frequency_response(self, w: float) -> complex:
        return complex(self.gain * np.exp(-1j * w * self.delay_s)
                       / ((1j * w * self.tau1_s + 1) * (1j * w * self.tau2_s + 1)))

    def ultimate(self) -> tuple[float, float]:
        """(Ku, Tu) the model predicts: where its phase crosses −180°."""
        lo, hi = 1e-3, 100.0
        for _ in range(80):  # phase is monotone in w: bisection
            mid = math.sqrt(lo * hi)
            phase = -mid * self.delay_s - math.atan(mid * self.tau1_s) - math.atan(
                mid * self.tau2_s)
            lo, hi = (mid, hi) if phase > -math.pi else (lo, mid)
        w = math.sqrt(lo * hi)
        return 1.0 / abs(self.frequency_response(w)), 2.0 * math.pi / w

    def step_response(self, t: np.ndarray, du: float) -> np.ndarray:
        """Response of y to an effort step du at t = 0 (from rest in deviation terms)."""
        s = np.clip(t - self.delay_s, 0.0, None)
        t1, t2 = self.tau1_s, max(self.tau2_s, 1e-6)
        if abs(t1 - t2) < 1e-6:
            shape = 1.0 - (1.0 + s / t1) * np.exp(-s / t1)
        else:
            shape = 1.0 - (t1 * np.exp(-s / t1) - t2 * np.exp(-s / t2)) / (t1 - t2)
        return np.asarray(self.gain * du * shape)

    @property
    def lag_s(self) -> float:
        """Mean delay of the chain (θ + τ1 + τ2): how far the chair's velocity trails a ramp."""
        return self.delay_s + self.tau1_s + self.tau2_s


def fit_step(trace: list[tuple[float, float, float]], bias: float) -> ChainModel:
    """Least-squares SOPDT fit of a step probe from the operating point it started at (bias
    u0 held y0 before the step)."""
    from scipy.optimize import least_squares  # (import here: the PID needs no scipy)

    t = np.array([s[0] for s in trace])
    y = np.array([s[1] for s in trace])
    u = np.array([s[2] for s in trace])
    du = float(u[0] - bias)
    y0 = float(np.mean(y[t < 0.05]))  # the dead time: y still at the operating point
    dy = y - y0

    def resid(p: np.ndarray) -> np.ndarray:
        k, t1, t2, th = p
        m = ChainModel(k, 0.0, t1, t2, th)
        return m.step_response(t, du) - dy

    k0 = float(np.mean(dy[-max(1, len(dy) // 10):])) / du
    best = None
    for th0 in (0.05, 0.2, 0.4):  # a few starts: the dead time makes the cost non-convex
        r = least_squares(resid, [k0, 0.3, 0.1, th0],
                          bounds=([1e-3, 1e-3, 0.0, 0.0], [20.0, 5.0, 5.0, 2.0]))
        if best is None or r.cost < best.cost:
            best = r
    assert best is not None
    k, t1, t2, th = (float(x) for x in best.x)
    t1, t2 = max(t1, t2), min(t1, t2)
    # The dead band as an effort offset: the bias held y0, and y0 = K·(u0 − u_db).
    u_db = (bias - y0 / k) * (1.0 if y0 >= 0 else -1.0)
    return ChainModel(k, max(0.0, u_db), t1, t2, th)


# --- gain rules -------------------------------------------------------------------------------

@dataclass(frozen=True)
class Gains:
    rule: str
    kp: float
    ki: float  # 1/s
    kd: float  # s

    def as_tuple(self) -> tuple[float, float, float]:
        return (round(self.kp, 3), round(self.ki, 3), round(self.kd, 3))


def ziegler_nichols(ku: float, tu: float) -> Gains:
    kp = 0.6 * ku
    return Gains("ZN", kp, 2.0 * kp / tu, kp * tu / 8.0)


def tyreus_luyben(ku: float, tu: float) -> Gains:
    kp, ti, td = ku / 2.2, 2.2 * tu, tu / 6.3
    return Gains("TL", kp, kp / ti, kp * td)


def simc(m: ChainModel, tau_c: float | None = None) -> Gains:
    """SIMC PID on the SOPDT (τc = θ by default: Skogestad's 'tight but robust')."""
    tc = m.delay_s if tau_c is None else tau_c
    kc = m.tau1_s / (m.gain * (tc + m.delay_s))
    ti = min(m.tau1_s, 4.0 * (tc + m.delay_s))
    td = m.tau2_s
    # series (Kc, τI, τD) → parallel
    f = 1.0 + td / ti
    return Gains("SIMC", kc * f, kc * f / (ti + td), kc * f * ti * td / (ti + td))


def snippet(gains: dict[str, Gains], models: dict[str, ChainModel]) -> str:
    """The [pid] config lines for these gains and models (TOML)."""
    lines = ["[pid]"]
    for axis, key in (("longitudinal", "v"), ("angular", "omega")):
        if axis in gains:
            g = gains[axis]
            lines.append(f"{key}_gains = [{g.kp:.3f}, {g.ki:.3f}, {g.kd:.3f}]  # {g.rule}")
        if axis in models:
            m = models[axis]
            lines.append(f"{key}_model = [{m.gain:.3f}, {m.dead_band:.3f}, {m.tau1_s:.3f}, "
                         f"{m.tau2_s:.3f}, {m.delay_s:.3f}]  # SOPDT: K, u_db, τ1, τ2, θ")
    return "\n".join(lines) + "\n"
