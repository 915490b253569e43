"""nav_eval's scan-made map (bench/scan_map.py, `--map scans`): the mapping service's grid grown
from the simulated laser's scans lands on the world's walls, so what the chair plans on in the
bench differs from the exact map only where mapping itself makes it differ."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from bench.nav_eval import laser_mount
from bench.scan_map import ScanMap

from autochair.geometry import Pose
from autochair.nav.field import GridMap
from autochair.sim.lidar.node import LidarSimConfig
from autochair.sim.world import DEFAULT_WORLD, load_world

Bool = npt.NDArray[np.bool_]


def drive(noise_m: float, v: float = 0.3, omega: float = 0.9, t_end: float = 3.0) -> GridMap:
    """The hallway's map from the start, parked 1 s, then a chair on an arc (v, ω): its
    sweeps skewed by the turn, as the live laser's are."""
    world = load_world(DEFAULT_WORLD)
    sm = ScanMap(world, laser_mount(), seed=3,
                 lidar=LidarSimConfig(tcp_port=0, noise_std_m=noise_m))
    gm = sm.parked(0.0, (0.0, 0.0, 0.0))
    r = v / omega
    for k in range(1, round(t_end / 0.01) + 1):
        t = k * 0.01
        a = omega * t
        pose: Pose = (r * math.sin(a), r * (1.0 - math.cos(a)), math.atan2(math.sin(a),
                                                                           math.cos(a)))
        gm = sm.step(t, pose, pose, (v, omega)) or gm
    assert t_end == 0.0 or sm.mapper.scans >= 10  # (the gate took scans while turning)
    return gm


def centres(gm: GridMap, mask: Bool) -> npt.NDArray[np.float64]:
    iy, ix = np.nonzero(mask)
    return np.stack([gm.origin_x_m + (ix + 0.5) * gm.resolution_m,
                     gm.origin_y_m + (iy + 0.5) * gm.resolution_m], axis=1)


def dilated(m: Bool) -> Bool:
    """Cells within one cell (8-neighbourhood) of `m`'s."""
    p = np.pad(m, 1)
    out = np.zeros_like(m)
    for dy in (0, 1, 2):
        for dx in (0, 1, 2):
            out |= p[dy:dy + m.shape[0], dx:dx + m.shape[1]]
    return out


def test_scan_walls_within_a_cell_of_the_world() -> None:
    world = load_world(DEFAULT_WORLD)
    noisy = drive(0.01)
    res = noisy.resolution_m
    # The cells lie as the exact map's (GridMap.from_shapes): walls on 5 cm lines lie on cell
    # boundaries in both, where the wall's cell depends on which side the beams end.
    assert np.allclose(np.array([noisy.origin_x_m, noisy.origin_y_m]) / res % 1.0, 0.0)
    # No ghost: every cell the scans made an obstacle is one a wall crosses or touches, or the
    # next one (a wrong laser mount, beam angle, stamp or sweep correction puts walls
    # 0.1-0.9 m off).
    far = world.distance_to(centres(noisy, noisy.occupied)) > 1.5 * res + 1e-9
    assert not far.any(), f"{far.sum()} obstacle cells off the world's walls"
    # Every wall the laser truly saw (the same drive, no noise) is in the map, within a cell.
    seen = drive(0.0)
    assert seen.occupied.sum() > 200
    assert (world.distance_to(centres(seen, seen.occupied)) <= 1.5 * res + 1e-9).all()
    missed = seen.occupied & ~dilated(noisy.occupied)
    assert not missed.any(), f"{missed.sum()} seen wall cells missing from the map"


def test_unseen_is_unknown_and_free() -> None:
    """From the start the hallway's offices are not seen: their cells are unknown in the
    message the control service reads, and free to plan through (GridMap.from_msg)."""
    gm = drive(0.01, t_end=0.0)
    assert gm.unknown is not None
    i = np.floor((np.array([12.5, 3.0]) - (gm.origin_x_m, gm.origin_y_m))
                 / gm.resolution_m).astype(int)  # office B, 12 m down the hallway
    assert gm.unknown[i[1], i[0]] and not gm.occupied[i[1], i[0]]
    j = np.floor((np.array([1.0, 0.0]) - (gm.origin_x_m, gm.origin_y_m))
                 / gm.resolution_m).astype(int)  # in front of the chair: seen, free
    assert not gm.unknown[j[1], j[0]] and not gm.occupied[j[1], j[0]]
