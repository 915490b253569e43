"""Keep-out zones in the safety monitor (H42, safety/keepout.py): places the laser cannot see
(stairs down, a kerb, glass) marked on a mask map, placed with localization; a stop while they
cannot be placed."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from autochair.mapping.mapfile import MapFile, load_map, save_map
from autochair.safety.core import SafetyCore, SafetyParams, SafetyTuning, Scan
from autochair.safety.keepout import Keepout, paint, zone_edges
from autochair.safety.monitor import Monitor
from autochair_msgs import OccupancyGrid

RES = 0.05
CORRECTION = (1.0, 0.5, 0.0)  # map → odom: odometry's origin at (1, 0.5) on the map
WALLS = [(-4.8, -4.8, -4.4, -4.4), (-4.8, 4.4, 4.8, 4.8)]  # the map's: a pillar and a wall


def mask(zones: list[tuple[float, float, float, float]], size_m: float = 10.0,
         walls: bool = True) -> MapFile:
    """A mask over [-size/2, size/2]² in map, as a person draws it: a copy of the map (its
    walls) with each zone (x0, y0, x1, y1) painted occupied."""
    n = round(size_m / RES)
    occ = np.zeros((n, n), dtype=bool)
    origin = -size_m / 2
    for x0, y0, x1, y1 in zones + (WALLS if walls else []):
        c0, c1 = round((x0 - origin) / RES), round((x1 - origin) / RES)
        r0, r1 = round((y0 - origin) / RES), round((y1 - origin) / RES)
        occ[r0:r1, c0:c1] = True
    return MapFile(occ, ~occ, RES, origin, origin)


def map_grid(m: MapFile | None = None) -> OccupancyGrid:
    """Localization's map as it publishes it (keys.LOC_MAP, its own `grid_msg`): by default
    the one the masks are drawn over (the walls alone)."""
    from autochair.localization.node import grid_msg

    return grid_msg(m or mask([]), 0, "map")


def open_scan() -> Scan:
    """Nothing within 4 m all round the laser's 240°: the path is clear for the laser."""
    n = 682
    inc = math.radians(240) / (n - 1)
    return Scan(np.full(n, 4.0), -(n - 1) / 2 * inc, inc, 0.02, 5.6, "laser")


def monitor(keepout: Keepout | None) -> Monitor:
    core = SafetyCore(SafetyParams.of(SafetyTuning(), 0.95, 0.25, 0.35, (0.8636, 0.0, 0.0)))
    return Monitor(core, 0.5, 0.3, 1.0, "laser", keepout=keepout)


def localized(m: Monitor, now: float, state: str = "tracking") -> None:
    m.on_correction(CORRECTION)
    m.on_loc_state(state, "localization", now)
    m.on_loc_map(map_grid())


def test_zone_edges_are_the_cells_touching_the_outside() -> None:
    m = mask([(0.0, 0.0, 0.2, 0.2)], walls=False)  # 4 × 4 cells
    edges = zone_edges(m)
    assert len(edges) == 12  # 16 cells less the 2 × 2 inside
    assert edges[:, 0].min() == pytest.approx(0.025) and edges[:, 0].max() == pytest.approx(0.175)


def test_a_mask_file_round_trips(tmp_path: Path) -> None:
    """The format a person draws zones in: a map_server PGM + YAML."""
    path = save_map(mask([(2.0, -1.0, 2.5, 1.0)]), tmp_path / "keepout.yaml")
    assert len(zone_edges(load_map(path))) == len(zone_edges(mask([(2.0, -1.0, 2.5, 1.0)])))


