"""Mapping core on simulated scans of the default hallway, from known poses (pure)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.ndimage as ndi

from autochair.geometry import compose
from autochair.mapping.core import (
    PEOPLE_MARGIN_M,
    GridSpec,
    NoReturn,
    OccupancyMapper,
    OdomBuffer,
    VoxelCloud,
    Walkers,
    people_discs,
    scan_points,
)
from autochair.runtime.config import ChairGeometry
from autochair.sim.lidar.scanner import UrgParams, ray_scan
from autochair.sim.world import DEFAULT_WORLD, World, load_world, parse_world, raycast
from autochair_msgs import Odometry, People, TrackedPerson

MOUNT = ChairGeometry().laser_mount  # (0.8636, 0.2032, 0.0), the [chair] default
POSES = [(0.0, 0.0, 0.0), (2.5, 0.3, 0.4), (5.0, -0.2, 0.0), (7.5, 0.0, -0.5),
         (10.0, 0.2, 0.0), (12.5, 0.0, 0.6), (15.0, -0.3, 0.0), (18.0, 0.0, 0.0),
         (20.5, 0.4, math.pi), (8.0, 0.0, math.pi)]


def build_map(res: float = 0.05) -> tuple[OccupancyMapper, list[np.ndarray]]:
    world, params = load_world(), UrgParams()
    rng = np.random.default_rng(7)
    mapper = OccupancyMapper(GridSpec(res, 30.0, 12.0, -5.0, -6.0))
    inc = 2 * math.pi / params.ares
    amin = (params.amin - params.afrt) * inc
    hits = []
    for pose in POSES:
        laser = compose(pose, MOUNT)
        for _ in range(3):
            raw = ray_scan(world, params, pose, MOUNT, 0.01, rng)
            r = np.where(raw < params.dmin_mm, np.nan, raw / 1000.0)
            mapper.integrate(r, amin, inc, laser)
        clean = ray_scan(world, params, pose, MOUNT, 0.0, rng)
        hits.append(scan_points(np.where(clean < 20, np.nan, clean / 1000.0), amin, inc, laser))
    return mapper, hits


def test_occupied_cells_lie_on_the_walls_within_one_cell() -> None:
    mapper, _ = build_map()
    occ = mapper.occupied()
    assert occ.sum() > 1000  # a real map, not a handful of cells
    d = load_world().distance_to(mapper.cell_centres(occ))
    # A cell "on" a wall contains it: its centre is within half a diagonal; one cell of slack.
    assert d.max() <= mapper.res * (1 + math.sqrt(2) / 2), f"stray cell {d.max():.3f} m off"


def test_walls_seen_are_occupied_within_one_cell() -> None:
    mapper, hits = build_map()
    occ = mapper.occupied()
    pts = np.concatenate(hits)
    dil = occ.copy()  # occupied or next to an occupied cell
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            dil |= np.roll(np.roll(occ, dy, 0), dx, 1)
    cells = mapper.cells(pts)
    cells = cells[cells >= 0]
    covered = dil.reshape(-1)[cells].mean()
    assert covered >= 0.98, f"only {covered:.1%} of wall returns are mapped"


def test_free_space_in_the_hallway_is_free() -> None:
    mapper, _ = build_map()
    cells = mapper.cells(np.array([[1.0, 0.0], [4.5, -1.0], [9.0, -0.5], [16.0, 1.0]]))
    assert (mapper.logodds.reshape(-1)[cells] < -1.0).all()


def test_grid_message_and_unknown_cells() -> None:
    mapper, _ = build_map(0.1)
    msg = mapper.to_msg(1, "odom")
    data = np.frombuffer(msg.data, dtype=np.uint8).reshape(msg.height, msg.width)
    assert (msg.width, msg.height) == (300, 120)
    assert data[0, 0] == 255  # far corner never observed
    ix = int((3.0 + 5.0) / 0.1)  # the left wall at x=3, y=1.4 (row of y 1.4)
    iy = int((1.4 + 6.0) / 0.1)
    assert data[iy - 1:iy + 1, ix].max() > 60


def test_voxel_cloud_is_bounded_and_deduplicated() -> None:
    cloud = VoxelCloud(0.1, max_points=50)
    cloud.add(np.array([[0.01, 0.01], [0.02, 0.03], [0.5, 0.5]]), 0.4)
    assert len(cloud) == 2
    cloud.add(np.random.default_rng(0).uniform(-10, 10, (500, 2)), 0.4)
    msg = cloud.to_msg(1)
    assert len(cloud) == 50 and msg.count == 50 and len(msg.points_xyz_f32) == 50 * 12


def test_odom_lookup_nearest_and_stale() -> None:
    buf = OdomBuffer()
    for k in range(10):
        buf.add(Odometry(stamp_ns=k * 5_000_000, x_m=k * 0.01, y_m=0.0, yaw_rad=0.0,
                         v_mps=0.0, omega_radps=0.0))
    pose = buf.nearest(21_000_000, 10_000_000)
    assert pose is not None and pose[0] == pytest.approx(0.04)
    assert buf.nearest(500_000_000, 100_000_000) is None


def test_compose_mount() -> None:
    x, y, yaw = compose((1.0, 2.0, math.pi / 2), MOUNT)
    assert (x, y, yaw) == pytest.approx((1.0 - 0.2032, 2.0 + 0.8636, math.pi / 2))


def test_a_parked_chairs_scans_are_integrated_once_a_second() -> None:
    from autochair.mapping.core import MoveGate

    gate = MoveGate(min_move_m=0.02, min_turn_rad=0.02, max_age_ns=1_000_000_000)
    ms = 1_000_000
    parked = [t for t in range(0, 3000 * ms, 100 * ms) if gate.take((1.0, 2.0, 0.5), t)]
    assert parked == [0, 1000 * ms, 2000 * ms]  # 10 scans/s parked: one a second
    # Moving (positive control): every scan that moved 2 cm or turned 0.02 rad counts.
    assert gate.take((1.03, 2.0, 0.5), 3000 * ms)
    assert gate.take((1.03, 2.0, 0.53), 3100 * ms)
    assert not gate.take((1.035, 2.0, 0.53), 3200 * ms)


def test_a_driving_chairs_scans_are_taken_every_10_cm_or_6_degrees() -> None:
    """The defaults the mapping and localization nodes use: a scan once the chair has moved
    10 cm or turned 0.1 rad since the last one taken (at the soak's 0.5 m/s and 0.6 rad/s,
    about every other scan); at 1.2 m/s every scan."""
    from autochair.mapping.core import MoveGate

    ms = 1_000_000
    for step, turn in ((0.05, 0.0), (0.0, 0.06), (0.12, 0.0)):
        gate = MoveGate()
        taken = [k for k in range(40) if gate.take((k * step, 0.0, k * turn), k * 100 * ms)]
        gaps = np.diff(taken)
        moved = gaps * max(step, turn)
        assert (moved >= 0.1 - 1e-9).all() and (moved <= 0.1 + max(step, turn) + 1e-9).all()
        assert len(taken) >= (40 if step > 0.1 else 13)


def test_a_scan_is_placed_by_odometry_along_its_sweep_or_skipped_with_a_reason() -> None:
    """The mapping service's placement (bench/scan_map.py calls the same function): the laser
    at the stamp, each beam where the laser was as it took it, the mount applied once."""
    from autochair.mapping.core import MoveGate, Placed, place_scan

    buf, gate, ms = OdomBuffer(), MoveGate(), 1_000_000
    assert place_scan(buf, gate, 0, 3, 0.035, MOUNT, 250 * ms) == "scans_no_odom"
    nowhere = place_scan(buf, MoveGate(), 0, 3, 0.035, MOUNT, 250 * ms, (0.0, 0.0, 0.0))
    assert isinstance(nowhere, Placed) and nowhere.laser == pytest.approx(MOUNT)
    for k in range(11):  # driving +x at 1 m/s, sampled every 20 ms
        buf.add(Odometry(stamp_ns=k * 20 * ms, x_m=k * 0.02, y_m=0.0, yaw_rad=0.0, v_mps=1.0,
                           omega_radps=0.0))
    placed = place_scan(buf, gate, 100 * ms, 3, 0.035, MOUNT, 250 * ms)
    assert isinstance(placed, Placed) and placed.beams is not None
    assert placed.laser == pytest.approx(compose((0.1, 0.0, 0.0), MOUNT))
    lx, _, _ = placed.beams
    assert lx == pytest.approx([0.1 + MOUNT[0], 0.135 + MOUNT[0], 0.17 + MOUNT[0]])
    # the same place again within a second: not mapped twice
    assert place_scan(buf, gate, 120 * ms, 3, 0.035, MOUNT, 250 * ms) == "scans_still"
    # one instant (no beam timing): the laser's pose for every beam
    one = place_scan(buf, MoveGate(), 100 * ms, 3, 0.0, MOUNT, 250 * ms)
    assert isinstance(one, Placed) and one.beams is None


# No-return beams (mapping/core.py NoReturn): a laser pose's scan of a world, NaN where
# nothing is within the URG's 5.6 m (as the ingest gives it).
URG = UrgParams()
INC = 2 * math.pi / URG.ares
AMIN = (URG.amin - URG.afrt) * INC
ANGLES = AMIN + INC * np.arange(URG.amax - URG.amin + 1, dtype=np.float64)


def laser_scan(world: World, pose: tuple[float, float, float]) -> np.ndarray:
    r = raycast(world, pose[0], pose[1], ANGLES + pose[2], URG.dmax_mm / 1000.0)
    return np.where(np.isfinite(r), r, np.nan)


def stray(mapper: OccupancyMapper, walls: World, x: float) -> int:
    """Occupied cells (as the control service reads them: ≥ 65 %) more than 0.1 m from every
    wall of `walls`, within 0.4 m of `x` in x."""
    pts = mapper.cell_centres(mapper.occupied(0.62))
    pts = pts[np.abs(pts[:, 0] - x) <= 0.4]
    return int((walls.distance_to(pts) > 0.1).sum())


def test_a_walkers_trail_is_cleared_by_beams_with_no_return_up_to_their_range() -> None:
    """A hall 5 m wide whose far end is beyond the laser's range, the chair parked (a scan a
    second, MoveGate), someone crossing it 1.5 m (or 3.5 m) ahead at 0.4 m/s: the beams past
    them find nothing, and before, their trail stayed mapped for good (nav_eval --map scans:
    the person cases ×3.0–3.3 the least time). Cleared within NoReturn.range_m (2 m) of the
    laser, not beyond."""
    walls = parse_world("wall -1 -2.5 30 -2.5\nwall -1 2.5 30 2.5")
    laser = (0.0, 0.0, 0.0)
    trail: dict[tuple[float, bool], int] = {}
    for x in (1.5, 3.5):
        maps = {clear: OccupancyMapper(GridSpec(0.05, 12.0, 6.0, -2.0, -3.0),
                                       no_return=NoReturn() if clear else None)
                for clear in (False, True)}
        for y in [*np.arange(-2.0, 2.1, 0.4), None, None, None]:  # 0.4 m a scan, then gone
            world = walls if y is None else parse_world(
                f"wall -1 -2.5 30 -2.5\nwall -1 2.5 30 2.5\ncircle {x} {y} 0.25")
            for m in maps.values():
                m.integrate(laser_scan(world, laser), AMIN, INC, laser)
        trail |= {(x, clear): stray(m, walls, x) for clear, m in maps.items()}
    assert trail[1.5, False] >= 5  # as before
    assert trail[1.5, True] == 0
    # beyond range_m it stays (a dark obstacle there is not erased either)
    assert trail[3.5, True] == trail[3.5, False] >= 5


def test_an_obstacle_with_no_return_from_some_angles_stays_mapped() -> None:
    """HAZARD: a dark or glancing surface gives no return either, and erasing it from the
    map would plan the chair into it (the safety monitor keeps no memory: a beam with no
    return is no point to it). A dark bin in a room, seen from the chair driving towards it
    (2.5 m of scans, one each 10 cm), then giving no return as the chair passes and stands
    1.6 m beyond it for 30 scans: the map is no more optimistic than without clearing (the
    distance to the nearest occupied cell, read round the bin, is the same: cells behind its
    face may go, 2 of 20). Positive control: without the floor (`keep_above`) the bin is
    eroded (11 of 20 cells) and the map reads farther from it."""
    room = "wall -1 -2 7 -2\nwall 7 -2 7 2\nwall 7 2 -1 2\nwall -1 2 -1 -2"
    world, walls = parse_world(room + "\nbox 3.0 0.8 0.4 0.4"), parse_world(room)
    variants = (None, NoReturn(), NoReturn(keep_above=math.inf))
    maps = [OccupancyMapper(GridSpec(0.05, 10.0, 6.0, -2.0, -3.0), no_return=nr)
            for nr in variants]
    for k in range(61):
        laser = (min(k * 0.1, 4.0), -0.5, 0.0)
        r = laser_scan(world, laser)
        if laser[0] >= 2.5:  # past its face: no return from it
            r[laser_scan(walls, laser) != r] = np.nan
        for m in maps:
            m.integrate(r, AMIN, INC, laser)
    m = maps[0]
    iy, ix = np.mgrid[0:m.h, 0:m.w]
    pts = np.stack([m.spec.origin_x_m + (ix.ravel() + 0.5) * m.res,
                    m.spec.origin_y_m + (iy.ravel() + 0.5) * m.res], axis=1)
    inside = (np.abs(pts[:, 0] - 3.0) < 0.2) & (np.abs(pts[:, 1] - 0.8) < 0.2)
    d_bin = parse_world("box 3.0 0.8 0.4 0.4").distance_to(pts)
    around = ~inside & (d_bin >= 0.1) & (d_bin <= 1.0)
    edt = [ndi.distance_transform_edt(~mm.occupied(0.62)).ravel()[around] for mm in maps]
    assert (edt[0] < 10).sum() > 100  # the bin was mapped: cells round it read it
    assert np.array_equal(edt[1], edt[0])
    assert (edt[2] > edt[0]).any()  # the floor is what keeps it


def test_a_blinded_laser_clears_nothing() -> None:
    """A scan with fewer than NoReturn.min_valid of its beams valid (a blinded or dazzled
    laser: error codes everywhere) clears nothing; with enough valid beams its no-return
    ones do (positive control)."""
    world = parse_world("box 1.52 0.0 0.4 0.4")
    m = OccupancyMapper(GridSpec(0.05, 6.0, 6.0, -3.0, -3.0), no_return=NoReturn())
    laser = (0.0, 0.0, 0.0)
    m.integrate(laser_scan(world, laser), AMIN, INC, laser)  # the box seen once
    box = m.cells(np.array([[1.33, 0.0]]))[0]
    hit = float(m.logodds.reshape(-1)[box])
    assert hit > 0.62
    third = ANGLES.size // 3
    scan = np.full(ANGLES.size, np.nan)  # the box's way (0°) gives no return in both
    scan[:third] = 3.0  # a third valid (nothing within 3 m that way)
    for _ in range(5):
        m.integrate(scan, AMIN, INC, laser)
    assert m.logodds.reshape(-1)[box] == hit
    scan[-third:] = 3.0  # two thirds valid
    for _ in range(2):
        m.integrate(scan, AMIN, INC, laser)
    assert m.logodds.reshape(-1)[box] < 0.62


def test_a_tracked_walkers_returns_are_not_mapped_and_leave_no_trail() -> None:
    """nav_eval's door_person world: someone pacing across room B's door, seen through it
    from room A by a chair driving up to it (a scan mapped every 0.1 s). Their returns left a
    trail across the door's exit (on the laser's map, nav_eval seed 7: 6 cells there as the
    chair stood in the door; the way from it then turned back, H75). The returns within the
    people the control service tracks (keys.PEOPLE, `people_discs`) are theirs, not the
    map's: no trail; without them (the old map) one; the walls are mapped alike."""
    world = load_world(DEFAULT_WORLD.parent / "door_person.world")
    walls = World(world.segments, world.circles)
    stray_cells, wall_cells = {}, {}
    for tracked in (False, True):
        m = OccupancyMapper(GridSpec(0.05, 12.0, 6.0, -2.0, -3.0))
        for k in range(10):
            t = 1.0 + 0.1 * k
            laser = compose((min(2.6 + 0.37 * t, 3.17), 1.0, 0.0), MOUNT)
            x, y, vx, vy, r = world.people_state(t)[0]
            report = People(stamp_ns=round(t * 1e9), frame_id="odom", people=[TrackedPerson(
                track_id=1, x_m=x, y_m=y, vx_mps=vx, vy_mps=vy, radius_m=r)])
            m.integrate(laser_scan(world.at(t), laser), AMIN, INC, laser,
                        people=people_discs(report, round(t * 1e9), "odom") if tracked
                        else None)
        pts = m.cell_centres(m.occupied(0.62))
        far = walls.distance_to(pts)
        stray_cells[tracked], wall_cells[tracked] = int((far > 0.1).sum()), int((far <= 0.1).sum())
    assert stray_cells[False] >= 5  # (the old map: the walker's trail)
    assert stray_cells[True] == 0
    assert wall_cells[True] == wall_cells[False] > 50


