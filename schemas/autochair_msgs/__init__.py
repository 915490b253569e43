"""autochair message types (msgspec Structs) and the table of Zenoh keys (`keys`)."""

from .common import FrameTransform, Health, LogEvent, Quaternion, Vector3
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

__all__ = [
    "CommandOwner",
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
    "Vector3",
    "VelocityCommand",
]
