"""Keep-out zones for the safety monitor (hazard H42), pure: what the laser cannot see.

A 2D laser sees one plane: stairs down, a kerb, a platform edge or glass is no obstacle to it.
A person marks such places on a mask map in `map` (the Nav2 keepout-filter convention: a
map_server PGM + YAML whose occupied cells are the zones; draw them over a saved map). The
monitor adds the zones' edge cells to every scan's points, as if the laser saw a wall there,
placed with localization's `map` → `odom` correction and the odometry pose; the sweep, the
stop distance and the imminent-collision e-stop then treat them like any obstacle.

Unknown is unsafe: while the zones cannot be placed (no localization heard, silent, not
tracking, or no fresh odometry pose) or the chair stands inside one, every limit is a stop.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from autochair.geometry import Pose, compose
from autochair.mapping.mapfile import MapFile
from autochair.nav.frames import MapFrame

F64 = npt.NDArray[np.float64]


def zone_edges(mask: MapFile) -> F64:
    """Map-frame centres (N, 2) of the zone cells that touch a cell outside every zone (or the
    mask's border): the only ones a chair outside can reach first."""
    zone = mask.occupied
    padded = np.pad(zone, 1, constant_values=False)
    inner = (padded[:-2, 1:-1] & padded[2:, 1:-1] & padded[1:-1, :-2] & padded[1:-1, 2:])
    rows, cols = np.nonzero(zone & ~inner)
    local = np.column_stack(((cols + 0.5) * mask.resolution_m, (rows + 0.5) * mask.resolution_m))
    c, s = math.cos(mask.origin_yaw), math.sin(mask.origin_yaw)
    return np.column_stack((mask.origin_x_m + c * local[:, 0] - s * local[:, 1],
                            mask.origin_y_m + s * local[:, 0] + c * local[:, 1]))


class Keepout:
    """The zones of one mask, placed in the chair frame for each scan."""

    def __init__(self, mask: MapFile, stale_s: float = 2.5) -> None:
        self.mask = mask
        self.edges = zone_edges(mask)
        self.frame = MapFrame(stale_s)  # localization's correction and state (H33's rule)

    def inside(self, x: float, y: float) -> bool:
        """Whether the map point (x, y) lies in a zone cell."""
        m = self.mask
        c, s = math.cos(m.origin_yaw), math.sin(m.origin_yaw)
        dx, dy = x - m.origin_x_m, y - m.origin_y_m
        col = math.floor((c * dx + s * dy) / m.resolution_m)
        row = math.floor((-s * dx + c * dy) / m.resolution_m)
        h, w = m.occupied.shape
        return 0 <= row < h and 0 <= col < w and bool(m.occupied[row, col])

    def points(self, odom_pose: Pose | None, now: float) -> tuple[F64 | None, str]:
        """The edges in the chair frame, or (None, why they cannot be placed: a stop)."""
        why = self.frame.why_not(now)
        if not why and odom_pose is None:
            why = "no fresh odometry pose"
        if why:
            return None, f"keep-out zones cannot be placed: {why}"
        assert self.frame.correction is not None
        x, y, th = compose(self.frame.correction, odom_pose)  # type: ignore[arg-type]
        if self.inside(x, y):
            return None, f"inside a keep-out zone at ({x:.2f}, {y:.2f}) in map"
        c, s = math.cos(th), math.sin(th)
        dx, dy = self.edges[:, 0] - x, self.edges[:, 1] - y
        return np.column_stack((c * dx + s * dy, -s * dx + c * dy)), ""
