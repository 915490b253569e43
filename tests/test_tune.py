"""Auto-tune core: relay probe, Ku/Tu against the thesis (table 5.1), SOPDT fit, gain rules,
feed-forward step response; all in lockstep with the simulated chair (no processes)."""

from __future__ import annotations

import cmath
import math
from collections import deque

import pytest

from autochair.pid.core import Command, VelocityPidCore
from autochair.tune.core import (
    ChainModel,
    Probe,
    ProbeKind,
    ProbeState,
    relay_result,
    simc,
    snippet,
    tyreus_luyben,
    ziegler_nichols,
)
from autochair.tune.lockstep import DT, Rig, core_for, identify, run_probe, step_response

THESIS = {"longitudinal": (1.5, 1.75), "angular": (1.2, 1.33)}  # (Ku, Tu s), table 5.1


@pytest.fixture(scope="module")
def tuned() -> dict[str, object]:
    return {axis: identify(axis) for axis in THESIS}


@pytest.mark.parametrize("axis", list(THESIS))
def test_relay_reproduces_thesis_ku_tu_within_10_percent(tuned: dict[str, object],
                                                        axis: str) -> None:
    r = tuned[axis].relay  # type: ignore[attr-defined]
    ku, tu = THESIS[axis]
    assert r.period_spread < 0.05  # a steady limit cycle, not a transient
    assert abs(r.ku / ku - 1) <= 0.10, r
    assert abs(r.ku_h1 / ku - 1) <= 0.10, r
    assert abs(r.tu_s / tu - 1) <= 0.10, r
    assert abs(math.degrees(cmath.phase(-r.point))) < 5.0  # the cycle sits at about −180°


def test_relay_first_harmonic_is_the_chains_frequency_response() -> None:
    """A relay on a known SOPDT: the first-harmonic point equals the model's G(jω) at the
    cycle's frequency (so 1/|G| is its ultimate gain), where 4d/(πa) reads about 7 % low."""
    m = ChainModel(1.85, 0.0, 0.36, 0.36, 0.37)
    delay = deque([0.0] * round(m.delay_s / DT))
    x1 = x2 = 0.0
    u, trace = 0.2, []
    for k in range(round(30.0 / DT)):
        u = -0.2 if x2 > 0.005 else 0.2 if x2 < -0.005 else u  # relay with hysteresis
        trace.append((k * DT, x2, u))
        delay.append(m.gain * u)
        x1 += (delay.popleft() - x1) * (1.0 - math.exp(-DT / m.tau1_s))
        x2 += (x1 - x2) * (1.0 - math.exp(-DT / m.tau2_s))
    r = relay_result(trace, 0.2)
    g = m.frequency_response(2.0 * math.pi / r.tu_s)
    assert abs(r.point / g - 1.0) < 0.005
    ku = m.ultimate()[0]
    assert r.ku_h1 == pytest.approx(ku, rel=0.01)
    assert r.ku < 0.95 * ku  # positive control: the describing function's estimate is off


@pytest.mark.parametrize("axis", list(THESIS))
def test_step_fit_finds_the_simulated_chain(tuned: dict[str, object], axis: str) -> None:
    m: ChainModel = tuned[axis].model  # type: ignore[attr-defined]
    # The simulator: 1.75 m/s (1.8 rad/s) at full stick beyond a 0.05 dead band.
    full = 1.75 if axis == "longitudinal" else 1.8
    assert m.gain == pytest.approx(full / 0.95, rel=0.03)
    assert m.dead_band == pytest.approx(0.05, abs=0.01)
    # Mean delay (θ + τ1 + τ2) = the simulator's delay + its lags (+ the odometry's ~10 ms).
    lags = (0.38, 0.20, 0.24) if axis == "longitudinal" else (0.26, 0.20, 0.08)
    assert m.lag_s == pytest.approx(0.25 + sum(lags), abs=0.06)
    # The model predicts the relay's ultimate point too (an independent check).
    ku, tu = m.ultimate()
    assert ku == pytest.approx(THESIS[axis][0], rel=0.10)
    assert tu == pytest.approx(THESIS[axis][1], rel=0.10)


def test_gain_rules() -> None:
    zn = ziegler_nichols(1.2, 1.33)  # the thesis's angular row
    assert zn.as_tuple() == pytest.approx((0.72, 1.083, 0.12), abs=1e-3)
    tl = tyreus_luyben(1.2, 1.33)
    assert tl.kp < zn.kp and tl.ki < zn.ki  # gentler
    m = ChainModel(2.0, 0.05, 0.4, 0.2, 0.3)
    g = simc(m)  # Kc = 0.4/(2·0.6), τI = 0.4, τD = 0.2 → parallel
    kc = 0.4 / 1.2
    assert g.kp == pytest.approx(kc * 1.5)
    assert g.ki == pytest.approx(kc * 1.5 / 0.6)
    assert g.kd == pytest.approx(kc * 1.5 * 0.4 * 0.2 / 0.6)
    text = snippet({"longitudinal": g}, {"longitudinal": m})
    assert text.startswith("[pid]\n") and "v_gains = [0.500, 0.833, 0.067]" in text
    assert "v_model = [2.000, 0.050, 0.400, 0.200, 0.300]" in text


