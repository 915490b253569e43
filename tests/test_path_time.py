"""nav_eval's time reference (bench/path_time.py): a path driven forward at the comfort limits,
checked on cases with a known answer."""

from __future__ import annotations

import math

import numpy as np
import pytest
from bench.control_eval import scurve_time
from bench.min_time import Limits
from bench.path_time import bends, drive_time, fit, grid, path_time, turn_time

LIM = Limits.of()  # v 1.2, a 1.0, jerk 2.0; ω 0.9, ω̇ 2.8, ω jerk 7.7


def line(length: float, heading: float = 0.0, n: int = 50) -> np.ndarray:
    u = np.linspace(0.0, length, n)
    return np.stack([u * math.cos(heading), u * math.sin(heading)], axis=1)


def corner(length: float, n: int = 50) -> np.ndarray:
    """Along +x, then a left turn of 90° onto +y, each leg `length` long."""
    up = line(length, heading=math.pi / 2, n=n)
    up[:, 0] += length
    return np.concatenate([line(length, n=n)[:-1], up])


def arc(radius: float, angle: float, n: int) -> np.ndarray:
    """A left arc from (0, 0) heading +x (its chord polyline: turns of angle/n... at n-1
    joints, and half that at each end, which path_time turns in place)."""
    a = np.linspace(0.0, angle, n + 1)
    return np.stack([radius * np.sin(a), radius * (1 - np.cos(a))], axis=1)


@pytest.mark.parametrize("length", [0.3, 1.0, 3.0, 20.0])
def test_a_straight_line_takes_the_s_curve_time(length: float) -> None:
    r = path_time(line(length), 0.0, 0.0, LIM)
    assert r["time_s"] == pytest.approx(scurve_time(length, 1.2, 1.0, 2.0), rel=2e-3)
    assert r["turn_start_rad"] == r["turn_end_rad"] == 0.0


@pytest.mark.parametrize("radius", [1.0, 0.5, 0.3, 0.2])
def test_an_arc_takes_the_s_curve_at_the_limits_the_arc_leaves(radius: float) -> None:
    """On an arc ω = v/r: v ≤ ω_max·r, a ≤ ω̇_max·r, jerk ≤ ω-jerk max·r bind where under
    the linear limits (r 0.2 m: all three)."""
    s = grid(2.0)
    t, v = drive_time(s, np.diff(s) / radius, LIM)
    best = scurve_time(2.0, min(1.2, 0.9 * radius), min(1.0, 2.8 * radius),
                       min(2.0, 7.7 * radius))
    assert t == pytest.approx(best, rel=5e-3)
    assert ((v[:-1] + v[1:]) / 2).max() <= 0.9 * radius + 1e-6  # ω over each interval


def test_a_chord_polyline_of_an_arc_takes_about_the_arcs_time() -> None:
    """A 90° arc of radius 0.5 as 40 chords, its turns as `bends` gives them (no smoothing,
    no spread: only eased over SETTLE_M, which moves a little of the turn near the ends into
    the turns in place) and its own: the drive is the arc's within 2 %."""
    n = 40
    xy = arc(0.5, math.pi / 2, n)
    turns, path = bends(xy, 0.0, math.pi / 2, math.inf, 0.0)
    r = path_time(path, 0.0, math.pi / 2, LIM, turns)
    assert turns.sum() == pytest.approx(math.pi / 2)
    assert 0 < r["turn_start_rad"] < 0.1 and 0 < r["turn_end_rad"] < 0.1
    length = 2 * n * 0.5 * math.sin(math.pi / 2 / n / 2)
    assert r["drive_s"] == pytest.approx(scurve_time(length, 0.45, 1.0, 2.0), rel=0.02)
    assert path_time(xy, 0.0, math.pi / 2, LIM)["drive_s"] == pytest.approx(r["drive_s"],
                                                                          rel=0.02)


@pytest.mark.parametrize("angle", [math.pi / 4, -math.pi / 2, math.pi])
def test_turns_in_place_take_the_jerk_limited_turn_time(angle: float) -> None:
    """No path (start on the goal): the turn in place, as bench/control_eval.py's bound; a
    path with the goal's yaw across it: turn, drive, turn, each rest to rest."""
    best = scurve_time(abs(angle), 0.9, 2.8, 7.7)
    assert path_time(np.zeros((2, 2)), 0.0, angle, LIM)["time_s"] == pytest.approx(best)
    assert turn_time(angle, LIM) == pytest.approx(best)
    r = path_time(line(2.0, heading=angle), 0.0, 0.0, LIM)
    assert r["time_s"] == pytest.approx(2 * best + scurve_time(2.0, 1.2, 1.0, 2.0), rel=2e-3)
    assert turn_time(2 * math.pi - 0.1, LIM) == pytest.approx(turn_time(0.1, LIM))  # the short way


def test_a_corner_is_spread_to_the_curvature_bound_and_costs_time() -> None:
    """A 90° corner in a polyline: spread to κ ≤ 1/0.37 (the axle's pass bound), its total
    turn kept; driven slower than a straight line of the same length, faster than stopping
    and turning in place at the corner."""
    xy = corner(2.0)
    turns, path = bends(xy, 0.0, math.pi / 2, 1 / 0.37, 0.0)
    ell = np.hypot(*np.diff(path, axis=0).T)
    assert turns.sum() == pytest.approx(math.pi / 2)
    assert np.abs(turns[1:-1]).max() <= 1 / 0.37 * ell.mean() * 1.1
    t = path_time(path, 0.0, math.pi / 2, LIM, turns)["time_s"]
    stop_and_turn = 2 * scurve_time(2.0, 1.2, 1.0, 2.0) + turn_time(math.pi / 2, LIM)
    assert scurve_time(4.0, 1.2, 1.0, 2.0) + 0.5 < t < stop_and_turn


def test_smoothing_is_only_as_much_as_the_geometry_allows() -> None:
    """A corner next to a 'wall': fit lowers the smoothing of the turns near where the path
    would cross it, not elsewhere; the total turn is kept."""
    xy = corner(3.0, n=61)

    def clear(p: np.ndarray) -> np.ndarray:  # the corner's inside may be cut by 0.15 m at most
        return np.asarray(0.15 - np.maximum(0.0, np.minimum(3.0 - p[:, 0], p[:, 1])))

    turns, path, sigma = fit(xy, 0.0, math.pi / 2, 1 / 0.37, (0.5, 0.2, 0.05, 0.0), clear)
    assert clear(path).min() >= 0.0
    assert turns.sum() == pytest.approx(math.pi / 2)
    assert sigma[60] < 0.5 and sigma[5] == 0.5  # lowered at the corner, not at the start
    loose, _, _ = fit(xy, 0.0, math.pi / 2, 1 / 0.37, (0.5, 0.2, 0.05, 0.0),
                      lambda p: np.ones(len(p)))
    assert path_time(xy, 0.0, math.pi / 2, LIM, loose)["time_s"] \
        < path_time(xy, 0.0, math.pi / 2, LIM, turns)["time_s"]
