"""Localization core (pure): drift in the simulated chair, scan matching, the filter with its
lost/recovered states, global localization, the pose graph, maps as ROS map_server files."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from bench import loc_eval

from autochair.localization.core import Localizer, LocParams, LocState
from autochair.localization.graph import PoseGraph
from autochair.localization.matching import DistanceField, compose, refine
from autochair.localization.node import localizer_for, map_from_grid
from autochair.localization.slam import MapRenderer, Slam, render
from autochair.mapping.mapfile import MapFile, MapFileError, load_map, map_path, save_map
from autochair.odometry.core import OdometryCore
from autochair.sim.chair.model import NEUTRAL_V, ChairModel, ChairParams, volts
from autochair.sim.lidar.scanner import UrgParams
from autochair.sim.world import load_world
from autochair_msgs import keys

DT = 1.0 / keys.DRIVE_RATE_HZ


def _drive(params: ChairParams, lv: float, av: float, seconds: float) -> tuple[
        ChairModel, OdometryCore]:
    m, odo = ChairModel(params), OdometryCore()
    for k in range(round(seconds / DT)):
        m.step(lv, av, DT)
        odo.update(m.left_counts, m.right_counts, round((k + 1) * DT * 1e6))
    return m, odo


def test_drift_off_odometry_follows_truth() -> None:
    m, odo = _drive(ChairParams(), volts(0.3), volts(0.2), 20.0)
    assert math.hypot(odo.x - m.x, odo.y - m.y) < 0.01
    assert abs(odo.yaw - m.yaw) < 0.005


def test_drift_on_odometry_drifts_truth_stays_kinematic() -> None:
    """Turning in place: odometry over-reads the turn by the base ratio (the true base is
    longer than the nominal one) and by the skid; straight ahead, the diameter mismatch bends
    the odometry while the chair goes straight."""
    p = ChairParams(drift=True, slip_noise=0.0, slip_accel_per_mps2=0.0)
    m, odo = _drive(p, NEUTRAL_V, volts(0.4), 3.0)
    m0, odo0 = _drive(ChairParams(), NEUTRAL_V, volts(0.4), 3.0)  # positive control
    assert 1.0 < m.yaw < 3.0  # no wrap in the ratio below
    assert odo0.yaw / m0.yaw == pytest.approx(1.0, abs=1e-3)
    assert 1.02 < odo.yaw / m.yaw < 1.06
    p = ChairParams(drift=True, base_ratio=1.0, slip_turn_per_radps=0.0, slip_noise=0.0)
    m, odo = _drive(p, volts(0.4), NEUTRAL_V, 20.0)
    assert abs(m.y) < 1e-6 and abs(m.yaw) < 1e-9
    assert abs(odo.y) > 0.05


def test_drift_is_seeded() -> None:
    a, _ = _drive(ChairParams(drift=True, seed=3), volts(0.3), volts(0.3), 5.0)
    b, _ = _drive(ChairParams(drift=True, seed=3), volts(0.3), volts(0.3), 5.0)
    c, _ = _drive(ChairParams(drift=True, seed=4), volts(0.3), volts(0.3), 5.0)
    assert (a.x, a.y, a.left_counts) == (b.x, b.y, b.left_counts)
    assert (a.x, a.y) != (c.x, c.y)


def _hallway() -> tuple[DistanceField, np.ndarray]:
    world = load_world()
    occ, frame = loc_eval.world_grid(world, 0.05, margin=1.0 + 0.5 * 0.05)
    return DistanceField(occ, frame), loc_eval.free_cells(world, occ, frame, (0.0, 0.0))


def test_refine_converges_from_an_offset() -> None:
    field, _ = _hallway()
    truth = (9.0, 0.1, 0.2)
    pts = loc_eval.scan_points(load_world(), UrgParams(), truth, np.random.default_rng(0))
    start = compose(np.array(truth), np.array([0.15, -0.1, math.radians(4)]))
    m = refine(field, pts, start)
    assert math.hypot(m.pose[0] - truth[0], m.pose[1] - truth[1]) < 0.02
    assert abs(m.pose[2] - truth[2]) < math.radians(0.5)
    assert m.inliers > 0.9
    # Positive control for the quality figure: a pose far off fits badly.
    assert refine(field, pts, np.array([15.0, 0.0, 1.5]), iterations=1).inliers < 0.5


def test_tracking_beats_drifting_odometry() -> None:
    samples = list(loc_eval.simulate("hallway", 1.0, seed=5))
    s = loc_eval.score(samples)
    assert s["odom_ate_max_m"] > 0.3  # the drift is real ...
    assert s["ate_rmse_m"] < 0.05 and s["ate_max_m"] < 0.10  # ... and corrected
    assert s["lost_scans"] == 0


def test_kidnap_is_lost_then_recovered_within_5s() -> None:
    r = loc_eval.kidnap("hallway", at_s=30.0)
    assert r["recovered"] == 1.0 and r["recovery_s"] <= 5.0


def test_lost_when_the_scan_does_not_fit_then_recovers() -> None:
    field, free = _hallway()
    world, urg, rng = load_world(), UrgParams(), np.random.default_rng(1)
    loc = Localizer(field, free)
    truth = (6.0, 0.0, 0.0)
    loc.set_pose(np.array([3.0, 0.5, 0.9]))  # told a wrong pose: 3 m and 50° off
    states = []
    for _ in range(40):
        e = loc.update(np.zeros(3), loc_eval.scan_points(world, urg, truth, rng))
        states.append(e.state)
        if e.state is LocState.TRACKING and states.count(LocState.LOST):
            break
    assert LocState.LOST in states
    assert states[-1] is LocState.TRACKING
    assert math.hypot(e.pose[0] - truth[0], e.pose[1] - truth[1]) < 0.05


def _parked_map_localizer() -> Localizer:
    """On the map SLAM makes of the hallway from a chair parked at the origin (as
    `autochair map save` would keep it): a corridor whose matcher has local minima 10-20 cm
    along it that fit 0.98."""
    world, urg, rng = load_world(), UrgParams(), np.random.default_rng(0)
    slam = Slam()
    for _ in range(15):
        slam.update(np.zeros(3), loc_eval.laser_scan(world, urg, (0.0, 0.0, 0.0), rng))
    return localizer_for(map_from_grid(slam.render()))


def _scans_to_chair(loc: Localizer, seed: int, limit: int = 40) -> tuple[int, list[LocState]]:
    """Scans of the parked chair at the origin until tracking within 3 cm of it."""
    world, urg, rng = load_world(), UrgParams(), np.random.default_rng(seed)
    states = []
    for k in range(1, limit + 1):
        e = loc.update(np.zeros(3), loc_eval.scan_points(world, urg, (0.0, 0.0, 0.0), rng))
        states.append(e.state)
        if e.state is LocState.TRACKING and math.hypot(e.pose[0], e.pose[1]) < 0.03:
            return k, states
    return limit + 1, states


WRONG_HINT = np.array([0.3, -0.2, math.radians(5)])  # 36 cm and 5° off the parked chair


def test_a_persons_guess_is_checked_by_a_search_before_it_is_tracked() -> None:
    loc = _parked_map_localizer()
    loc.hint(WRONG_HINT.copy(), 0.3, 0.2)
    assert loc.state is LocState.INITIALIZING  # nothing claimed before a scan fits near it
    scans, states = _scans_to_chair(loc, seed=1)
    assert scans == 1 and states == [LocState.TRACKING]
    # Positive control: tracked from the guess itself (as before), it stays off the chair.
    trusted = _parked_map_localizer()
    trusted.set_pose(WRONG_HINT.copy(), 0.3, 0.2)
    assert _scans_to_chair(trusted, seed=1, limit=3)[0] > 3
    # A guess that nothing fits near (3 m and 50° off, told ±10 cm): the whole map searched.
    far = _parked_map_localizer()
    far.hint(np.array([3.0, 0.5, 0.9]), 0.1, 0.1)
    scans, states = _scans_to_chair(far, seed=2)
    assert states[0] is LocState.INITIALIZING and scans <= 10


def _pushed(params: LocParams, seed: int) -> int:
    """Tracking a chair parked 36 cm and 5° from the origin; then it is pushed to the origin
    with its wheels free (the odometry does not move): scans until tracked there."""
    world, urg, rng = load_world(), UrgParams(), np.random.default_rng(100 + seed)
    loc = _parked_map_localizer()
    loc.p = params
    loc.set_pose(WRONG_HINT.copy(), 0.01, 0.01)
    for _ in range(5):
        e = loc.update(np.zeros(3), loc_eval.scan_points(world, urg, tuple(WRONG_HINT), rng))
    assert e.state is LocState.TRACKING and math.hypot(*(e.pose[:2] - WRONG_HINT[:2])) < 0.03
    return _scans_to_chair(loc, seed=seed, limit=60)[0]


def test_a_parked_chair_pushed_elsewhere_is_found_by_a_search() -> None:
    assert [_pushed(LocParams(), seed) for seed in (0, 3)] == [3, 3]  # the confirmation
    # Positive control: without the search, the refine from the old pose stops short (local
    # minima along the corridor) and the jump waits for three far matches in a row.
    assert min(_pushed(LocParams(still_m=0.0), seed) for seed in (0, 3)) > 10


def test_a_lost_searchs_weak_fit_is_checked_against_the_whole_map() -> None:
    """Lost 3 m along the corridor from the chair: the search's window reaches a 0.86 fit
    1.9 m off (an alias) before the chair's own 1.00; the alias is not taken (seed 2; also
    seeds 3 and 5 took it before, 0-5 all recover now)."""
    loc = _parked_map_localizer()
    loc.set_pose(np.array([3.0, 0.5, 0.9]), 0.1, 0.1)
    scans, states = _scans_to_chair(loc, seed=2)
    assert LocState.LOST in states and scans <= 10
    # Positive control: without the check against the whole map, the alias is tracked.
    alias = _parked_map_localizer()
    alias.p = LocParams(sure_quality=0.0)
    alias.set_pose(np.array([3.0, 0.5, 0.9]), 0.1, 0.1)
    world, urg, rng = load_world(), UrgParams(), np.random.default_rng(2)
    for _ in range(8):
        e = alias.update(np.zeros(3), loc_eval.scan_points(world, urg, (0.0, 0.0, 0.0), rng))
        if e.state is LocState.LOST:
            break
    e = alias.update(np.zeros(3), loc_eval.scan_points(world, urg, (0.0, 0.0, 0.0), rng))
    assert e.state is LocState.TRACKING and e.pose[0] > 1.5  # found, at the alias


def test_global_localization_without_initial_pose() -> None:
    field, free = _hallway()
    world, urg, rng = load_world(), UrgParams(), np.random.default_rng(2)
    loc = Localizer(field, free)
    truth = (12.4, -0.3, math.radians(100))  # looking into office B
    for _ in range(5):
        e = loc.update(np.zeros(3), loc_eval.scan_points(world, urg, truth, rng))
        if e.state is LocState.TRACKING:
            break
    assert e.state is LocState.TRACKING
    assert math.hypot(e.pose[0] - truth[0], e.pose[1] - truth[1]) < 0.05


def test_pose_graph_closes_a_square() -> None:
    """Odometry edges that under-turn each corner by 3°; one loop edge start→end."""
    g = PoseGraph()
    info = np.diag([1e4, 1e4, 1e4])
    pose = np.zeros(3)
    g.add_node(pose)
    for k in range(40):
        step = np.array([1.0, 0.0, math.radians(87) if k % 10 == 9 else 0.0])
        pose = compose(pose, step)
        g.add_node(pose)
        g.add_edge(k, k + 1, step, info)
    end_before = np.linalg.norm(g.nodes[-1][:2])
    assert end_before > 1.0  # positive control: without the loop edge the square is open
    g.add_edge(0, 40, np.array([0.0, 0.0, math.radians(-12)]), np.diag([1e6] * 3), loop=True)
    g.optimize()
    assert np.linalg.norm(g.nodes[-1][:2]) < 0.02
    assert np.linalg.norm(g.nodes[0]) < 1e-6  # the first node is held


def test_map_file_round_trip(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    occ = rng.random((37, 53)) < 0.1
    free = ~occ & (rng.random(occ.shape) < 0.7)
    m = MapFile(occ, free, 0.05, -3.25, 1.5)
    path = save_map(m, map_path(tmp_path, "floor-2"))
    back = load_map(path)
    assert np.array_equal(back.occupied, occ) and np.array_equal(back.free, free)
    assert (back.resolution_m, back.origin_x_m, back.origin_y_m) == (0.05, -3.25, 1.5)
    # ROS convention: the image's top row is the map's largest y.
    pgm = path.with_suffix(".pgm").read_bytes()
    first_row = pgm[-occ.size:][:occ.shape[1]]
    assert first_row == bytes(0 if o else 254 if f else 205
                              for o, f in zip(occ[-1], free[-1], strict=True))
    assert "image: floor-2.pgm" in path.read_text()


def test_map_file_read_like_map_server(tmp_path: Path) -> None:
    """A map_saver-style file with comments and negate=1."""
    (tmp_path / "m.pgm").write_bytes(b"P5\n# CREATOR: map_saver\n2 1\n255\n\x00\xff")
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.1\norigin: [1.0, 2.0, 0.0]\n"
                                     "negate: 1\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    m = load_map(tmp_path / "m.yaml")
    assert m.free.tolist() == [[True, False]] and m.occupied.tolist() == [[False, True]]


@pytest.mark.parametrize("name", ["../x", "a/b", "", "x.yaml", ".hidden"])
def test_map_names_cannot_escape(name: str) -> None:
    with pytest.raises(MapFileError):
        map_path("/tmp", name)


def test_map_file_errors_name_the_problem(tmp_path: Path) -> None:
    (tmp_path / "m.pgm").write_bytes(b"P5 1 1 255\n\x00")
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.1\n")
    with pytest.raises(MapFileError, match="missing origin"):
        load_map(tmp_path / "m.yaml")
    with pytest.raises(MapFileError, match="cannot read"):
        load_map(tmp_path / "none.yaml")
    # A rotated map: localization and navigation take the grid's axes as the map's, the
    # keep-out zones would have been rotated: refused rather than half-honoured.
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0.3]\n"
                                     "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    with pytest.raises(MapFileError, match=r"origin yaw 0\.3 rad: rotated maps are not supported"):
        load_map(tmp_path / "m.yaml")
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n"
                                     "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    assert load_map(tmp_path / "m.yaml").occupied.shape == (1, 1)  # positive control


def test_chair_params_defaults_keep_drift_off() -> None:
    assert ChairParams().drift is False
    assert replace(ChairParams(), drift=True).base_ratio != 1.0


def test_odom_buffer_interpolates_between_samples() -> None:
    from autochair.mapping.core import OdomBuffer
    from autochair_msgs import Odometry

    buf = OdomBuffer()
    for k, (x, yaw) in enumerate([(0.0, 3.1), (0.2, -3.1)]):  # across the ±π seam
        buf.add(Odometry(stamp_ns=k * 20_000_000, x_m=x, y_m=0.0, yaw_rad=yaw, v_mps=0.0,
                         omega_radps=0.0))
    x, _, yaw = buf.at(5_000_000, 50_000_000) or (0.0, 0.0, 0.0)
    assert x == pytest.approx(0.05)
    assert yaw == pytest.approx(3.1 + 0.25 * (2 * math.pi - 6.2))  # the short way round
    assert buf.at(10**9, 50_000_000) is None  # not bracketed, nothing near


def test_map_renderer_draws_new_keyframes_and_redraws_after_a_correction() -> None:
    """The live map grows by the new keyframes only (one full render), equals a full render,
    and is redrawn whole when a keyframe it drew has moved (a loop closure)."""
    slam = Slam()
    slam.pose = np.array(loc_eval.ROUTES["hallway"][0], dtype=np.float64)
    r = MapRenderer(slam.p)
    for k, tick in enumerate(loc_eval.drive("hallway", 0.4)):
        slam.update(tick.odom, tick.scan)
        if k == 100:
            r.update(*slam.snapshot())
    nodes, kfs = slam.snapshot()
    assert 10 < len(r.drawn) < len(kfs)  # the second update has new keyframes to draw
    grid = r.update(nodes, kfs)
    assert r.full_renders == 1  # drawn incrementally

    def cells(g: object) -> set[tuple[int, int]]:
        occ = g.occupied()  # type: ignore[attr-defined]
        s = g.spec  # type: ignore[attr-defined]
        iy, ix = np.nonzero(occ)
        return set(zip((ix + round(s.origin_x_m / s.resolution_m)).tolist(),
                       (iy + round(s.origin_y_m / s.resolution_m)).tolist(), strict=True))

    full = cells(render(nodes, kfs, slam.p))
    # the same walls; a few cells differ where keyframes moved by less than the redraw
    # tolerance (half a cell) or a point falls on a cell edge of the other grid's origin
    assert len(full) > 200 and len(full ^ cells(grid)) <= 0.02 * len(full)
    moved = [n.copy() for n in nodes]
    moved[5][0] += 0.3
    r.update(moved, kfs)
    assert r.full_renders == 2
