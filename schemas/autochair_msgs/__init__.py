"""autochair message types (msgspec Structs) and the table of Zenoh keys (`keys`)."""

from .common import Empty, FrameTransform, Health, LogEvent, Quaternion, Vector3
from .drive import (
    CommandOwner,
    EncoderSample,
    GroundTruth,
    JoystickCommand,
    JoystickOutput,
    Odometry,
    PidProbeReply,
    PidProbeRequest,
    PidStatus,
    VelocityCommand,
)
from .lidar import LaserScan, OccupancyGrid, PointCloud
from .localization import (
    LocalizedPose,
    LocalizeReply,
    LocalizeRequest,
    MapSaveReply,
    MapSaveRequest,
)
from .nav import GoalReply, GoalRequest, GoalStatus, NavPlan, People, Pose2D, TrackedPerson
from .safety import (
    EStopAssert,
    EStopCause,
    EStopRelease,
    EStopReply,
    EStopState,
    SafetyLimit,
    says_stop,
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
    "LocalizeReply",
    "LocalizeRequest",
    "LocalizedPose",
    "LogEvent",
    "MapSaveReply",
    "MapSaveRequest",
    "NavPlan",
    "OccupancyGrid",
    "Odometry",
    "People",
    "PidProbeReply",
    "PidProbeRequest",
    "PidStatus",
    "PointCloud",
    "Pose2D",
    "Quaternion",
    "SafetyLimit",
    "TrackedPerson",
    "Vector3",
    "VelocityCommand",
    "says_stop",
]
