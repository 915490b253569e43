"""Odometry core against analytic motion: straight lines, arcs, a full circle, counter wrap."""

from __future__ import annotations

import math

import pytest

from autochair.geometry import wrap_angle
from autochair.odometry.core import OdometryCore
from autochair.protocol.arduino import ST_BOOT
from autochair_msgs import keys

R, B, CPR = 0.049, 0.367, 10000
M_PER_COUNT = 2 * math.pi * R / CPR
HZ = keys.DRIVE_RATE_HZ  # the encoder rate


def drive(core: OdometryCore, v: float, omega: float, seconds: float, hz: float = HZ,
          start: tuple[int, int, int] = (0, 0, 0)) -> None:
    """Feed samples of an exact constant-(v, ω) motion; counts are rounded like an encoder."""
    left = right = 0.0
    l0, r0, t0 = start
    n = round(seconds * hz)
    core.update(l0, r0, t0)
    for i in range(1, n + 1):
        left += (v - omega * B / 2) / hz
        right += (v + omega * B / 2) / hz
        core.update(l0 + round(left / M_PER_COUNT), r0 + round(right / M_PER_COUNT),
                    (t0 + round(i * 1e6 / hz)) % (1 << 32))


def test_straight_line() -> None:
    core = OdometryCore()
    drive(core, 0.5, 0.0, 4.0)
    assert core.x == pytest.approx(2.0, abs=M_PER_COUNT)
    assert core.y == pytest.approx(0.0, abs=1e-9)
    assert core.yaw == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("v,omega", [(0.5, 0.4), (0.3, -0.8), (1.0, 0.1), (-0.4, 0.5)])
def test_arc_matches_analytic(v: float, omega: float) -> None:
    core = OdometryCore()
    t = 3.0
    drive(core, v, omega, t)
    yaw = omega * t
    r = v / omega
    assert core.x == pytest.approx(r * math.sin(yaw), abs=2e-4)
    assert core.y == pytest.approx(r * (1 - math.cos(yaw)), abs=2e-4)
    assert core.yaw == pytest.approx(wrap_angle(yaw), abs=2e-4)


def test_full_circle_returns_home() -> None:
    core = OdometryCore()
    omega = 0.5
    drive(core, 0.5, omega, 2 * math.pi / omega)
    # Whole samples end within half a sample of the full circle: compare with that point.
    t = round(2 * math.pi / omega * HZ) / HZ
    home = (0.5 / omega * math.sin(omega * t), 0.5 / omega * (1 - math.cos(omega * t)))
    assert math.hypot(core.x - home[0], core.y - home[1]) < 1e-3
    assert abs(wrap_angle(core.yaw - omega * t)) < 1e-3
    assert core.distance == pytest.approx(2 * math.pi * 1.0, rel=1e-3)


def test_spin_in_place_keeps_position_and_wraps_yaw() -> None:
    core = OdometryCore()
    drive(core, 0.0, 1.0, 4.0)  # 4 rad: past π, must wrap to 4 − 2π
    assert math.hypot(core.x, core.y) < 1e-6
    assert core.yaw == pytest.approx(4.0 - 2 * math.pi, abs=1e-3)
    assert -math.pi < core.yaw <= math.pi


def test_counter_and_clock_wrap_are_invisible() -> None:
    near_wrap = (1 << 32) - 5000
    a, b = OdometryCore(), OdometryCore()
    drive(a, 0.8, 0.3, 2.0)
    drive(b, 0.8, 0.3, 2.0, start=(near_wrap, near_wrap, (1 << 32) - 100_000))
    assert (b.x, b.y, b.yaw) == pytest.approx((a.x, a.y, a.yaw), abs=1e-12)


def test_backwards_over_zero_counts() -> None:
    core = OdometryCore()
    drive(core, -0.5, 0.0, 1.0, start=(3, 3, 0))  # counters go below zero → wrap to 2^32 − n
    assert core.x == pytest.approx(-0.5, abs=M_PER_COUNT)


