"""autochair message types (msgspec Structs) and the table of Zenoh keys (`keys`)."""

from .common import Empty, FrameTransform, Health, LogEvent, Quaternion, Vector3
from .drive import (
    CommandOwner,
    EncoderSample,
    GroundTruth,
    JoystickCommand,
    JoystickOutput,
    Odometry,
    PidStatus,
    VelocityCommand,
)
from .lidar import LaserScan, OccupancyGrid, PointCloud
from .nav import GoalReply, GoalRequest, GoalStatus, Pose2D
from .safety import (
    EStopAssert,
    EStopCause,
    EStopRelease,
    EStopReply,
    EStopState,
    SafetyLimit,
)

__all__ = [
    "CommandOwner",
    "EStopAssert",
    "EStopCause",
    "EStopRelease",
    "EStopReply",
    "EStopState",
    "Empty",
    "EncoderSample",
    "FrameTransform",
    "GoalReply",
    "GoalRequest",
    "GoalStatus",
    "GroundTruth",
    "Health",
    "JoystickCommand",
    "JoystickOutput",
    "LaserScan",
    "LogEvent",
    "OccupancyGrid",
    "Odometry",
    "PidStatus",
    "PointCloud",
    "Pose2D",
    "Quaternion",
    "SafetyLimit",
    "Vector3",
    "VelocityCommand",
]