def test_people_discs_are_moved_to_the_scan_or_not_used() -> None:
    report = People(stamp_ns=1_000_000_000, frame_id="odom", people=[TrackedPerson(
        track_id=1, x_m=1.0, y_m=2.0, vx_mps=1.0, vy_mps=0.0, radius_m=0.25)])
    d = people_discs(report, 1_200_000_000, "odom")
    assert d is not None and d[0] == pytest.approx([1.2, 2.0, 0.25 + PEOPLE_MARGIN_M + 0.2])
    assert people_discs(report, 1_200_000_000, "map") is None  # (another frame)
    assert people_discs(report, 1_600_000_000, "odom") is None  # (too old: all mapped)
    assert people_discs(None, 0, "odom") is None


def test_only_the_tracks_that_have_walked_are_left_out_of_the_map() -> None:
    """Something set down in floor the map had seen free (a bin, a door leaf) can be tracked as
    a person: it is mapped as before (and, the map's, dropped by the tracker), not left out
    for good. A track is a walker once reported WALKED_M from where it was first."""
    w = Walkers()

    def report(*tracks: tuple[int, float, float]) -> People:
        return People(stamp_ns=0, frame_id="odom", people=[TrackedPerson(
            track_id=i, x_m=x, y_m=y, vx_mps=0.0, vy_mps=0.0, radius_m=0.25)
            for i, x, y in tracks])

    assert not w.of(report((1, 0.0, 0.0), (2, 5.0, 0.0))).people
    assert not w.of(report((1, 0.05, 0.02), (2, 5.3, 0.0))).people  # (jitter, 0.3 m)
    walkers = w.of(report((1, 0.04, -0.03), (2, 5.6, 0.0))).people
    assert [q.track_id for q in walkers] == [2]
    assert [q.track_id for q in w.of(report((2, 5.0, 0.0))).people] == [2]  # (still walked)
    assert not w.of(report((3, 5.0, 0.0))).people  # (a new track: not yet)
    assert not w.of(report((2, 5.0, 0.0))).people  # (2 was left out: forgotten)
