"""Keep-out zones for the safety monitor (hazard H42), pure: what the laser cannot see.

A 2D laser sees one plane: stairs down, a kerb, a platform edge or glass is no obstacle to it.
A person marks such places on a mask map in `map` (the Nav2 keepout-filter convention: a
map_server PGM + YAML whose occupied cells are the zones; draw them over a saved map). The
monitor adds the zones' edge cells to every scan's points, as if the laser saw a wall there,
placed with localization's `map` → `odom` correction and the odometry pose; the sweep, the
stop distance and the imminent-collision e-stop then treat them like any obstacle.

Unknown is unsafe: while the zones cannot be placed (no localization heard, silent, not
tracking, localizing on a map of its own (SLAM), a mask not drawn over localization's map, a
non-finite correction or pose, or no fresh odometry pose) or the chair stands inside one, every
limit is a stop.
"""

from __future__ import annotations

import math
from typing import Any

import msgspec
import numpy as np
import numpy.typing as npt

from autochair.geometry import Pose, compose
from autochair.mapping.mapfile import MapFile, MapFileError, load_map
from autochair.nav.frames import MapFrame
from autochair_msgs import OccupancyGrid

F64 = npt.NDArray[np.float64]


def cells_to_map(m: MapFile, cx: npt.NDArray[np.floating[Any]],
                 cy: npt.NDArray[np.floating[Any]]) -> F64:
    """Map-frame points (N, 2) at grid coordinates (cx, cy) in cells (cell (r, c)'s centre is
    (c + 0.5, r + 0.5))."""
    return np.column_stack((m.origin_x_m + cx * m.resolution_m,
                            m.origin_y_m + cy * m.resolution_m))


def zone_edges(mask: MapFile) -> F64:
    """Map-frame centres (N, 2) of the zone cells that touch a cell outside every zone (or the
    mask's border): the only ones a chair outside can reach first."""
    zone = mask.occupied
    padded = np.pad(zone, 1, constant_values=False)
    inner = (padded[:-2, 1:-1] & padded[2:, 1:-1] & padded[1:-1, :-2] & padded[1:-1, 2:])
    rows, cols = np.nonzero(zone & ~inner)
    return cells_to_map(mask, cols + 0.5, rows + 0.5)


def zone_samples(mask: MapFile) -> F64:
    """Map-frame points (N, 2) covering every zone cell, 2 × 2 a cell, so that painted into a
    grid of the same resolution at any rotation no cell of a zone is skipped."""
    rows, cols = np.nonzero(mask.occupied)
    qx, qy = np.array([0.25, 0.25, 0.75, 0.75]), np.array([0.25, 0.75, 0.25, 0.75])
    return cells_to_map(mask, (cols[:, None] + qx[None, :]).ravel(),
                        (rows[:, None] + qy[None, :]).ravel())


MIN_WALLS = 0.9  # of the map's walls a mask drawn over it must have


def mask_mismatch(mask: MapFile, m: MapFile) -> str:
    """"" if `mask` was drawn over the map `m`, else why not (one line). The convention is a
    copy of the map with the zones painted black: the same grid, the map's walls, and more.
    A mask drawn over another map (another floor, an older map of this one), moved, or zones
    alone on a blank canvas would put its zones beside the real stairs."""
    def grid(g: MapFile) -> str:
        return (f"{g.occupied.shape[1]}×{g.occupied.shape[0]} cells of {g.resolution_m:g} m from "
                f"({g.origin_x_m:g}, {g.origin_y_m:g})")

    if mask.occupied.shape != m.occupied.shape or not np.allclose(
            (mask.resolution_m, mask.origin_x_m, mask.origin_y_m),
            (m.resolution_m, m.origin_x_m, m.origin_y_m), rtol=0, atol=1e-6):
        return f"its grid is not the map's: {grid(mask)} against {grid(m)}"
    walls = int(m.occupied.sum())
    kept = int((mask.occupied & m.occupied).sum())
    if walls == 0 or kept < MIN_WALLS * walls:
        return (f"it has {kept} of the map's {walls} wall cells, want ≥ {MIN_WALLS:.0%} (drawn "
                "over another map?)")
    if not (mask.occupied & ~m.occupied).any():
        return "it has no zone beyond the map's walls (zones are black cells)"
    return ""