def test_a_zone_ahead_limits_the_chair_like_a_wall_and_one_aside_does_not() -> None:
    now = 100.0
    # A band across the path 1.5 m ahead of the chair's centre (map x 2.5: the chair is at
    # map (1, 0.5) when odometry says (0, 0)).
    ahead = monitor(Keepout(mask([(2.5, -2.0, 3.0, 3.0)])))
    localized(ahead, now)
    ahead.on_odom(0.0, 0.0, now, (0.0, 0.0, 0.0))
    lim = ahead.on_scan(open_scan(), now).published
    assert lim.free_fwd_m == pytest.approx(1.5 - 0.95, abs=0.06)
    assert 0.0 < lim.v_fwd < 1.0
    # Positive control: the same zone 3 m to the side does not limit forward motion.
    aside = monitor(Keepout(mask([(2.5, 3.5, 3.0, 4.5)])))
    localized(aside, now)
    aside.on_odom(0.0, 0.0, now, (0.0, 0.0, 0.0))
    free = aside.on_scan(open_scan(), now).published
    assert free.free_fwd_m == math.inf and free.v_fwd > lim.v_fwd
    # Turned 90° in odom, the band is to the chair's right: forward is free again.
    ahead.on_odom(0.0, 0.0, now, (0.0, 0.0, math.pi / 2))
    assert ahead.on_scan(open_scan(), now).published.free_fwd_m == math.inf


def test_zones_that_cannot_be_placed_are_a_stop_with_the_reason() -> None:
    now = 100.0
    m = monitor(Keepout(mask([(2.5, -2.0, 3.0, 3.0)])))
    m.on_odom(0.0, 0.0, now, (0.0, 0.0, 0.0))
    v = m.on_scan(open_scan(), now)
    assert (v.published.v_fwd, v.published.v_rev, v.published.omega) == (0.0, 0.0, 0.0)
    assert "keep-out zones cannot be placed: no localization heard" in v.published.reason
    assert v.degraded and v.detail.startswith("stop: keep-out")
    localized(m, now, "lost")
    assert "not tracking" in m.on_scan(open_scan(), now).published.reason
    localized(m, now)
    assert m.on_scan(open_scan(), now).published.v_fwd > 0.0  # placed: not a stop
    assert "silent" in m.on_scan(open_scan(), now + 3.0).published.reason
    m.on_odom(0.0, 0.0, now + 3.0, (0.0, 0.0, 0.0))
    localized(m, now + 3.0)
    stale = m.on_scan(open_scan(), now + 3.5)  # odometry 0.5 s old
    assert "no fresh odometry pose" in stale.published.reason
    # Positive control: the same scans with no keep-out configured drive.
    plain = monitor(None)
    plain.on_odom(0.0, 0.0, now, None)
    assert plain.on_scan(open_scan(), now).published.v_fwd > 0.0


def test_a_chair_inside_a_zone_is_stopped() -> None:
    now = 100.0
    m = monitor(Keepout(mask([(0.0, -1.0, 3.0, 2.0)])))  # around map (1, 0.5)
    localized(m, now)
    m.on_odom(0.0, 0.0, now, (0.0, 0.0, 0.0))
    lim = m.on_scan(open_scan(), now).published
    assert lim.v_fwd == 0.0 and "inside a keep-out zone" in lim.reason
    m.on_odom(0.0, 0.0, now, (-4.0, 0.0, math.pi))  # map (-3, 0.5): outside, facing away
    assert m.on_scan(open_scan(), now).published.v_fwd > 0.0


def test_zones_are_painted_into_the_live_grid_in_odom_where_localization_puts_them() -> None:
    """The mapping service's side: the whole zone, every cell, at any correction."""
    grid = OccupancyGrid(stamp_ns=0, frame_id="odom", resolution_m=RES, width=200, height=200,
                         origin_x_m=-5.0, origin_y_m=-5.0, data=bytes(200 * 200))
    k = Keepout(mask([(2.5, -0.5, 3.0, 0.5)]))  # 10 × 20 cells in map
    assert k.in_odom(0.0)[0] is None  # positive control below: placed once localized
    for correction in (CORRECTION, (1.0, 0.5, math.radians(30))):
        k.frame.on_correction(correction)
        k.on_loc("tracking", "localization", 0.0)
        k.on_map(map_grid())
        pts, why = k.in_odom(0.0)
        assert pts is not None and not why
        cells = np.frombuffer(paint(grid, pts).data, np.uint8).reshape(200, 200) == 100
        assert cells.sum() >= 200  # no cell of the zone skipped at 30°
        # The zone's centre (2.75, 0) in map is here in odom:
        ox, oy, oth = correction
        c, s = math.cos(oth), math.sin(oth)
        x, y = c * (2.75 - ox) + s * (0.0 - oy), -s * (2.75 - ox) + c * (0.0 - oy)
        assert cells[math.floor((y + 5.0) / RES), math.floor((x + 5.0) / RES)]
        assert not cells[100, 100]  # odom's origin is outside the zone


