"""Foxglove well-known channels derived from autochair messages, so the 3D panel, the Log panel
and the map work without any user scripts.

| derived topic    | schema                     | from                               |
|------------------|----------------------------|------------------------------------|
| /map             | foxglove.Grid              | keys.MAP_GRID                      |
| /log             | foxglove.Log               | keys.LOG, new faults in keys.HEALTH |
| /nav/plan        | foxglove.PosesInFrame      | keys.NAV_PLAN (predicted path, then the target) |
| /nav/scene       | foxglove.SceneUpdate       | keys.NAV_PLAN (footprint, target arrow, people) |
| /loc/map         | foxglove.Grid              | keys.LOC_MAP (frame `map`)         |

Scans and transforms need no derived channel: keys.SCAN, keys.TF and keys.TF_STATIC are
recorded as foxglove.LaserScan and foxglove.FrameTransform themselves (`schema.codec_for`); the
chair's pose is shown by the transforms (`odom` → `chair` from odometry, `map` → `odom` from
localization), so no pose is derived either. Maps, plans and logs are derived from every
message. Frames follow REP-105 (`map` → `odom` → `chair` → `laser`): set the 3D panel's
display frame to `map`.

Times are {sec, nsec}; bytes are base64. The schemas are Foxglove's own (copied from npm
`@foxglove/schemas` into foxglove_schemas.json).
"""

from __future__ import annotations

import base64
import math
from collections.abc import Callable
from typing import Any

import msgspec

from autochair import geometry
from autochair_msgs import Health, LogEvent, NavPlan, OccupancyGrid, keys

from .schema import FOXGLOVE_SCHEMAS, ORIGIN

SCHEMAS = FOXGLOVE_SCHEMAS
LEVELS = {"debug": 1, "info": 2, "warning": 3, "warn": 3, "error": 4, "fatal": 5}

TOPIC_MAP, TOPIC_LOG = "/map", "/log"
TOPIC_PLAN, TOPIC_SCENE = "/nav/plan", "/nav/scene"
TOPIC_LOC_MAP = "/loc/map"
DERIVED = {TOPIC_MAP: "foxglove.Grid", TOPIC_LOG: "foxglove.Log",
           TOPIC_PLAN: "foxglove.PosesInFrame", TOPIC_SCENE: "foxglove.SceneUpdate",
           TOPIC_LOC_MAP: "foxglove.Grid"}

Derived = tuple[str, int, dict[str, Any]]  # (derived topic, stamp ns, message)


def time_of(ns: int) -> dict[str, int]:
    sec, nsec = divmod(max(ns, 0), 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def yaw_quaternion(yaw: float) -> dict[str, float]:
    return dict(zip("xyzw", geometry.yaw_quaternion(yaw), strict=True))


def _finite(v: float) -> float:
    return v if math.isfinite(v) else 0.0


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


def _pose3(x: float, y: float, yaw: float) -> dict[str, Any]:
    return {"position": {"x": _finite(x), "y": _finite(y), "z": 0.0},
            "orientation": yaw_quaternion(_finite(yaw))}


def _plan(m: NavPlan) -> dict[str, Any]:
    poses = [_pose3(x, y, a) for x, y, a in zip(m.path_x_m, m.path_y_m, m.path_yaw_rad,
                                                strict=False)]
    poses.append(_pose3(m.target_x_m, m.target_y_m, m.target_yaw_rad))
    return {"timestamp": time_of(m.stamp_ns), "frame_id": m.frame_id, "poses": poses}


def _rgba(r: float, g: float, b: float, a: float = 1.0) -> dict[str, float]:
    return {"r": r, "g": g, "b": b, "a": a}


def _scene(m: NavPlan) -> dict[str, Any]:
    """The chair's footprint (a loop), MPEPC's target (an arrow) and the people (cylinders)."""
    xy = m.footprint_xy_m
    loop = {"type": 1, "pose": ORIGIN, "thickness": 0.03, "scale_invariant": False,
            "points": [{"x": _finite(xy[i]), "y": _finite(xy[i + 1]), "z": 0.05}
                       for i in range(0, len(xy) - 1, 2)],
            "color": _rgba(0.1, 0.6, 1.0), "colors": [], "indices": []}
    arrow = {"pose": _pose3(m.target_x_m, m.target_y_m, m.target_yaw_rad),
             "shaft_length": 0.4, "shaft_diameter": 0.05, "head_length": 0.15,
             "head_diameter": 0.12, "color": _rgba(1.0, 0.5, 0.0)}
    p = m.people_xyr_m
    people = [{"pose": _pose3(p[i], p[i + 1], 0.0),
               "size": {"x": _finite(2 * p[i + 2]), "y": _finite(2 * p[i + 2]), "z": 1.7},
               "bottom_scale": 1.0, "top_scale": 1.0, "color": _rgba(1.0, 0.2, 0.2, 0.6)}
              for i in range(0, len(p) - 2, 3)]
    entity = {"timestamp": time_of(m.stamp_ns), "frame_id": m.frame_id, "id": "nav",
              "lifetime": {"sec": 0, "nsec": 0}, "frame_locked": False,
              "metadata": [{"key": "state", "value": m.state}],
              "arrows": [arrow], "cubes": [], "spheres": [], "cylinders": people,
              "lines": [loop], "triangles": [], "texts": [], "models": []}
    return {"deletions": [], "entities": [entity]}


def log_message(stamp_ns: int, level: str, name: str, message: str) -> dict[str, Any]:
    return {"timestamp": time_of(stamp_ns), "level": LEVELS.get(level, 0), "message": message,
            "name": name, "file": "", "line": 0}


class Deriver:
    """Maps one decoded message to its foxglove.* messages. Keeps the last fault seen per
    service so a Health fault becomes one Log entry, not one per second."""

    def __init__(self) -> None:
        self._faults: dict[str, int] = {}
        self._by_key: dict[str, Callable[[Any], list[Derived]]] = {
            keys.MAP_GRID.key: lambda m: [(TOPIC_MAP, m.stamp_ns, _grid(m))],
            keys.LOC_MAP.key: lambda m: [(TOPIC_LOC_MAP, m.stamp_ns, _grid(m))],
            keys.NAV_PLAN.key: lambda m: [(TOPIC_PLAN, m.stamp_ns, _plan(m)),
                                          (TOPIC_SCENE, m.stamp_ns, _scene(m))],
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
