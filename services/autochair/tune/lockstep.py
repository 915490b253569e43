"""The tuning experiments in lockstep with the simulated chair (PURE, deterministic, faster
than real time): ChairModel → encoder counts → OdometryCore → VelocityPidCore (with its probe
mode, exactly as the PID process runs it) → joystick volts → ChairModel. Used by the tests, the
benches and `autochair tune --lockstep`."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from autochair.odometry.core import OdometryCore, OdomState
from autochair.pid.core import Command, PidOutput, VelocityPidCore
from autochair.sim.chair.model import ChairModel
from autochair_msgs import keys

from .core import (
    AXES,
    ChainModel,
    Probe,
    ProbeKind,
    ProbeState,
    RelayResult,
    fit_step,
    relay_result,
)

DT = 1.0 / keys.DRIVE_RATE_HZ  # the drive chain's rate: encoders, odometry, PID (0.01 s)


class Rig:
    """Chair model, odometry and a PID core, stepped together (the tuning experiments here; the
    control and navigation benches drive `sense`/`act` themselves). With `step`, the desired
    velocity is a command stream begun at construction (the deliberate act the PID requires)."""

    def __init__(self, core: VelocityPidCore | None = None, chair: ChairModel | None = None,
                 truth: bool = False, start: tuple[float, float, float] | None = None) -> None:
        self.chair = chair or ChairModel()
        self.odom = OdometryCore()
        if start is not None:  # the chair placed there, and the odometry with it
            self.chair.x, self.chair.y, self.chair.yaw = start
            self.odom.reset(*start)
        self.core = core or VelocityPidCore(require_estop=False)
        self.truth = truth  # measure the true velocity instead of the odometry's
        self.t = 0.0
        self.volts = (2.5, 2.5)
        self.rows: list[tuple[float, float, float, float, float]] = []  # t, v, ω true; cv, cw

    def sense(self) -> OdomState:
        """One tick of the chair under the last volts; the odometry reads its encoders."""
        c = self.chair
        c.step(*self.volts, DT)
        return self.odom.update(c.left_counts, c.right_counts, round(c.t * 1e6))

    def act(self, t: float, v_meas: float, omega_meas: float,
            desired: tuple[float, float] | None = None) -> PidOutput:
        """One PID tick at `t` on a measurement: a new desired velocity first if given (the
        same command stream), then the volts for the next `sense`."""
        ns = round(t * 1e9)
        if desired is not None:
            # (stamped 1 ns on: at t = 0 the stream, begun just after the core's start, would
            # otherwise be stamped before it began)
            self.core.set_desired(Command(desired[0], desired[1], "autonomy", ns + 1, 1), t, ns)
        out = self.core.update(v_meas, omega_meas, DT, t, ns)
        self.volts = (out.longitudinal_v, out.angular_v)
        return out

    def step(self, v: float, omega: float) -> None:
        st, c = self.sense(), self.chair
        self.t += DT
        mv, mw = (c.v, c.omega) if self.truth else (st.v, st.omega)
        out = self.act(self.t, mv, mw, (v, omega))
        self.rows.append((self.t, c.v, c.omega, out.v_effort, out.omega_effort))

    def hold(self, v: float, omega: float, seconds: float) -> None:
        for _ in range(round(seconds / DT)):
            self.step(v, omega)

    def measured(self, axis: str) -> float:
        i = AXES.index(axis)
        return (self.core.v_pid, self.core.omega_pid)[i]._prev_meas or 0.0


def core_for(axis: str, gains: tuple[float, float, float], model: ChainModel | None = None,
             prefilter_s: float = 0.15) -> VelocityPidCore:
    """A PID core with these gains (and model) on one axis, the thesis's on the other."""
    if axis == "longitudinal":
        return VelocityPidCore(require_estop=False, v_gains=gains, v_model=model,
                               prefilter_s=prefilter_s)
    return VelocityPidCore(require_estop=False, omega_gains=gains, omega_model=model,
                           prefilter_s=prefilter_s)


def setpoint_pair(axis: str, setpoint: float) -> tuple[float, float]:
    return (setpoint, 0.0) if axis == "longitudinal" else (0.0, setpoint)


