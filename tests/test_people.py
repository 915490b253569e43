"""The people tracker (autochair.people.core), alone: scans ray-cast in small worlds."""

from __future__ import annotations

import math

import msgspec
import numpy as np

from autochair.nav.field import GridMap
from autochair.people.core import PeopleTracker, StaticMap, scan_points
from autochair.sim.world import World, raycast
from autochair_msgs import OccupancyGrid

ANGLES = np.linspace(-2.09, 2.09, 682)  # a URG-04LX's 240°
WALLS = np.array([[-1.0, -2.0, 10.0, -2.0], [-1.0, 2.0, 10.0, 2.0]])  # a 4 m corridor


def scan(world: World, laser: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    r = raycast(world, laser[0], laser[1], ANGLES + laser[2], 5.6)
    return scan_points(r, float(ANGLES[0]), float(ANGLES[1] - ANGLES[0]), 0.02, 5.6, laser)


def mapped(segments: np.ndarray, circles: np.ndarray | None = None) -> StaticMap:
    g = GridMap.from_shapes(segments, np.zeros((0, 3)) if circles is None else circles, 0.05)
    return StaticMap.of(g.occupied, g.resolution_m, g.origin_x_m, g.origin_y_m)


def people(world: World, static: StaticMap | None, times: int = 3) -> list:  # type: ignore[type-arg]
    tracker = PeopleTracker(static=static)
    out: list = []  # type: ignore[type-arg]
    for k in range(times):
        out = tracker.update(scan(world), (0.0, 0.0), k * 0.1)
    return out


def test_a_person_is_found_at_their_centre_and_the_map_is_not() -> None:
    person = np.array([[3.0, 0.5, 0.25]])
    world = World(WALLS, person)
    found = people(world, mapped(WALLS))
    assert len(found) == 1
    assert math.hypot(found[0].x_m - 3.0, found[0].y_m - 0.5) < 0.05
    assert people(World(WALLS, np.zeros((0, 3))), mapped(WALLS)) == []  # walls are the map's


def test_an_unmapped_pillar_is_tracked_a_mapped_one_is_not() -> None:
    pillar = np.array([[2.5, -1.0, 0.2]])
    world = World(WALLS, pillar)
    assert len(people(world, mapped(WALLS))) == 1  # positive control: not in the map
    assert people(world, mapped(WALLS, pillar)) == []


def test_a_track_is_reported_after_three_hits_and_dropped_when_unseen() -> None:
    world = World(WALLS, np.array([[3.0, 0.0, 0.25]]))
    static = mapped(WALLS)
    tracker = PeopleTracker(static=static)
    got = [len(tracker.update(scan(world), (0.0, 0.0), k * 0.1)) for k in range(3)]
    assert got == [0, 0, 1]
    empty = World(WALLS, np.zeros((0, 3)))
    assert len(tracker.update(scan(empty), (0.0, 0.0), 0.5)) == 1  # coasting
    assert tracker.update(scan(empty), (0.0, 0.0), 0.81) == []  # unseen for > 0.5 s


def test_a_walking_person_gets_their_velocity() -> None:
    static = mapped(WALLS)
    tracker = PeopleTracker(static=static)
    for k in range(16):  # 1.5 s at 1 m/s across the corridor
        t = k * 0.1
        world = World(WALLS, np.array([[3.0, -1.2 + 1.0 * t, 0.25]]))
        found = tracker.update(scan(world), (0.0, 0.0), t)
    assert len(found) == 1
    assert abs(found[0].vx_mps) < 0.15 and abs(found[0].vy_mps - 1.0) < 0.15


def test_two_legs_are_one_person() -> None:
    legs = np.array([[3.0, 0.15, 0.07], [3.0, -0.15, 0.07]])
    found = people(World(WALLS, legs), mapped(WALLS))
    assert len(found) == 1 and abs(found[0].y_m) < 0.05


def test_what_the_live_map_has_not_observed_is_the_maps() -> None:
    """A wall just come into view lies in cells the live map (a second behind) has not taken
    in: not a person. Where the map has seen the floor, the same thing is one."""
    box = World(np.zeros((0, 4)), np.array([[3.0, 0.0, 0.25]]))
    res, w, h = 0.05, 200, 100  # x 0..10, y −2.5..2.5

    def grid(value: int) -> OccupancyGrid:
        data = np.full((h, w), value, np.uint8)
        return OccupancyGrid(stamp_ns=0, frame_id="odom", resolution_m=res, width=w,
                             height=h, origin_x_m=0.0, origin_y_m=-2.5, data=data.tobytes())

    assert len(people(box, StaticMap.from_grid(grid(20)))) == 1  # seen free: a person
    assert people(box, StaticMap.from_grid(grid(255))) == []  # never observed
    assert people(box, StaticMap.from_grid(grid(55))) == []  # leaning occupied (grazed)
    # A grid republished with the same cells (a parked chair's) reuses the map made of them;
    # one changed cell is taken in (positive control), as is a change of the grid's place.
    free = StaticMap.from_grid(grid(20))
    assert StaticMap.from_grid(grid(21), reuse=free) is free  # both seen free
    assert StaticMap.from_grid(grid(255), reuse=free) is not free
    moved = msgspec.structs.replace(grid(20), origin_x_m=0.05)
    assert StaticMap.from_grid(moved, reuse=free).origin_x_m == 0.05
