"""Foxglove well-known channels derived from autochair messages, so the 3D panel, the Log panel
and the map work without any user scripts.

| derived topic    | schema                     | from                               |
|------------------|----------------------------|------------------------------------|
| /tf              | foxglove.FrameTransforms   | keys.TF, keys.TF_STATIC            |
| /pose            | foxglove.PoseInFrame       | keys.ODOM                          |
| /scan            | foxglove.LaserScan         | keys.SCAN                          |
| /map             | foxglove.Grid              | keys.MAP_GRID                      |
| /log             | foxglove.Log               | keys.LOG, new faults in keys.HEALTH |

/tf (from keys.TF), /pose and /scan are duplicates of channels recorded at the full rate
(keys.TF, keys.ODOM, keys.SCAN): they are decimated by message stamp to at most `max_hz` (the
logger's `derived_max_hz`, default 20 Hz) and `scan_max_hz` (`derived_scan_hz`, default 5 Hz),
enough for the 3D panel. Static transforms, maps and logs are derived from every message.

Times are {sec, nsec}; bytes are base64. The schemas are Foxglove's own (copied from npm
`@foxglove/schemas` into foxglove_schemas.json). foxglove.LaserScan has no range limits and
JSON no NaN, so an invalid beam (NaN or out of [range_min, range_max]) is written as 0.0 m,
which draws at the sensor; the raw channel keeps the exact values.
"""

from __future__ import annotations

import base64
import json
import math
from collections.abc import Callable
from importlib import resources
from typing import Any

import msgspec

from autochair import geometry
from autochair.timing import Decimator
from autochair_msgs import (
    FrameTransform,
    Health,
    LaserScan,
    LogEvent,
    OccupancyGrid,
    Odometry,
    keys,
)

SCHEMAS: dict[str, dict[str, Any]] = json.loads(
    resources.files(__package__).joinpath("foxglove_schemas.json").read_text()
)
LEVELS = {"debug": 1, "info": 2, "warning": 3, "warn": 3, "error": 4, "fatal": 5}

TOPIC_TF, TOPIC_POSE, TOPIC_SCAN, TOPIC_MAP, TOPIC_LOG = "/tf", "/pose", "/scan", "/map", "/log"
DERIVED = {TOPIC_TF: "foxglove.FrameTransforms", TOPIC_POSE: "foxglove.PoseInFrame",
           TOPIC_SCAN: "foxglove.LaserScan", TOPIC_MAP: "foxglove.Grid",
           TOPIC_LOG: "foxglove.Log"}

Derived = tuple[str, int, dict[str, Any]]  # (derived topic, stamp ns, message)


def time_of(ns: int) -> dict[str, int]:
    sec, nsec = divmod(max(ns, 0), 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def yaw_quaternion(yaw: float) -> dict[str, float]:
    return dict(zip("xyzw", geometry.yaw_quaternion(yaw), strict=True))


def _finite(v: float) -> float:
    return v if math.isfinite(v) else 0.0


def _tf(m: FrameTransform) -> dict[str, Any]:
    t, r = m.translation, m.rotation
    return {"transforms": [{
        "timestamp": time_of(m.stamp_ns), "parent_frame_id": m.parent_frame_id,
        "child_frame_id": m.child_frame_id,
        "translation": {"x": _finite(t.x), "y": _finite(t.y), "z": _finite(t.z)},
        "rotation": {"x": _finite(r.x), "y": _finite(r.y), "z": _finite(r.z),
                     "w": _finite(r.w)},
    }]}


def _pose(m: Odometry) -> dict[str, Any]:
    return {"timestamp": time_of(m.stamp_ns), "frame_id": m.frame_id, "pose": {
        "position": {"x": _finite(m.x_m), "y": _finite(m.y_m), "z": 0.0},
        "orientation": yaw_quaternion(_finite(m.yaw_rad))}}


_ORIGIN = {"position": {"x": 0.0, "y": 0.0, "z": 0.0},
           "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}


def _scan(m: LaserScan) -> dict[str, Any]:
    lo, hi = m.range_min_m, m.range_max_m
    ranges = [r if lo <= r <= hi else 0.0 for r in m.ranges_m]  # NaN fails both compares
    n = max(len(ranges) - 1, 0)
    return {"timestamp": time_of(m.stamp_ns), "frame_id": m.frame_id, "pose": _ORIGIN,
            "start_angle": _finite(m.angle_min_rad),
            "end_angle": _finite(m.angle_min_rad + n * m.angle_increment_rad),
            "ranges": ranges, "intensities": []}


def _grid(m: OccupancyGrid) -> dict[str, Any]:
    return {"timestamp": time_of(m.stamp_ns), "frame_id": m.frame_id,
            "pose": {"position": {"x": _finite(m.origin_x_m), "y": _finite(m.origin_y_m),
                                  "z": 0.0},
                     "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
            "column_count": m.width,
            "cell_size": {"x": _finite(m.resolution_m), "y": _finite(m.resolution_m)},
            "row_stride": m.width, "cell_stride": 1,
            "fields": [{"name": "occupancy", "offset": 0, "type": 1}],  # 1 = UINT8
            "data": base64.b64encode(m.data).decode("ascii")}


def log_message(stamp_ns: int, level: str, name: str, message: str) -> dict[str, Any]:
    return {"timestamp": time_of(stamp_ns), "level": LEVELS.get(level, 0), "message": message,
            "name": name, "file": "", "line": 0}


class Deriver:
    """Maps one decoded message to its foxglove.* messages. Keeps the last fault seen per
    service so a Health fault becomes one Log entry, not one per second."""

    def __init__(self, max_hz: float = 0.0, scan_max_hz: float = 0.0) -> None:
        self._faults: dict[str, int] = {}
        # Decimation of the duplicates of full-rate raw channels (0 = every message).
        tf, pose, scan = Decimator.at(max_hz), Decimator.at(max_hz), Decimator.at(scan_max_hz)
        self._by_key: dict[str, Callable[[Any], list[Derived]]] = {
            keys.TF.key: lambda m: [(TOPIC_TF, m.stamp_ns, _tf(m))] if tf(m.stamp_ns) else [],
            keys.TF_STATIC.key: lambda m: [(TOPIC_TF, m.stamp_ns, _tf(m))],
            keys.ODOM.key: lambda m: [(TOPIC_POSE, m.stamp_ns, _pose(m))]
            if pose(m.stamp_ns) else [],
            keys.SCAN.key: lambda m: [(TOPIC_SCAN, m.stamp_ns, _scan(m))]
            if scan(m.stamp_ns) else [],
            keys.MAP_GRID.key: lambda m: [(TOPIC_MAP, m.stamp_ns, _grid(m))],
            keys.LOG.key: self._log,
        }

    def derive(self, key: str, msg: msgspec.Struct) -> list[Derived]:
        fn = self._by_key.get(key)
        if fn is not None:
            return fn(msg)
        if isinstance(msg, Health):
            return self._health(msg)
        return []

    def _log(self, m: LogEvent) -> list[Derived]:
        return [(TOPIC_LOG, m.stamp_ns, log_message(m.stamp_ns, m.level, m.service, m.message))]

    def _health(self, m: Health) -> list[Derived]:
        if not m.last_fault_stamp_ns or self._faults.get(m.service) == m.last_fault_stamp_ns:
            return []
        self._faults[m.service] = m.last_fault_stamp_ns
        return [(TOPIC_LOG, m.last_fault_stamp_ns, log_message(
            m.last_fault_stamp_ns, "error" if m.state == "fault" else "warning", m.service,
            f"fault ({m.state}): {m.last_fault}"))]
