"""The simulated URG-04LX sweeps: each beam is cast from where the chair was when the turning
laser took it, so a scan taken while the chair turns is skewed as a real one is."""

from __future__ import annotations

import numpy as np

from autochair.people.core import scan_points
from autochair.sim.lidar.scanner import UrgParams, ray_scan
from autochair.sim.world import World

URG = UrgParams()
MOUNT = (0.0, 0.0, 0.0)
ROOM = World(np.array([[3.0, -5.0, 3.0, 5.0], [-5.0, 3.0, 3.0, 3.0], [-5.0, -5.0, 3.0, -5.0]]),
             np.zeros((0, 3)))


def wall_error(raw: np.ndarray, yaws: np.ndarray | float) -> float:
    """Largest distance of the scan's points from the walls, each beam placed at `yaws`."""
    angles = URG.step_angles()
    r = np.where(raw >= URG.dmin_mm, raw / 1000.0, np.nan)
    pts = scan_points(r, float(angles[0]), float(angles[1] - angles[0]), 0.02, 5.6,
                      (0.0, 0.0, yaws))
    pts = pts[np.isfinite(pts).all(axis=1)]
    return float(ROOM.distance_to(pts).max())


def test_a_turning_chairs_scan_is_skewed_and_placing_each_beam_at_its_time_undoes_it() -> None:
    rng = np.random.default_rng(1)
    still = ray_scan(ROOM, URG, (0.0, 0.0, 0.0), MOUNT, 0.0, rng)
    assert wall_error(still, 0.0) < 0.002  # at rest: every beam where it belongs
    omega = 0.9
    turning = ray_scan(ROOM, URG, (0.0, 0.0, 0.0), MOUNT, 0.0, rng, (0.0, omega))
    skew = wall_error(turning, 0.0)  # one pose (the sweep's end) for all beams
    steps = np.arange(URG.amin, URG.amax + 1)
    at_their_time = -omega * (1.0 - steps / URG.ares) / URG.scan_rate_hz
    assert skew > 0.15, skew  # 0.09 rad over the sweep: tens of cm at 3-5 m
    assert wall_error(turning, at_their_time) < 0.002