def run_probe(rig: Rig, probe: Probe, setpoint: float, settle_s: float = 8.0) -> Probe:
    """Settle at the setpoint with the loop, then run the probe until it ends."""
    pair = setpoint_pair(probe.axis, setpoint)
    rig.hold(*pair, settle_s)
    why = rig.core.start_probe(probe, rig.t)
    if why:
        raise RuntimeError(why)
    while probe.state is ProbeState.RUNNING:
        rig.step(*pair)
    return probe


@dataclass(frozen=True)
class AxisTune:
    axis: str
    relay: RelayResult
    model: ChainModel


def identify(axis: str, setpoint: float = 0.5, relay_d: float = 0.2, hysteresis: float = 0.005,
             step_d: float = 0.1, core: Callable[[], VelocityPidCore] | None = None,
             chair: Callable[[], ChairModel] | None = None) -> AxisTune:
    """Relay (Ku, Tu) and step (SOPDT) probes of one axis, each from a fresh chair."""
    make = core or (lambda: VelocityPidCore(require_estop=False))
    mk_chair = chair or ChairModel
    relay = run_probe(Rig(make(), mk_chair()), Probe(ProbeKind.RELAY, axis, relay_d, hysteresis,
                                                     duration_s=30.0), setpoint)
    step = run_probe(Rig(make(), mk_chair()), Probe(ProbeKind.STEP, axis, step_d,
                                                    duration_s=4.0), setpoint)
    if relay.state is not ProbeState.DONE or step.state is not ProbeState.DONE:
        raise RuntimeError(f"probe aborted: {relay.reason or step.reason}")
    return AxisTune(axis, relay_result(relay.trace, relay_d), fit_step(step.trace, step.bias))


@dataclass(frozen=True)
class StepMetrics:
    overshoot: float  # fraction of the step
    settle_5_s: float  # last time outside ±5 % of the step, from the step
    settle_10_s: float
    rise_s: float  # 10 → 90 %
    peak_acc: float  # of the true velocity (m/s² or rad/s²)
    t: list[float]
    y: list[float]  # true velocity


def step_response(core: VelocityPidCore, axis: str, size: float = 0.5,
                  duration_s: float = 5.0) -> StepMetrics:
    """The chair at rest, then a desired-velocity step of `size` on one axis (the other 0);
    measured on the simulator's true velocity."""
    rig = Rig(core)
    rig.hold(0.0, 0.0, 0.5)
    t0 = rig.t
    rig.hold(*setpoint_pair(axis, size), duration_s)
    i = 1 if axis == "longitudinal" else 2
    t = [r[0] - t0 for r in rig.rows if r[0] > t0]
    y = [r[i] for r in rig.rows if r[0] > t0]
    return metrics(t, y, size)


def metrics(t: list[float], y: list[float], size: float) -> StepMetrics:
    def settle(band: float) -> float:
        out = [tt for tt, yy in zip(t, y, strict=True) if abs(yy - size) > band * abs(size)]
        if out and out[-1] >= t[-1]:
            return math.inf  # still outside at the end: not settled
        return out[-1] if out else 0.0

    def first(frac: float) -> float:
        return next((tt for tt, yy in zip(t, y, strict=True) if yy / size >= frac), math.nan)

    k = max(1, round(0.02 / (t[1] - t[0]))) if len(t) > 1 else 1  # differences over 20 ms
    acc = [abs(b - a) / (tb - ta) for (ta, a), (tb, b) in
           zip(zip(t[::k], y[::k], strict=True), zip(t[k::k], y[k::k], strict=False),
               strict=False)]
    return StepMetrics(max(0.0, max(yy / size for yy in y) - 1.0), settle(0.05), settle(0.10),
                       first(0.9) - first(0.1), max(acc, default=0.0), t, y)


def summary(m: StepMetrics) -> dict[str, Any]:
    def r(x: float) -> float | None:  # JSON has no inf/nan: None = not settled / not risen
        return round(x, 3) if math.isfinite(x) else None

    return {"overshoot_pct": round(100 * m.overshoot, 1), "settle_5pct_s": r(m.settle_5_s),
            "settle_10pct_s": r(m.settle_10_s), "rise_s": r(m.rise_s)}
