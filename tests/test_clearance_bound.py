"""nav_eval's clearance bound (bench/clearance_bound.py): the best minimum clearance a case
allows, on worlds with a known answer."""

from __future__ import annotations

import math

import numpy as np
import pytest
from bench.clearance_bound import GRID_M, Room, bottleneck, lattice_attainable, pose_clearance
from bench.nav_eval import summarise

from autochair.nav.field import Footprint, GridMap, NavField
from autochair.sim.world import World

FP = Footprint()  # 1.2 × 0.7 m, the axle 0.25 m from the rear
SLACK = GRID_M / math.sqrt(2) + 1e-3  # the bottleneck grid's allowance (and its bisection's)


def walls(*segs: tuple[float, float, float, float]) -> World:
    return World(np.array(segs, dtype=float), np.zeros((0, 3)))


def corridor(width: float, length: float = 8.0) -> World:
    h = width / 2
    return walls((-2, -h, length, -h), (-2, h, length, h), (-2, -h, -2, h),
                 (length, -h, length, h))


def two_rooms(gap: float) -> World:
    """Two 4 × 4 m rooms (x −2..2 and 2..6), joined by a gap `gap` wide at y = 0 in the
    wall between them (x = 2)."""
    g = gap / 2
    return walls((-2, -2, 6, -2), (-2, 2, 6, 2), (-2, -2, -2, 2), (6, -2, 6, 2),
                 (2, -2, 2, -g), (2, g, 2, 2))


@pytest.mark.parametrize("width", [1.0, 1.5, 2.0])
def test_a_straight_corridor_allows_half_its_spare_width(width: float) -> None:
    b = Room(corridor(width)).upper_bound(FP, (0.0, 0.0, 0.0), (5.0, 0.0, 0.0))
    assert b["bound_m"] == pytest.approx((width - 0.7) / 2, abs=1e-6)
    assert (width - 0.7) / 2 <= b["way_m"] <= (width - 0.7) / 2 + SLACK


@pytest.mark.parametrize("gap", [0.9, 1.1, 1.4])
def test_a_gap_between_two_rooms_bounds_the_way_through_it(gap: float) -> None:
    """The start and the goal stand in the open (over 1 m clear): the gap decides."""
    world = two_rooms(gap)
    start, goal = (0.0, 0.0, 0.0), (4.5, 0.0, 0.0)
    assert min(pose_clearance(world, FP, start), pose_clearance(world, FP, goal)) > 0.5
    b = Room(world).upper_bound(FP, start, goal)
    assert (gap - 0.7) / 2 <= b["bound_m"] <= (gap - 0.7) / 2 + SLACK
    # ... and a forward-only lattice path through it keeps less, by the map's raster (a wall
    # end on a cell's edge marks the cell below: the 1.1 m gap is 1.0 m on the grid) and the
    # rectangle grown by half a cell
    fld = NavField(GridMap.from_shapes(world.segments, world.circles), FP)
    lat = lattice_attainable(fld, start, goal, b["bound_m"])
    assert lat is not None and b["bound_m"] - 0.1 <= lat <= b["bound_m"]


def test_a_goal_near_a_wall_bounds_the_case() -> None:
    """The goal's front 0.12 m from the corridor's end: no motion ends with more."""
    b = Room(corridor(2.0)).upper_bound(FP, (0.0, 0.0, 0.0), (8.0 - 0.95 - 0.12, 0.0, 0.0))
    assert b["goal_m"] == pytest.approx(0.12, abs=1e-6)
    assert b["bound_m"] == pytest.approx(0.12, abs=1e-6)


def test_a_start_turned_towards_a_wall_bounds_the_case() -> None:
    """Facing across a 2 m corridor the front is 0.25 m from the wall (1.0 − 0.95 + 0.2 m
    off the centre line the other way)."""
    b = Room(corridor(2.0)).upper_bound(FP, (0.0, -0.2, math.pi / 2), (5.0, 0.0, 0.0))
    assert b["start_m"] == pytest.approx(0.25, abs=1e-6)
    assert b["bound_m"] == pytest.approx(0.25, abs=1e-6)


def test_a_disc_under_the_chair_is_no_clearance() -> None:
    world = World(corridor(2.0).segments, np.array([[0.3, 0.0, 0.1]]))
    assert pose_clearance(world, FP, (0.0, 0.0, 0.0)) == 0.0


def test_bottleneck_is_the_widest_paths_narrowest_cell() -> None:
    c = np.array([[0.9, 0.1, 0.9],
                  [0.9, 0.1, 0.9],
                  [0.5, 0.3, 0.9]])
    # round the bottom (0.5 then 0.3: its narrowest 0.3), not across the top (0.1)
    assert bottleneck(c, (0, 0), (0, 2)) == pytest.approx(0.3, abs=1e-3)
    assert bottleneck(c, (0, 0), (1, 0)) == pytest.approx(0.9, abs=1e-3)


def run(clear: float, bound: float, lattice: float | None, doorway: bool = False
        ) -> dict[str, object]:
    return {"time_s": 10.0, "doorway": doorway, "min_clearance_m": clear,
            "clearance_bound_m": bound, "clearance_lattice_m": lattice, "arrived": True,
            "true_pos_error_m": 0.0, "true_yaw_error_deg": 0.0, "collisions": 0,
            "collisions_moving": 0, "time_ratio": 1.0, "time_ratio_trapezoid": 1.0,
            "min_time_ok": None, "ref_s": 1.0, "min_time_s": None, "path_ratio": 1.0,
            "peak_a_mps2": 0.0, "peak_jerk_mps3": 0.0, "peak_omega_dot_radps2": 0.0,
            "plan_ms": [1.0], "accept_ms": 1.0, "v_tight_mps": 0.0}


def test_the_summary_counts_cases_under_what_they_allow() -> None:
    runs = [run(0.137, 0.150, 0.147),  # under 0.2, and under its bound and lattice
            run(0.149, 0.150, 0.12),  # under its bound by 1 mm, over its lattice
            run(0.16, 0.150, 0.147),  # at its bound
            run(0.19, 0.40, 0.22),  # room for 0.2: under it
            run(0.06, 0.114, None, doorway=True),  # a doorway over its 0.05 m
            run(0.21, 0.40, None)]
    s = summarise(runs, [{"refused": True, "seconds": 0.0}], 1.0)
    assert s["cases_clearance_below_goal"] == 4
    assert s["cases_clearance_below_attainable"] == 3
    assert s["cases_clearance_below_lattice"] == 2
