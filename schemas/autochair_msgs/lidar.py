"""Laser scans and the map built from them."""

from __future__ import annotations

import msgspec


class LaserScan(msgspec.Struct, kw_only=True):
    """One planar scan in the `laser` frame. Invalid beams (device error codes) are NaN."""

    stamp_ns: int  # host time of the first beam in ranges_m, from the device clock
    frame_id: str
    angle_min_rad: float
    angle_increment_rad: float
    range_min_m: float
    range_max_m: float
    ranges_m: list[float]
    scan_seq: int = 0
    device_time_ms: int = 0  # device clock, unwrapped
    # Beam i was taken at stamp + i·time_increment_s (the laser turns while it scans: on a
    # moving chair, place each beam with the pose at its own time). 0: all at the stamp.
    time_increment_s: float = 0.0


class OccupancyGrid(msgspec.Struct, kw_only=True):
    """Row-major occupancy, 0..100 (255 unknown); cell (0, 0) is at the origin, rows grow in +y."""

    stamp_ns: int
    frame_id: str
    resolution_m: float
    width: int
    height: int
    origin_x_m: float
    origin_y_m: float
    data: bytes


class PointCloud(msgspec.Struct, kw_only=True):
    """Points as little-endian float32 x, y, z triples (metres) in `frame_id`."""

    stamp_ns: int
    frame_id: str
    count: int
    points_xyz_f32: bytes
