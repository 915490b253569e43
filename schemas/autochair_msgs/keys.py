"""The one table of every Zenoh key in autochair (after openpilot's cereal/services.py).

Each row: key expression, message type, nominal rate (None = on event), whether the logger
records it, and what it is. Services, the logger, the CLI and the docs all read this table.
"""

from __future__ import annotations

import builtins
from dataclasses import dataclass
from typing import Generic, Literal, TypeVar

import msgspec

from .common import Empty, FrameTransform, Health, LogEvent
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
from .nav import GoalReply, GoalRequest, GoalStatus, NavPlan, People
from .safety import EStopAssert, EStopRelease, EStopReply, EStopState, SafetyLimit
from .sim import SimFault, SimFaultReply

T = TypeVar("T", bound=msgspec.Struct)

PREFIX = "autochair"


@dataclass(frozen=True)
class Topic(Generic[T]):
    key: str
    type: type[T]
    rate_hz: float | None
    logged: bool
    doc: str
    kind: Literal["pub", "query"] = "pub"
    # For "query" rows: the reply type (the request type is `type`).
    reply: builtins.type[msgspec.Struct] | None = None

    def for_service(self, service: str) -> str:
        """Concrete key of a per-service row (`.../*`)."""
        assert self.key.endswith("/*"), self.key
        return self.key[:-1] + service


# --- drive chain ---------------------------------------------------------------------------
# The drive chain's one rate (telemetry, odometry, PID, joystick frames); the thesis's xPC
# Target ran its controller at 100 Hz. The firmware's AC_FRAME_US must match (test_firmware_*).
DRIVE_RATE_HZ = 100
ENCODERS = Topic("autochair/chair/encoders", EncoderSample, DRIVE_RATE_HZ, True,
                 "Encoder telemetry from the chair (gateway)")
JOYSTICK = Topic("autochair/chair/joystick", JoystickCommand, DRIVE_RATE_HZ, False,
                 "Joystick voltages wanted (velocity PID → gateway); not recorded: the PID's "
                 "effort is in pid/status and what reached the chair in joystick_out")
JOYSTICK_OUT = Topic("autochair/chair/joystick_out", JoystickOutput, DRIVE_RATE_HZ, True,
                     "Joystick frames actually written to the chair (gateway)")
CMD_VEL = Topic("autochair/cmd/vel", VelocityCommand, 20, True,
                "Desired velocity (control law, CLI, teleop → velocity PID)")
TELEOP = Topic("autochair/cmd/teleop", VelocityCommand, 20, True,
               "Teleop velocity (laptop keyboard/pad → velocity PID), obeyed only while "
               "CMD_OWNER says \"teleop\"; teleop sends zero then stops on deadman")
CMD_OWNER = Topic("autochair/cmd/owner", CommandOwner, 1, True,
                  "Who drives: \"autonomy\" (PID obeys CMD_VEL, the default) or \"teleop\" "
                  "(PID obeys TELEOP only). Teleop takes over and hands back explicitly and "
                  "repeats its claim ~1 Hz; a lost link leaves \"teleop\" (stale → stop)")
ODOM = Topic("autochair/odom", Odometry, DRIVE_RATE_HZ, True, "Encoder odometry (odometry)")
ODOM_SLOW = Topic("autochair/odom/slow", Odometry, 50, False,
                  "The same odometry decimated to 50 Hz for consumers that need no more "
                  "(safety, control, tools); not recorded: autochair/odom is, at full rate")
TF = Topic("autochair/tf", FrameTransform, 20, True,
           "Dynamic transforms (REP-105): odom → chair (odometry; the pose of ODOM, "
           "decimated) and map → odom (localization)")
TF_STATIC = Topic("autochair/tf_static", FrameTransform, 1, True,
                  "Static transforms, e.g. chair → laser, repeated for late joiners")
PID_STATUS = Topic("autochair/pid/status", PidStatus, DRIVE_RATE_HZ, True,
                   "Velocity loops: desired, measured, effort (velocity PID)")
PID_PROBE = Topic("autochair/pid/probe", PidProbeRequest, None, False,
                  "Tuning probe of a velocity loop, run inside the PID under all its gates "
                  "(query; reply PidProbeReply; autochair tune)", kind="query",
                  reply=PidProbeReply)
SIM_TRUTH = Topic("autochair/sim/truth", GroundTruth, 100, True,
                  "Simulator ground truth (simulator only)")