@pytest.mark.parametrize("correction,pose", [
    (CORRECTION, (0.0, 0.0, math.nan)),  # every edge NaN: no zone at all, 1.2 m/s
    (CORRECTION, (math.nan, 0.0, 0.0)),
    ((1.0, 0.5, math.nan), (0.0, 0.0, 0.0)),
    ((math.inf, 0.5, 0.0), (0.0, 0.0, 0.0)),
])
def test_a_non_finite_correction_or_pose_is_a_stop_not_a_lost_zone(
        correction: tuple[float, float, float], pose: tuple[float, float, float]) -> None:
    """Unknown is unsafe: a NaN yaw dropped every zone (the band ahead read as clear); a NaN
    position or correction raised inside the scan callback (no limit for 0.5 s)."""
    now = 100.0
    k = Keepout(mask([(2.5, -2.0, 3.0, 3.0)]))
    m = monitor(k)
    localized(m, now)
    m.on_odom(0.0, 0.0, now, (0.0, 0.0, 0.0))
    fine = m.on_scan(open_scan(), now).published  # positive control: the band limits
    assert 0.0 < fine.v_fwd < 1.0
    m.on_correction(correction)
    m.on_odom(0.0, 0.0, now, pose)
    lim = m.on_scan(open_scan(), now).published
    assert (lim.v_fwd, lim.v_rev, lim.omega) == (0.0, 0.0, 0.0)
    assert "keep-out zones cannot be placed" in lim.reason
    if not all(math.isfinite(c) for c in correction):  # mapping: nothing "placed" as NaN
        assert k.in_odom(now)[0] is None


def test_zones_are_not_placed_on_a_map_of_slams_own() -> None:
    """A config with keepout_map but no map: localization runs SLAM, reports tracking, and its
    `map` begins where the chair started: the zones would land beside the real stairs."""
    now = 100.0
    k = Keepout(mask([(2.5, -2.0, 3.0, 3.0)]))
    m = monitor(k)
    m.on_correction(CORRECTION)
    m.on_loc_map(map_grid())
    m.on_loc_state("tracking", "mapping", now)
    m.on_odom(0.0, 0.0, now, (0.0, 0.0, 0.0))
    lim = m.on_scan(open_scan(), now).published
    assert lim.v_fwd == 0.0 and "'mapping'" in lim.reason
    assert k.in_odom(now)[0] is None
    m.on_loc_state("tracking", "localization", now)  # positive control: on the saved map
    assert m.on_scan(open_scan(), now).published.v_fwd > 0.0
    assert k.in_odom(now)[0] is not None


def test_a_mask_without_any_zone_is_refused_at_start(tmp_path: Path) -> None:
    """Zones painted grey (unknown, below occupied_thresh) or none at all: the person believes
    the stairs are marked while nothing is."""
    from autochair.runtime.config import ConfigError
    from autochair.safety.keepout import load_keepout

    with pytest.raises(ConfigError, match=r"\[safety\] keepout_map: .*no keep-out zone"):
        load_keepout("safety", str(save_map(mask([], walls=False), tmp_path / "empty.yaml")))
    k = load_keepout("safety", str(save_map(mask([(2.5, -1.0, 3.0, 1.0)]), tmp_path / "k.yaml")))
    assert k is not None and len(k.edges) > 0  # positive control


