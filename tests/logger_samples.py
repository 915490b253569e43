"""Non-trivial messages of every type in the key table (shared by the logger tests and bench)."""

from __future__ import annotations

import math
from typing import Any

import msgspec

from autochair_msgs import (
    CommandOwner,
    EncoderSample,
    FrameTransform,
    GoalRequest,
    GoalStatus,
    GroundTruth,
    Health,
    JoystickCommand,
    JoystickOutput,
    LaserScan,
    LogEvent,
    OccupancyGrid,
    Odometry,
    PidStatus,
    PointCloud,
    Pose2D,
    Quaternion,
    Vector3,
    VelocityCommand,
    keys,
)

T0 = 1_763_700_000_123_456_789  # a stamp above 2^53: JSON readers in JS would round it


def auto_sample(type_: Any, i: int) -> Any:
    """A non-trivial value of any msgspec type (for key-table rows added without a
    hand-written sample): NaN in float fields, large ints, non-ASCII text, every byte."""
    info = msgspec.inspect.type_info(type_) if not isinstance(
        type_, msgspec.inspect.Type) else type_
    if isinstance(info, msgspec.inspect.StructType):
        return info.cls(**{f.name: auto_sample(f.type, i + n)
                           for n, f in enumerate(info.fields)})
    if isinstance(info, msgspec.inspect.FloatType):
        return [math.nan, -math.inf, 0.1 + i, -1e-300][i % 4]
    if isinstance(info, msgspec.inspect.BoolType):
        return i % 2 == 0
    if isinstance(info, msgspec.inspect.IntType):
        return 2**40 + i
    if isinstance(info, msgspec.inspect.StrType):
        return f"x ü {i}"
    if isinstance(info, msgspec.inspect.BytesType):
        return bytes(range(256))
    if isinstance(info, msgspec.inspect.ListType):
        return [auto_sample(info.item_type, i + k) for k in range(3)]
    if isinstance(info, msgspec.inspect.DictType):
        return {f"k{k}": auto_sample(info.value_type, i + k) for k in range(2)}
    if isinstance(info, msgspec.inspect.UnionType):
        return auto_sample(next(t for t in info.types
                                if not isinstance(t, msgspec.inspect.NoneType)), i)
    if isinstance(info, msgspec.inspect.LiteralType):
        return info.values[0]
    raise TypeError(f"add a sample for {info}")


def samples(i: int = 0) -> dict[str, msgspec.Struct]:
    """One message per concrete key (per-service rows get the key of service "pid")."""
    out = {k: m for k, m in _hand_samples(i).items() if keys.by_key(k).logged}
    for t in keys.TOPICS:  # rows added to the table later: generated samples
        key = t.for_service("pid") if t.key.endswith("/*") else t.key
        if t.logged and t.kind == "pub" and key not in out:
            out[key] = auto_sample(t.type, i)
    return out


