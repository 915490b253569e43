"""PID and velocity-controller core: anti-windup, saturation, filtering, stale desired."""

from __future__ import annotations

import pytest

from autochair.pid.core import PID, VelocityPidCore, effort_to_volts


def test_proportional_and_integral() -> None:
    pid = PID(kp=2.0, ki=1.0, kd=0.0, out_min=-10, out_max=10)
    assert pid.update(1.0, 0.0, 0.1) == pytest.approx(2.0 + 0.1)
    assert pid.update(1.0, 0.0, 0.1) == pytest.approx(2.0 + 0.2)


def test_no_derivative_kick_on_setpoint_step() -> None:
    pid = PID(kp=1.0, ki=0.0, kd=5.0, out_min=-100, out_max=100)
    pid.update(0.0, 0.0, 0.01)
    assert pid.update(10.0, 0.0, 0.01) == pytest.approx(10.0)  # only P: D acts on measurement


def test_derivative_on_measurement_is_filtered() -> None:
    pid = PID(kp=1.0, ki=0.0, kd=1.0, out_min=-100, out_max=100, d_filter_n=10)
    pid.update(0.0, 0.0, 0.01)
    out = pid.update(0.0, 0.01, 0.01)  # raw derivative −1 → filtered by α = 0.01/(0.1+0.01)
    assert out == pytest.approx(-0.01 - 1.0 * (0.01 / 0.11), rel=1e-6)


def test_anti_windup_recovers_quickly() -> None:
    pid = PID(kp=0.5, ki=2.0, kd=0.0, out_min=-1, out_max=1)
    for _ in range(1000):  # 10 s saturated against an unreachable setpoint
        assert pid.update(10.0, 0.0, 0.01) == 1.0
    assert pid.integral <= 1.0
    # Once the error reverses the output leaves saturation at once, not after unwinding 10 s.
    assert pid.update(0.0, 1.0, 0.01) < 0.6


def test_output_is_saturated() -> None:
    pid = PID(kp=100.0, ki=0.0, kd=0.0, out_min=-0.5, out_max=0.7)
    assert pid.update(1.0, 0.0, 0.01) == 0.7
    assert pid.update(-1.0, 0.0, 0.01) == -0.5


def test_bumpless_reset() -> None:
    pid = PID(kp=1.0, ki=1.0, kd=1.0, out_min=-1, out_max=1)
    pid.reset(measurement=0.3, output=0.4)
    assert pid.update(0.3, 0.3, 0.01) == pytest.approx(0.4)


def test_dt_must_be_positive() -> None:
    with pytest.raises(ValueError):
        PID(1, 1, 1).update(0, 0, 0.0)


def test_effort_maps_to_thesis_voltage_and_clamps() -> None:
    assert effort_to_volts(0.0) == 2.5
    assert effort_to_volts(0.5) == pytest.approx(3.25)
    assert effort_to_volts(1.0) == 3.9  # 4.0 V clamped to the window
    assert effort_to_volts(-1.0) == 1.1


def test_stale_desired_gives_exact_neutral() -> None:
    core = VelocityPidCore(stale_s=0.3)
    assert core.set_desired(0.5, 0.0, now_s=0.0) == "ok"
    out = core.update(0.0, 0.0, 0.005, now_s=0.1)
    assert out.active and out.longitudinal_v > 2.5
    out = core.update(0.0, 0.0, 0.005, now_s=0.31)
    assert not out.active
    assert (out.longitudinal_v, out.angular_v, out.v_effort) == (2.5, 2.5, 0.0)


def test_never_commanded_is_neutral() -> None:
    out = VelocityPidCore().update(0.0, 0.0, 0.005, now_s=100.0)
    assert (out.longitudinal_v, out.angular_v, out.active) == (2.5, 2.5, False)


def test_parked_is_exact_neutral_and_integrator_cleared() -> None:
    core = VelocityPidCore()
    for i in range(100):
        core.set_desired(0.5, 0.0, i * 0.005)
        core.update(0.1, 0.0, 0.005, i * 0.005)
    assert core.v_pid.integral > 0
    core.set_desired(0.0, 0.0, 0.5)
    out = core.update(0.0, 0.0, 0.005, 0.5)
    assert (out.longitudinal_v, out.angular_v) == (2.5, 2.5)
    assert core.v_pid.integral == 0.0


def test_non_finite_desired_is_rejected() -> None:
    core = VelocityPidCore()
    assert core.set_desired(float("nan"), 0.0, 0.0) == "rejected"
    assert core.desired(0.0) is None


def test_thesis_gains_are_default() -> None:
    core = VelocityPidCore()
    assert (core.v_pid.kp, core.v_pid.ki, core.v_pid.kd) == (0.90, 1.03, 0.20)
    assert (core.omega_pid.kp, core.omega_pid.ki, core.omega_pid.kd) == (0.72, 1.08, 0.12)


def test_only_the_owner_drives() -> None:
    core = VelocityPidCore()
    assert core.set_desired(0.5, 0.0, 0.0, source="teleop") == "not_owner"
    assert core.desired(0.0) is None
    assert core.set_desired(0.5, 0.0, 0.0) == "ok"
    assert core.set_owner("teleop")
    assert core.desired(0.0) is None  # autonomy's last command no longer counts
    assert core.set_desired(0.2, 0.1, 0.0, source="teleop") == "ok"
    assert core.set_desired(0.9, 0.0, 0.0, source="autonomy") == "not_owner"
    assert core.desired(0.0) == (0.2, 0.1)
    assert not core.set_owner("someone")


def test_safety_limit_clamps_and_may_be_required() -> None:
    core = VelocityPidCore(require_limit=True, limit_stale_s=0.5)
    core.set_desired(1.0, 1.0, 0.0)
    assert core.desired(0.0) == (0.0, 0.0)  # required but never received: stop
    assert core.set_limit(0.3, 0.2, 0.5, 0.0)
    assert core.desired(0.1) == (0.3, 0.5)
    core.set_desired(-1.0, -1.0, 0.2)
    assert core.desired(0.2) == (-0.2, -0.5)
    core.set_desired(-1.0, -1.0, 0.5)
    assert core.desired(0.51) == (0.0, 0.0)  # limit stale
    assert not core.set_limit(float("nan"), 0, 0, 0)
