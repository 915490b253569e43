"""Goals for the smooth local control law."""

from __future__ import annotations

from typing import Literal

import msgspec


class Pose2D(msgspec.Struct, frozen=True):
    """A planar pose, metres and radians, in the frame its message names (`odom`, REP-105's
    odometry origin where the chair started, unless said otherwise)."""

    x_m: float
    y_m: float
    yaw_rad: float


class GoalRequest(msgspec.Struct, kw_only=True):
    """Set a goal: one pose, or several waypoints driven in order (the last is the goal)."""

    waypoints: list[Pose2D]
    # "odom", or "map": driven on localization's map (re-expressed in odom with its newest
    # correction, only while it is tracking)
    frame_id: Literal["odom", "map"] = "odom"
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
    # "idle" | "planning" | "driving" | "blocked" | "arrived" | "aborted" | "cancelled"
    # (planning, driving and blocked: the goal is active; blocked and aborted say why in reason)
    state: str
    waypoint_index: int = 0
    waypoint_count: int = 0
    distance_left_m: float = 0.0
    eta_s: float = 0.0
    reason: str = ""


class NavPlan(msgspec.Struct, kw_only=True):
    """MPEPC's latest plan (control), in `frame_id` (the map's): the law's target and speed,
    the predicted path of the drive-axle centre, the chair's footprint outline where it is now
    (a closed polygon) and the people it plans around. Metres and radians."""

    stamp_ns: int
    frame_id: str
    goal_id: int
    state: str  # the goal's state (GoalStatus.state)
    target_x_m: float
    target_y_m: float
    target_yaw_rad: float
    vmax_mps: float
    path_x_m: list[float]
    path_y_m: list[float]
    path_yaw_rad: list[float]
    footprint_xy_m: list[float]  # x0, y0, x1, y1, ... (corners, in order)
    people_xyr_m: list[float] = []  # x, y, radius per person
    cost: float = 0.0
    progress_m: float = 0.0  # φ(now) − φ(end of the prediction)
    survival: float = 1.0
    min_clearance_m: float = 0.0
    plan_ms: float = 0.0  # the planning cycle's wall time
    new_field: bool = False  # the first cycle on a field made since the last (the map changed)


class TrackedPerson(msgspec.Struct, kw_only=True, frozen=True):
    """A person (or anything that moves and is not the map's) tracked in the scans."""

    track_id: int
    x_m: float
    y_m: float
    vx_mps: float
    vy_mps: float
    radius_m: float


class People(msgspec.Struct, kw_only=True):
    """The people the tracker follows (mapping), in `frame_id` (odom), for MPEPC: predicted at
    constant velocity. Empty when there is no one."""

    stamp_ns: int  # the scan's
    frame_id: str
    people: list[TrackedPerson] = []
