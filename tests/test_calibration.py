"""Odometry calibration (pure): the simulator's injected wheel-diameter ratio and base error
are recovered within 10 % of their size from encoder counts and noisy poses."""

from __future__ import annotations

import numpy as np
import pytest
from bench import loc_eval

from autochair.localization.calibration import calibrate
from autochair.odometry.core import OdometryCore
from autochair.sim.chair.model import ChairModel, ChairParams
from autochair_msgs import keys

DT = 1.0 / keys.DRIVE_RATE_HZ


def _drive(seconds: float, caps: tuple[float, ...], xy_noise_m: float, yaw_noise_deg: float,
           seed: int = 0) -> tuple[np.ndarray, ...]:
    """A 4 m square driven anticlockwise then clockwise, turn-rate limit varied per lap;
    poses (truth + localization-like noise) and encoder counts every 0.1 s."""
    p = ChairParams(drift=True, seed=5)
    m = ChairModel(p)
    driver = loc_eval.Driver([(4.0, 0.0), (4.0, 4.0), (0.0, 4.0), (0.0, 0.0),
                              (0.0, 4.0), (4.0, 4.0), (4.0, 0.0), (0.0, 0.0)], omega_caps=caps)
    rng = np.random.default_rng(seed)
    t, left, right, poses = [], [], [], []
    every = round(0.1 / DT)
    for k in range(round(seconds / DT)):
        m.step(*loc_eval.to_volts(*driver.command(m.x, m.y, m.yaw), p), DT)
        if (k + 1) % every == 0:
            t.append((k + 1) * DT)
            left.append(m.left_counts)
            right.append(m.right_counts)
            poses.append((m.x + rng.normal(0, xy_noise_m), m.y + rng.normal(0, xy_noise_m),
                          m.yaw + rng.normal(0, np.radians(yaw_noise_deg))))
    return (np.array(t), np.array(left, dtype=np.float64), np.array(right, dtype=np.float64),
            np.array(poses))


@pytest.mark.parametrize("seed", [0, 1])
def test_calibration_recovers_injected_errors_within_10_percent(seed: int) -> None:
    """Poses with white noise of 5 mm / 0.1° every 0.1 s (measured: E_b 4–5 % off over
    four noise seeds; 0.8 % noise-free; the localized bench runs: 4–5 %)."""
    t, left, right, poses = _drive(300.0, (0.3, 0.55, 0.8), 0.005, 0.1, seed)
    odo, p = OdometryCore(), ChairParams(drift=True)
    cal = calibrate(t, left, right, poses, wheel_radius_m=odo.wheel_radius_m,
                    base_m=odo.base_m, counts_per_rev=odo.counts_per_rev, window=5)
    assert abs(cal.diameter_ratio - p.diameter_ratio) <= 0.1 * abs(p.diameter_ratio - 1)
    assert abs(cal.base_ratio - p.base_ratio) <= 0.1 * abs(p.base_ratio - 1)
    assert cal.base_m == pytest.approx(odo.base_m * cal.base_ratio)
    assert f"base_m = {cal.base_m:.6f}" in cal.config_text()
