"""The simulated chair plant: calibration against the thesis, dead band, encoders, kinematics."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from autochair.geometry import wrap_angle
from autochair.sim.chair.model import (
    NEUTRAL_V,
    ChairModel,
    ChairParams,
    effort,
    volts,
    ziegler_nichols,
)
from autochair_msgs import keys

DT = 1.0 / keys.DRIVE_RATE_HZ  # the simulator's model step
THESIS = {"longitudinal": (1.5, 1.75), "angular": (1.2, 1.33)}
ZN_PID = {"longitudinal": (0.90, 1.03, 0.20), "angular": (0.72, 1.08, 0.12)}


def _measure(m: ChairModel, axis: str) -> float:
    return m.v if axis == "longitudinal" else m.omega


def _apply(m: ChairModel, axis: str, c: float) -> None:
    if axis == "longitudinal":
        m.step(volts(c), NEUTRAL_V, DT)
    else:
        m.step(NEUTRAL_V, volts(c), DT)


@pytest.mark.parametrize("axis", ["longitudinal", "angular"])
def test_ziegler_nichols_matches_thesis(axis: str) -> None:
    ku, tu = ziegler_nichols(ChairModel, axis)  # type: ignore[arg-type]
    ku_t, tu_t = THESIS[axis]
    assert ku == pytest.approx(ku_t, rel=0.15)
    assert tu == pytest.approx(tu_t, rel=0.15)


@pytest.mark.parametrize("axis", ["longitudinal", "angular"])
def test_thesis_pid_settles_half_step_within_3s(axis: str) -> None:
    """Thesis ZN gains, derivative on measurement with a first-order filter (N = 10)."""
    kp, ki, kd = ZN_PID[axis]
    m, sp = ChairModel(), 0.5
    integ = d_filt = 0.0
    prev = _measure(m, axis)
    tf = kd / kp / 10.0
    trace = []
    for _ in range(round(8.0 / DT)):
        y = _measure(m, axis)
        d_filt += (DT / (tf + DT)) * (-(y - prev) / DT - d_filt)
        prev = y
        e = sp - y
        u = kp * e + integ + kd * d_filt
        if -1.0 < u < 1.0:  # conditional integration: no windup
            integ += ki * e * DT
        _apply(m, axis, max(-1.0, min(1.0, u)))
        trace.append(y)
    outside = [i for i, y in enumerate(trace) if abs(y - sp) > 0.1 * sp]
    settle_s = (outside[-1] + 1) * DT
    assert settle_s < 3.0
    assert max(trace) > sp  # ZN tuning is aggressive: some overshoot is expected


def test_neutral_and_dead_band_hold_still() -> None:
    m = ChairModel()
    small = volts(0.9 * m.params.dead_band)
    for v_long, v_ang in ((NEUTRAL_V, NEUTRAL_V), (small, small), (5 - small, 5 - small)):
        for _ in range(400):
            m.step(v_long, v_ang, DT)
    assert (m.x, m.y, m.yaw, m.v, m.omega) == (0.0, 0.0, 0.0, 0.0, 0.0)
    assert m.left_counts == m.right_counts == 0


def test_joystick_directions_rep103() -> None:
    fwd = ChairModel()
    for _ in range(600):
        fwd.step(3.0, NEUTRAL_V, DT)
    assert fwd.v > 0.3 and fwd.x > 0.5 and abs(fwd.y) < 1e-9
    left = ChairModel()
    for _ in range(600):
        left.step(NEUTRAL_V, 3.0, DT)
    assert left.omega > 0.3 and left.yaw > 0.3  # V > 2.5 turns counter-clockwise
    assert left.right_counts > 0 > left.left_counts


def test_effort_mapping() -> None:
    assert effort(2.5) == 0.0 and effort(4.0) == 1.0 and effort(1.0) == -1.0
    assert volts(effort(3.3)) == pytest.approx(3.3)


def test_one_wheel_revolution_is_10000_counts() -> None:
    """Drive straight at steady speed: counts track travel / (2πr) × 10000, floor-quantised."""
    m = ChairModel()
    circumference = 2 * math.pi * m.params.wheel_radius_m
    while m._left_travel_m < circumference:
        m.step(3.5, NEUTRAL_V, DT)
    per_m = 10000 / circumference
    assert m.left_counts == math.floor(m._left_travel_m * per_m)
    assert m.left_counts >= 10000 and m.left_counts - 10000 < m.v * DT * per_m + 1
    assert m.left_counts == m.right_counts


def test_pure_rotation_stays_in_place_and_wraps_yaw() -> None:
    m = ChairModel()
    yaw_total = 0.0
    for _ in range(round(12.0 / DT)):
        prev = m.yaw
        m.step(NEUTRAL_V, 4.0, DT)
        yaw_total += wrap_angle(m.yaw - prev)
        assert -math.pi < m.yaw <= math.pi
    assert yaw_total > 2 * math.pi  # turned more than once around
    assert math.hypot(m.x, m.y) < 1e-9
    # Counts: wheels travel ±yaw·b/2.
    per_rad = (m.params.base_m / 2) * 10000 / (2 * math.pi * m.params.wheel_radius_m)
    assert m.right_counts == pytest.approx(yaw_total * per_rad, abs=2)
    assert m.left_counts == pytest.approx(-yaw_total * per_rad, abs=2)


def test_straight_line_and_arc_pose() -> None:
    m = ChairModel()
    for _ in range(round(5.0 / DT)):
        m.step(3.4, NEUTRAL_V, DT)
    per_m = 10000 / (2 * math.pi * m.params.wheel_radius_m)
    assert m.y == 0.0 and m.yaw == 0.0
    assert m.x == pytest.approx(m.left_counts / per_m, abs=2 / per_m)
    # Steady arc: the radius is v/omega, so the chair stays on a circle about its centre.
    a = ChairModel()
    for _ in range(round(6.0 / DT)):
        a.step(3.2, 3.0, DT)
    r = a.v / a.omega
    cx, cy = a.x - r * math.sin(a.yaw), a.y + r * math.cos(a.yaw)
    pts = []
    for _ in range(round(3.0 / DT)):
        a.step(3.2, 3.0, DT)
        pts.append(math.hypot(a.x - cx, a.y - cy))
    assert max(pts) - min(pts) < 1e-3 * r


def test_saturation_and_full_stick_speed() -> None:
    m = ChairModel()
    for _ in range(round(8.0 / DT)):
        m.step(5.0, NEUTRAL_V, DT)  # beyond full stick
    assert m.v == pytest.approx(m.params.v_full_mps, rel=1e-3)


def test_noise_is_seeded_and_off_by_default() -> None:
    p = replace(ChairParams(), noise=True, seed=7)
    runs = []
    for params in (p, p, replace(p, seed=8)):
        m = ChairModel(params)
        for _ in range(400):
            m.step(3.2, 2.7, DT)
        runs.append((m.x, m.left_counts))
    assert runs[0] == runs[1] != runs[2]


def test_bad_dt_rejected() -> None:
    with pytest.raises(ValueError, match="dt"):
        ChairModel().step(2.5, 2.5, 0.0)