SIM_FAULT = Topic("autochair/sim/fault", SimFault, None, False,
                  "Inject a link fault into the simulator (query; reply SimFaultReply)",
                  kind="query", reply=SimFaultReply)

# --- navigation ----------------------------------------------------------------------------
GOAL_SET = Topic("autochair/goal/set", GoalRequest, None, False,
                 "Set a goal or waypoints (query; reply GoalReply)", kind="query", reply=GoalReply)
GOAL_CANCEL = Topic("autochair/goal/cancel", GoalRequest, None, False,
                    "Cancel the active goal (query; reply GoalReply)", kind="query",
                    reply=GoalReply)
GOAL_STATUS = Topic("autochair/goal/status", GoalStatus, 5, True, "Goal progress (control law)")
GOAL_GET = Topic("autochair/goal/get", Empty, None, False,
                 "Current goal status (query, empty request; reply GoalStatus)", kind="query",
                 reply=GoalStatus)
NAV_PLAN = Topic("autochair/nav/plan", NavPlan, 2, True,
                 "MPEPC plan: target, predicted path, footprint, people (control)")
PEOPLE = Topic("autochair/people", People, 10, True,
               "People tracked in the scans, in odom, with their velocity (control), for MPEPC "
               "and mapping (their returns are not the map's)")

# --- lidar and map -------------------------------------------------------------------------
SCAN = Topic("autochair/lidar/scan", LaserScan, 10, True, "Checked laser scans (lidar ingest)")
MAP_GRID = Topic("autochair/map/grid", OccupancyGrid, 1, True, "Occupancy grid (mapping)")
MAP_CLOUD = Topic("autochair/map/cloud", PointCloud, 1, False,
                  "Accumulated odom-frame points (mapping), for live viewers; not recorded: "
                  "the grid is, and the scans and odometry it is made from are")
LOC_POSE = Topic("autochair/localization/pose", LocalizedPose, 10, True,
                 "Chair pose in `map` with covariance, quality and state (localization)")
LOC_MAP = Topic("autochair/localization/map", OccupancyGrid, 0.2, True,
                "The map localization uses or builds, in `map` (localization)")
LOC_SET_POSE = Topic("autochair/localization/set_pose", LocalizeRequest, None, False,
                     "Set the pose on the map, or search it (query; reply LocalizeReply)",
                     kind="query", reply=LocalizeReply)
MAP_SAVE = Topic("autochair/map/save", MapSaveRequest, None, False,
                 "Save the map as PGM + YAML (query; reply MapSaveReply)", kind="query",
                 reply=MapSaveReply)

# --- safety --------------------------------------------------------------------------------
ESTOP_ASSERT = Topic("autochair/estop/assert", EStopAssert, None, True,
                     "Latch the e-stop (any service, the CLI, an allowed laptop)")
ESTOP_CLEAR = Topic("autochair/estop/clear", EStopAssert, None, True,
                    "A source's e-stop cause has cleared (services only: a laptop may latch, "
                    "never clear); the latch stays until a release")
ESTOP_STATE = Topic("autochair/estop/state", EStopState, 10, True,
                    "E-stop latch and causes (estop); gateway holds neutral if latched or silent")
ESTOP_RELEASE = Topic("autochair/estop/release", EStopRelease, None, False,
                      "Release the latch (query; reply EStopReply; refused while a cause "
                      "remains)", kind="query", reply=EStopReply)
SAFETY_LIMIT = Topic("autochair/safety/limit", SafetyLimit, 10, True,
                     "Speed bounds from the safety monitor; the velocity PID clamps to them")

# --- system --------------------------------------------------------------------------------
HEALTH = Topic("autochair/health/*", Health, 1, True, "Health of each service")
LOG = Topic("autochair/log", LogEvent, None, True, "Service events and faults")
ALIVE = "autochair/alive/*"  # liveliness tokens, one per running service
HUB_PROBE = "autochair/hub/probe"  # the hub's own queryable, asked by its watchdog probe

TOPICS: tuple[Topic[msgspec.Struct], ...] = tuple(
    v for v in list(globals().values()) if isinstance(v, Topic)
)


def by_key(key: str) -> Topic[msgspec.Struct]:
    """The table row whose key expression matches a concrete key."""
    for topic in TOPICS:
        if topic.key == key or (topic.key.endswith("/*") and key.startswith(topic.key[:-1])
                                and "/" not in key[len(topic.key) - 1:]):
            return topic
    raise KeyError(key)