class Keepout:
    """The zones of one mask, placed in the chair frame for each scan (the safety monitor) or in
    `odom` (the mapping service paints them into the live grid, so navigation plans round them
    and refuses goals in them)."""

    def __init__(self, mask: MapFile, stale_s: float = 2.5) -> None:
        self.mask = mask
        self.edges = zone_edges(mask)
        self.frame = MapFrame(stale_s)  # localization's correction and state (H33's rule)
        self.mode = ""  # localization's; only "localization" is on a fixed map, the mask's
        # Why the mask does not fit localization's map ("" if it does; None: no map heard yet).
        self.mismatch: str | None = None
        self._samples: F64 | None = None

    def on_map(self, grid: OccupancyGrid) -> None:
        """Localization's map (keys.LOC_MAP), against which the mask is checked."""
        cells = np.frombuffer(grid.data, np.uint8)
        if cells.size != grid.width * grid.height:
            self.mismatch = f"localization's map is malformed ({cells.size} cells)"
            return
        occ = cells.reshape(grid.height, grid.width) == 100
        self.mismatch = mask_mismatch(self.mask, MapFile(occ, ~occ, grid.resolution_m,
                                                         grid.origin_x_m, grid.origin_y_m))

    def on_loc(self, state: str, mode: str, now: float) -> None:
        """Localization's state and mode (keys.LOC_POSE)."""
        self.frame.on_state(state, now)
        self.mode = mode

    def why_not(self, now: float) -> str:
        """"" if the zones can be placed now, else why not (one line)."""
        why = self.frame.why_not(now)
        if why:
            return why
        # SLAM tracks too, but in a map of its own whose origin is where it started: the
        # mask's zones would land at the wrong places (a config with keepout_map and no map).
        if self.mode != "localization":
            return (f"localization mode is {self.mode!r}, not 'localization' on the saved map "
                    "the zones are drawn on")
        if self.mismatch is None:
            return "localization's map not heard yet (the mask is checked against it)"
        return (f"the mask does not fit localization's map: {self.mismatch}" if self.mismatch
                else "")

    def in_odom(self, now: float) -> tuple[F64 | None, str]:
        """Every zone's sample points in `odom`, or (None, why they cannot be placed)."""
        why = self.why_not(now)
        if why:
            return None, f"keep-out zones cannot be placed: {why}"
        if self._samples is None:
            self._samples = zone_samples(self.mask)
        assert self.frame.correction is not None
        ox, oy, oth = self.frame.correction  # the pose of odom in map
        c, s = math.cos(oth), math.sin(oth)
        dx, dy = self._samples[:, 0] - ox, self._samples[:, 1] - oy
        return np.column_stack((c * dx + s * dy, -s * dx + c * dy)), ""

    def inside(self, x: float, y: float) -> bool:
        """Whether the map point (x, y) lies in a zone cell."""
        m = self.mask
        col = math.floor((x - m.origin_x_m) / m.resolution_m)
        row = math.floor((y - m.origin_y_m) / m.resolution_m)
        h, w = m.occupied.shape
        return 0 <= row < h and 0 <= col < w and bool(m.occupied[row, col])

    def points(self, odom_pose: Pose | None, now: float,
               footprint: tuple[float, float, float] | None = None) -> tuple[F64 | None, str]:
        """The edges in the chair frame, or (None, why: a stop). `footprint` (front, rear,
        half width from the axle): an edge under it is a stop too, as the axle in a zone."""
        why = self.why_not(now)
        if not why and (odom_pose is None or not all(math.isfinite(v) for v in odom_pose)):
            why = "no fresh odometry pose"  # (a NaN yaw would turn every edge into NaN: none)
        if why:
            return None, f"keep-out zones cannot be placed: {why}"
        assert self.frame.correction is not None and odom_pose is not None
        x, y, th = compose(self.frame.correction, odom_pose)
        if self.inside(x, y):
            return None, f"inside a keep-out zone at ({x:.2f}, {y:.2f}) in map"
        c, s = math.cos(th), math.sin(th)
        dx, dy = self.edges[:, 0] - x, self.edges[:, 1] - y
        pts = np.column_stack((c * dx + s * dy, -s * dx + c * dy))
        # The sweep counts no point already under the footprint as a hit, and only edges are
        # added: with the front past a deep zone's edge, forward read as open to its far edge.
        if footprint is not None:
            front, rear, half = footprint
            under = (pts[:, 0] <= front) & (pts[:, 0] >= -rear) & (np.abs(pts[:, 1]) <= half)
            if under.any():
                return None, f"the chair stands over a keep-out zone at ({x:.2f}, {y:.2f}) in map"
        return pts, ""


def paint(grid: OccupancyGrid, odom_pts: F64) -> OccupancyGrid:
    """`grid` (in `odom`) with the cells under `odom_pts` occupied (100): a copy."""
    data = np.frombuffer(grid.data, np.uint8).copy()
    ix = np.floor((odom_pts[:, 0] - grid.origin_x_m) / grid.resolution_m).astype(np.int64)
    iy = np.floor((odom_pts[:, 1] - grid.origin_y_m) / grid.resolution_m).astype(np.int64)
    ok = (ix >= 0) & (ix < grid.width) & (iy >= 0) & (iy < grid.height)
    data[iy[ok] * grid.width + ix[ok]] = 100
    return msgspec.structs.replace(grid, data=data.tobytes())


def load_keepout(section: str, path: str) -> Keepout | None:
    """The zones of the mask at `path` ("" = none); ConfigError naming `[section]` if bad.
    (The nodes' file edge: the runtime's error type is imported here only, keeping the module
    free of Zenoh for the pure users above.)"""
    from autochair.runtime.config import ConfigError

    if not path:
        return None
    try:
        mask = load_map(path)
    except MapFileError as e:
        raise ConfigError(f"[{section}] keepout_map: {e}") from None
    # A mask with no zone (drawn in grey, below occupied_thresh, or not drawn at all) would
    # protect nothing while the person believes the stairs are marked.
    if not mask.occupied.any():
        raise ConfigError(f"[{section}] keepout_map: {path}: no keep-out zone in the mask "
                          "(zones are black: occupied cells)")
    return Keepout(mask)
