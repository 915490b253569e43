"""Localization and map files: the chair's pose in `map`, how sure it is, and requests."""

from __future__ import annotations

import msgspec

from .nav import Pose2D


class LocalizedPose(msgspec.Struct, kw_only=True, frozen=True):
    """The chair (drive-axle centre) in `map`, scan-matched and fused with odometry."""

    stamp_ns: int
    frame_id: str = "map"
    x_m: float
    y_m: float
    yaw_rad: float
    covariance: list[float]  # 3×3 row-major over (x m, y m, yaw rad)
    quality: float  # fraction of scan points that lie on the map, 0..1
    state: str  # "initializing" | "tracking" | "lost"
    mode: str  # "mapping" | "localization"


class LocalizeRequest(msgspec.Struct, kw_only=True):
    """Set the chair's pose on the map (`autochair localize X Y YAW`); pose None = search the
    whole map (global localization)."""

    pose: Pose2D | None = None
    sigma_xy_m: float = 0.3
    sigma_yaw_rad: float = 0.2


class LocalizeReply(msgspec.Struct, kw_only=True):
    ok: bool
    state: str = ""
    error: str = ""


class MapSaveRequest(msgspec.Struct, kw_only=True):
    """Save the current map as NAME.pgm + NAME.yaml (ROS map_server format) in the maps
    directory of the localization service."""

    name: str


class MapSaveReply(msgspec.Struct, kw_only=True):
    ok: bool
    path: str = ""  # the YAML file written
    error: str = ""