def test_a_chair_whose_footprint_is_over_a_zone_is_stopped() -> None:
    """Only the zones' edge cells are added to the scan, and a point already under the
    footprint is no hit for the sweep: with the front 0.35–0.9 m past a deep zone's edge (a
    stairwell; the axle still outside) forward read as open up to 1.17 m/s, free to the zone's
    far edge. A localization correction that jumps by a few decimetres puts a parked chair
    there. Over a zone is inside one: a stop."""
    now = 100.0
    deep = mask([(2.5, -2.0, 4.9, 3.0)])  # from map x 2.5 on; the axle at map x 1 + odom x
    for front in (2.85, 3.0, 3.3):  # map x of the front (0.95 m ahead of the axle)
        m = monitor(Keepout(deep))
        localized(m, now)
        m.on_odom(0.0, 0.0, now, (front - 0.95 - CORRECTION[0], 0.0, 0.0))
        lim = m.on_scan(open_scan(), now).published
        assert (lim.v_fwd, lim.v_rev, lim.omega) == (0.0, 0.0, 0.0), (front, lim.reason)
        assert "over a keep-out zone" in lim.reason
    # Positive controls: 0.5 m before the edge the zone limits like a wall, and facing away
    # with the rear 0.1 m clear of it the chair drives off.
    m = monitor(Keepout(deep))
    localized(m, now)
    m.on_odom(0.0, 0.0, now, (2.0 - 0.95 - CORRECTION[0], 0.0, 0.0))
    before = m.on_scan(open_scan(), now).published
    assert 0.0 < before.v_fwd < 1.0 and "free fwd" in before.reason
    m.on_odom(0.0, 0.0, now, (2.4 - 0.25 - CORRECTION[0], 0.0, math.pi))
    assert m.on_scan(open_scan(), now).published.v_fwd > 1.0


def test_a_mask_not_drawn_over_localizations_map_is_a_stop() -> None:
    """A mask drawn over another map (another floor, an older map of this one), moved, zones
    alone on a blank canvas, or a copy with no zone painted black: tracking on the saved map
    would place its zones beside the real stairs, or none, and read them as open."""
    now = 100.0
    band = (2.5, -2.0, 3.0, 3.0)
    other = mask([band, WALLS[0], (-1.0, -3.0, 0.0, -2.5)], walls=False)  # the pillar only
    moved = mask([band])
    cases = {
        "drawn over another map": (other, "it has 64 of the map's 1600 wall cells"),
        "zones alone": (mask([band], walls=False), "it has 0 of the map's 1600 wall cells"),
        "moved 10 cm": (MapFile(moved.occupied, moved.free, RES, -4.9, -5.0),
                        "its grid is not the map's: 200×200 cells of 0.05 m from (-4.9"),
        "no zone painted": (mask([]), "it has no zone beyond the map's walls"),
    }
    for name, (m_, why) in cases.items():
        k = Keepout(m_)
        m = monitor(k)
        localized(m, now)
        m.on_odom(0.0, 0.0, now, (0.0, 0.0, 0.0))
        lim = m.on_scan(open_scan(), now).published
        assert (lim.v_fwd, lim.v_rev, lim.omega) == (0.0, 0.0, 0.0), name
        assert f"the mask does not fit localization's map: {why}" in lim.reason, name
        assert k.in_odom(now)[0] is None, name  # nor painted for navigation
    # Until localization's map is heard the mask cannot be checked: a stop too.
    m = monitor(Keepout(mask([band])))
    m.on_correction(CORRECTION)
    m.on_loc_state("tracking", "localization", now)
    m.on_odom(0.0, 0.0, now, (0.0, 0.0, 0.0))
    assert "map not heard yet" in m.on_scan(open_scan(), now).published.reason
    # Positive control: the same band drawn over the map's copy limits like a wall.
    m.on_loc_map(map_grid())
    lim = m.on_scan(open_scan(), now).published
    assert 0.0 < lim.v_fwd < 1.0 and "free fwd" in lim.reason


def test_a_mask_fits_the_map_as_localization_publishes_it(tmp_path: Path) -> None:
    """The check against the grid localization really sends (its saved map through
    `grid_msg`), from files as `autochair up --map --keepout` gives them."""
    k = Keepout(load_map(save_map(mask([(2.5, -2.0, 3.0, 3.0)]), tmp_path / "stairs.yaml")))
    k.on_map(map_grid(load_map(save_map(mask([]), tmp_path / "hall.yaml"))))
    assert k.mismatch == ""
    k.on_map(map_grid(load_map(save_map(mask([], 12.0), tmp_path / "big.yaml"))))
    assert k.mismatch and "grid is not the map's" in k.mismatch  # positive control
