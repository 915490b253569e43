"""Goals for the smooth local control law."""

from __future__ import annotations

import msgspec


class Pose2D(msgspec.Struct, frozen=True):
    """A pose in `world`: metres and radians."""

    x_m: float
    y_m: float
    yaw_rad: float


class GoalRequest(msgspec.Struct, kw_only=True):
    """Set a goal: one pose, or several waypoints driven in order (the last is the goal)."""

    waypoints: list[Pose2D]
    tolerance_m: float = 0.05
    tolerance_rad: float = 0.05235987755982988  # 3°
    vmax_mps: float | None = None


class GoalReply(msgspec.Struct, kw_only=True):
    ok: bool
    goal_id: int = 0
    error: str = ""


class GoalStatus(msgspec.Struct, kw_only=True):
    stamp_ns: int
    goal_id: int
    state: str  # "idle" | "active" | "arrived" | "aborted" | "cancelled"
    waypoint_index: int = 0
    waypoint_count: int = 0
    distance_left_m: float = 0.0
    eta_s: float = 0.0
    reason: str = ""