def test_model_static_maps_are_inverse() -> None:
    m = ChainModel(1.85, 0.05, 0.36, 0.36, 0.37)
    for y in (-0.8, -0.02, -0.001, 0.0, 0.01, 0.3, 1.2):
        assert m.output_for(m.effort_for(y)) == pytest.approx(y, abs=1e-9)


def test_relay_with_hysteresis_switches_only_outside_the_band() -> None:
    p = Probe(ProbeKind.RELAY, "longitudinal", 0.2, 0.01, duration_s=10)
    p.start(0.5, 0.3, 0.0)
    assert p.effort(0.5, 0.0) == pytest.approx(0.5)  # starts high
    assert p.effort(0.505, 0.01) == pytest.approx(0.5)  # within ε: no switch
    assert p.effort(0.52, 0.02) == pytest.approx(0.1)  # above the band: low
    assert p.effort(0.495, 0.03) == pytest.approx(0.1)  # back within ε: stays low
    assert p.effort(0.48, 0.04) == pytest.approx(0.5)


def test_probe_bounds() -> None:
    p = Probe(ProbeKind.STEP, "longitudinal", 0.1, speed_bound=0.6, duration_s=2.0)
    p.start(0.5, 0.3, 0.0)
    assert p.effort(0.55, 0.1) == pytest.approx(0.4)
    assert p.effort(0.61, 0.2) is None and p.state is ProbeState.ABORTED
    q = Probe(ProbeKind.STEP, "longitudinal", 0.1, duration_s=2.0)
    q.start(0.5, 0.3, 0.0)
    assert q.effort(0.5, 2.01) is None and q.state is ProbeState.DONE
    assert Probe(ProbeKind.RELAY, "sideways", 0.1).check()
    assert Probe(ProbeKind.RELAY, "angular", 0.9).check()  # amplitude beyond 0.5
    assert not Probe(ProbeKind.RELAY, "angular", 0.2).check()


def test_probe_needs_a_command_stream_and_aborts_on_a_stop() -> None:
    core = VelocityPidCore(require_estop=False)
    # Positive control: while driving at 0.5 m/s a probe starts.
    rig = Rig(core)
    rig.hold(0.5, 0.0, 3.0)
    assert core.start_probe(Probe(ProbeKind.RELAY, "longitudinal", 0.2), rig.t) == ""
    assert core.start_probe(Probe(ProbeKind.RELAY, "angular", 0.2), rig.t)  # one at a time
    rig.step(0.5, 0.0)
    assert core.probe is not None and core.probe.state is ProbeState.RUNNING
    # An e-stop latch aborts it and the PID goes to neutral.
    ns = round(rig.t * 1e9)
    core.set_estop(True, rig.t, ns)
    out = core.update(0.5, 0.0, DT, rig.t + DT, ns + round(DT * 1e9))
    assert core.probe.is_(ProbeState.ABORTED) and not out.active
    assert out.longitudinal_v == 2.5
    # Not driving: refused.
    idle = VelocityPidCore(require_estop=False)
    assert "not driving" in idle.start_probe(Probe(ProbeKind.RELAY, "longitudinal", 0.2), 0.0)


def test_probe_speed_bound_is_a_stop() -> None:
    core = VelocityPidCore(require_estop=False)
    probe = run_probe(Rig(core), Probe(ProbeKind.STEP, "longitudinal", 0.3, speed_bound=0.6,
                                       duration_s=5.0), 0.5, settle_s=4.0)
    assert probe.state is ProbeState.ABORTED and "bound" in probe.reason
    assert "tuning probe aborted" in core.stop_reason and not core.obeying
    # A stream begun before the stop is refused: no unexpected start-up.
    assert core.set_desired(Command(0.5, 0.0, "autonomy", 10**10, 1), 10.0, 10**10).value \
        == "before_stop"


@pytest.mark.parametrize("axis", list(THESIS))
def test_feedforward_step_meets_the_goal(tuned: dict[str, object], axis: str) -> None:
    m: ChainModel = tuned[axis].model  # type: ignore[attr-defined]
    tunedstep = step_response(core_for(axis, simc(m).as_tuple(), m, 0.15), axis)
    zn = step_response(VelocityPidCore(require_estop=False), axis)
    assert zn.overshoot > 0.10  # positive control: the thesis's gains overshoot
    assert tunedstep.overshoot <= 0.10
    assert tunedstep.settle_5_s < zn.settle_5_s
    assert tunedstep.settle_5_s <= 1.2  # the goal (±5 %, true velocity)
    assert not math.isnan(tunedstep.rise_s)
