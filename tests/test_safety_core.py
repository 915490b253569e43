"""Safety-monitor core: footprint sweep and speed bounds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from autochair.safety.core import SafetyCore, SafetyParams, scan_points, stop_speed

P = SafetyParams()


def wall_x(x: float, y0: float = -2.0, y1: float = 2.0) -> np.ndarray:
    """Points of a wall across the path at chair-frame x."""
    y = np.arange(y0, y1, 0.02)
    return np.column_stack((np.full_like(y, x), y))


def wall_y(y: float, x0: float = -3.0, x1: float = 3.0) -> np.ndarray:
    x = np.arange(x0, x1, 0.02)
    return np.column_stack((x, np.full_like(x, y)))


def test_nothing_in_view_is_the_caps() -> None:
    lim = SafetyCore(P).limit(np.zeros((0, 2)), 1.0, 0.0)
    assert (lim.v_fwd, lim.v_rev, lim.omega) == (P.v_max_fwd_mps, P.v_max_rev_mps,
                                                  P.omega_max_radps)
    assert lim.reason == "clear" and not lim.imminent


@pytest.mark.parametrize("gap", [0.05, 0.2, 0.5, 1.0, 1.5])
def test_obstacle_ahead_bound_stops_before_it(gap: float) -> None:
    """A wall `gap` metres ahead of the padded front: the bound stops within the gap."""
    x = P.front_m + P.padding_m + gap
    lim = SafetyCore(P).limit(wall_x(x), 0.5, 0.0)
    assert lim.free_fwd_m == pytest.approx(gap, abs=P.step_m + 1e-9)
    v = lim.v_fwd
    stop = v * P.reaction_s + v * v / (2 * P.decel_mps2)
    assert stop <= lim.free_fwd_m - P.stop_margin_m + 1e-9 or v == 0.0
    assert v == pytest.approx(min(P.v_max_fwd_mps, stop_speed(
        lim.free_fwd_m, P.decel_mps2, P.reaction_s, P.stop_margin_m)))
    assert lim.v_rev == P.v_max_rev_mps  # backing away is free


def test_bound_decreases_monotonically_to_zero() -> None:
    core = SafetyCore(P)
    bounds = [core.limit(wall_x(P.front_m + P.padding_m + g), 0.3, 0.0).v_fwd
              for g in (2.5, 1.5, 1.0, 0.6, 0.3, 0.15, 0.1, 0.05, 0.0)]
    assert bounds == sorted(bounds, reverse=True)
    assert bounds[0] == P.v_max_fwd_mps and bounds[-1] == 0.0 and 0 < bounds[3] < 1.0


def test_obstacle_touching_the_front_allows_reverse() -> None:
    lim = SafetyCore(P).limit(wall_x(P.front_m + 0.02), 0.0, 0.0)  # inside the padding
    assert lim.v_fwd == 0.0 and lim.v_rev == P.v_max_rev_mps


def test_obstacle_behind_limits_reverse_only() -> None:
    lim = SafetyCore(P).limit(wall_x(-(P.rear_m + P.padding_m + 0.3)), -0.2, 0.0)
    assert lim.v_fwd == P.v_max_fwd_mps
    assert 0 < lim.v_rev < P.v_max_rev_mps
    lim = SafetyCore(P).limit(wall_x(-(P.rear_m + P.padding_m + 0.05)), 0.0, 0.0)
    assert lim.v_rev == 0.0 and lim.v_fwd == P.v_max_fwd_mps


def test_wall_alongside_does_not_limit_straight_driving() -> None:
    lim = SafetyCore(P).limit(wall_y(P.half_width_m + P.padding_m + 0.1), 1.0, 0.0)
    assert lim.v_fwd == P.v_max_fwd_mps and lim.v_rev == P.v_max_rev_mps


def test_turning_in_place_next_to_a_wall() -> None:
    core = SafetyCore(P)
    # A wall 15 cm beside the chair: either turn swings a corner into it.
    near = core.limit(wall_y(P.half_width_m + P.padding_m + 0.15), 0.0, 0.0)
    assert near.omega < 0.5 * P.omega_max_radps
    assert near.v_fwd == P.v_max_fwd_mps  # but it may drive along it
    # Beyond the corner radius (√(0.95² + 0.35²) ≈ 1.01 m + padding) turning is free.
    far = core.limit(wall_y(1.2), 0.0, 0.0)
    assert far.omega == P.omega_max_radps and math.isinf(far.free_ccw_rad)


def test_arc_follows_the_current_turn() -> None:
    """An obstacle ahead-left is on the path of a left turn but not of a right turn."""
    pts = np.array([[1.6, 0.9], [1.6, 1.0], [1.65, 0.95]])
    core = SafetyCore(P)
    straight = core.limit(pts, 0.5, 0.0)
    left = core.limit(pts, 0.5, 0.5)
    right = core.limit(pts, 0.5, -0.5)
    assert math.isinf(straight.free_fwd_m) and math.isinf(right.free_fwd_m)
    assert left.free_fwd_m < 1.0 and left.v_fwd < P.v_max_fwd_mps


def test_imminent_only_when_it_cannot_stop() -> None:
    core = SafetyCore(P)
    pts = wall_x(P.front_m + P.padding_m + 0.3)
    assert core.limit(pts, 1.2, 0.0).imminent  # 1.44 > 2·2·0.3
    assert not core.limit(pts, 0.5, 0.0).imminent
    assert not core.limit(pts, -0.5, 0.0).imminent  # backing away


def test_scan_points_mount_and_invalid_beams() -> None:
    ranges = np.array([1.0, math.nan, 0.01, 10.0, 2.0])
    pts = scan_points(ranges, -math.pi / 2, math.pi / 4, 0.02, 5.6, (0.8636, 0.2032, 0.0))
    assert pts.shape == (2, 2)  # NaN, below range_min, beyond range_max dropped
    assert pts[0] == pytest.approx([0.8636, 0.2032 - 1.0])
    assert pts[1] == pytest.approx([0.8636, 0.2032 + 2.0])


def test_bad_params_rejected() -> None:
    with pytest.raises(ValueError, match="decel_mps2"):
        SafetyCore(SafetyParams(decel_mps2=0.0))


def test_far_points_are_dropped_without_changing_the_limits() -> None:
    core = SafetyCore(SafetyParams())
    rng = np.random.default_rng(7)
    for _ in range(20):
        pts = rng.uniform(-6, 6, size=(400, 2))
        v, omega = rng.uniform(-0.5, 1.2), rng.uniform(-0.8, 0.8)
        fast = core.limit(pts, v, omega)
        core.reach_m = math.inf  # the same core without the prefilter
        full = core.limit(pts, v, omega)
        core.reach_m = SafetyCore(SafetyParams()).reach_m
        assert fast == full