def _hand_samples(i: int) -> dict[str, msgspec.Struct]:
    t = T0 + i * 5_000_000
    nan, inf = math.nan, math.inf
    return {
        keys.ENCODERS.key: EncoderSample(stamp_ns=t, seq=65535 - i, mcu_time_us=2**32 - 1,
                                         left_counts=2**32 - 7, right_counts=123456 + i,
                                         status=0b1011, dropped=3),
        keys.JOYSTICK.key: JoystickCommand(stamp_ns=t, longitudinal_v=2.5 + 1e-12 * i,
                                           angular_v=1 / 3, enable=False, source_seq=i),
        keys.JOYSTICK_OUT.key: JoystickOutput(stamp_ns=t, seq=i, longitudinal_v=3.9,
                                              angular_v=0.1 + 0.2, enable=True,
                                              reason="neutral:stale ü", clamped=True),
        keys.CMD_VEL.key: VelocityCommand(stamp_ns=t, v_mps=-0.0, omega_radps=5e-324,
                                          source="cli"),
        keys.TELEOP.key: VelocityCommand(stamp_ns=t, v_mps=0.3, omega_radps=-0.25,
                                         source="teleop"),
        keys.CMD_OWNER.key: CommandOwner(stamp_ns=t, owner="teleop", by="laptop-ü"),
        keys.ODOM.key: Odometry(stamp_ns=t, x_m=1.25 + i, y_m=-3.5, yaw_rad=math.pi,
                                v_mps=0.7, omega_radps=-0.2, distance_m=12.0, source_seq=i),
        keys.TF.key: FrameTransform(stamp_ns=t, parent_frame_id="odom", child_frame_id="chair",
                                    translation=Vector3(1.0, 2.0, 0.0),
                                    rotation=Quaternion(0.0, 0.0, math.sin(0.5),
                                                        math.cos(0.5))),
        keys.TF_STATIC.key: FrameTransform(stamp_ns=t, parent_frame_id="chair",
                                           child_frame_id="laser",
                                           translation=Vector3(0.8636, 0.2032, 0.3937),
                                           rotation=Quaternion()),
        keys.PID_STATUS.key: PidStatus(stamp_ns=t, v_desired_mps=1.0, v_measured_mps=nan,
                                       v_effort=1.0, omega_desired_radps=-inf,
                                       omega_measured_radps=inf, omega_effort=-1.0,
                                       active=True, saturated=True),
        keys.SIM_TRUTH.key: GroundTruth(stamp_ns=t, sim_time_s=0.005 * i, x_m=1e-300,
                                        y_m=1e300, yaw_rad=-math.pi + 1e-9, v_mps=0.1,
                                        omega_radps=0.0, longitudinal_v=2.5, angular_v=2.5),
        keys.GOAL_STATUS.key: GoalStatus(stamp_ns=t, goal_id=7, state="active",
                                         waypoint_index=1, waypoint_count=3,
                                         distance_left_m=nan, eta_s=4.5, reason="null"),
        keys.SCAN.key: LaserScan(stamp_ns=t, frame_id="laser", angle_min_rad=-2.0862,
                                 angle_increment_rad=2 * math.pi / 1024, range_min_m=0.02,
                                 range_max_m=5.6, ranges_m=[0.5, nan, 5.6, 0.019, inf, 1.0],
                                 scan_seq=i, device_time_ms=2**24 + 5),
        keys.MAP_GRID.key: OccupancyGrid(stamp_ns=t, frame_id="odom", resolution_m=0.05,
                                         width=4, height=3, origin_x_m=-1.0, origin_y_m=-0.5,
                                         data=bytes([0, 100, 255, 50] * 3)),
        keys.MAP_CLOUD.key: PointCloud(stamp_ns=t, frame_id="odom", count=2,
                                       points_xyz_f32=bytes(range(24))),
        keys.HEALTH.for_service("pid"): Health(
            stamp_ns=t, service="pid", state="fault", uptime_s=12.5,
            counters={"rx": 10, "decode_errors:autochair/odom": 2},
            rates_hz={"rx": 200.0, "bad": nan}, thresholds={"stale_s": 0.1},
            detail="odometry stale", last_fault="odom stale", last_fault_stamp_ns=t - 1),
        keys.LOG.key: LogEvent(stamp_ns=t, service="gateway", level="warning",
                               message='bad "frame"\n\tNaN'),
    }


_HAND_OTHER: dict[str, msgspec.Struct] = {
    keys.GOAL_SET.key: GoalRequest(
        waypoints=[Pose2D(1.0, 2.0, 0.5), Pose2D(math.nan, 0.0, -math.inf)], vmax_mps=None),
    keys.GOAL_CANCEL.key: GoalRequest(waypoints=[], tolerance_m=0.1, vmax_mps=0.8),
}


def other_samples() -> dict[str, Any]:
    """Rows the logger does not record (queries, unlogged keys) and query reply types: the
    codec must still round-trip them (keyed `key` and `key#reply`)."""
    out: dict[str, Any] = dict(_HAND_OTHER)
    for t in keys.TOPICS:
        if not (t.logged and t.kind == "pub"):
            out.setdefault(t.key, auto_sample(t.type, 1))
        if t.reply is not None:
            out[t.key + "#reply"] = auto_sample(t.reply, 2)
    return out


QUERY_SAMPLES = other_samples()