def test_velocity_from_mcu_clock() -> None:
    core = OdometryCore(velocity_window_s=0.02)
    drive(core, 0.5, 0.2, 1.0)
    st = core.update(*_next_sample(core, 0.5, 0.2))
    assert st.v == pytest.approx(0.5, abs=0.01)
    assert st.omega == pytest.approx(0.2, abs=0.02)


def _next_sample(core: OdometryCore, v: float, omega: float) -> tuple[int, int, int]:
    assert core._prev is not None
    left, right, t = core._prev
    return (left + round((v - omega * B / 2) / HZ / M_PER_COUNT),
            right + round((v + omega * B / 2) / HZ / M_PER_COUNT), t + round(1e6 / HZ))


@pytest.mark.parametrize("a,expected", [(math.pi, math.pi), (-math.pi, math.pi),
                                        (3 * math.pi, math.pi), (0.1, 0.1),
                                        (-7.0, -7 + 2 * math.pi)])
def test_wrap_angle(a: float, expected: float) -> None:
    assert wrap_angle(a) == pytest.approx(expected)


def test_mcu_restart_rebases_instead_of_jumping() -> None:
    core = OdometryCore()
    drive(core, 0.5, 0.0, 2.0, start=(5_000_000, 5_000_000, 600_000_000))
    x = core.x
    # The MCU reset (USB replug): counters and clock restart near zero, boot flag possibly
    # missed while the gateway reconnected. No jump, and driving goes on from the same pose.
    core.update(10, 10, 1_500_000)
    assert core.x == pytest.approx(x) and core.restarts == 1
    core.update(10 + round(0.01 / M_PER_COUNT), 10 + round(0.01 / M_PER_COUNT), 1_505_000)
    assert core.x == pytest.approx(x + 0.01, abs=M_PER_COUNT)


def test_boot_flag_rising_rebases() -> None:
    core = OdometryCore()
    core.update(0, 0, 0, status=ST_BOOT)  # our own start during the MCU's boot: no news
    core.update(100, 100, 5000, status=0)
    assert core.restarts == 0
    core.update(999_999, 999_999, 10_000, status=ST_BOOT)  # rising edge: counters reset
    assert core.restarts == 1 and core.distance == pytest.approx(100 * M_PER_COUNT)


def test_forward_gap_keeps_the_distance() -> None:
    core = OdometryCore()
    core.update(0, 0, 0)
    core.update(20_000, 20_000, 3_000_000)  # 3 s without samples (a reconnect), no reset
    assert core.x == pytest.approx(20_000 * M_PER_COUNT) and core.restarts == 0


def test_an_implausible_counter_jump_does_not_poison_the_pose() -> None:
    core = OdometryCore()
    core.update(0, 0, 0)
    core.update(100, 100, 5000)  # 3 mm in 5 ms: 0.6 m/s, plausible
    x = core.x
    assert x > 0.0
    core.update(100 + 2_000_000, 100, 10000)  # a glitch: 61 m in 5 ms
    assert core.implausible == 1 and core.x == x and math.isfinite(core.yaw)
    core.update(100 + 2_000_000 + 100, 200, 15000)  # then on from the new counters
    assert core.x > x and core.x - x < 0.05


def test_decimator_is_drift_free_and_rebases_on_late_samples_and_clock_steps() -> None:
    from autochair.timing import Decimator

    d = Decimator.at(50.0)  # 20 ms
    ms = 1_000_000
    passed = [t for t in range(0, 200 * ms, 5 * ms) if d(t)]  # 200 Hz in
    assert passed == list(range(0, 200 * ms, 20 * ms))  # exactly every 4th, no drift
    assert d(1000 * ms) and not d(1005 * ms)  # late: re-based on the sample
    assert d(10 * ms) and not d(15 * ms) and d(30 * ms)  # clock stepped back: re-based
    every = Decimator.at(0.0)
    assert all(every(t) for t in (0, 1, 1, 2))
