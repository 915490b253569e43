"""Shared building blocks. Stamps are Unix-epoch nanoseconds (what MCAP and Foxglove expect)."""

from __future__ import annotations

import msgspec


class Empty(msgspec.Struct, frozen=True):
    """A request that carries nothing (e.g. "what is the goal's status?")."""


class Vector3(msgspec.Struct, frozen=True):
    """A vector in metres."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0


class Quaternion(msgspec.Struct, frozen=True):
    """A unit quaternion (x, y, z, w)."""

    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    w: float = 1.0


class FrameTransform(msgspec.Struct, kw_only=True, frozen=True):
    """Pose of `child_frame_id` in `parent_frame_id` (REP-103: x forward, y left, z up)."""

    stamp_ns: int
    parent_frame_id: str
    child_frame_id: str
    translation: Vector3
    rotation: Quaternion


class Health(msgspec.Struct, kw_only=True):
    """What a service says of itself, about once a second."""

    stamp_ns: int
    service: str
    state: str  # "starting" | "ok" | "degraded" | "fault"
    uptime_s: float
    counters: dict[str, int] = {}
    rates_hz: dict[str, float] = {}
    # Configured thresholds (stale timeouts etc.) so an operator can see them in one place.
    thresholds: dict[str, float] = {}
    detail: str = ""
    last_fault: str = ""
    last_fault_stamp_ns: int = 0


class LogEvent(msgspec.Struct, kw_only=True):
    """A service event or fault (mapped to foxglove.Log by the logger)."""

    stamp_ns: int
    service: str
    level: str  # "debug" | "info" | "warning" | "error" | "fatal"
    message: str
