"""Messages of the drive chain: chair ↔ gateway ↔ odometry ↔ velocity PID."""

from __future__ import annotations

import msgspec


class EncoderSample(msgspec.Struct, kw_only=True, frozen=True):
    """One telemetry frame from the chair, as received by the gateway.

    Counts are the MCU's raw 32-bit counters (unsigned, wrapping): consumers unwrap them with a
    modular difference. 10000 counts per encoder-wheel revolution on the thesis chair.
    """

    stamp_ns: int  # host receive time
    seq: int  # 16-bit frame sequence number from the MCU
    mcu_time_us: int  # 32-bit MCU clock, µs, wrapping
    left_counts: int
    right_counts: int
    status: int  # bit field, see docs/arduino-protocol.md
    dropped: int = 0  # frames missing before this one (sequence gap)
    link_epoch: int = 0  # the gateway's serial (re)connections so far: a new link, a new epoch


class JoystickCommand(msgspec.Struct, kw_only=True, frozen=True):
    """Joystick voltages wanted by the velocity PID (volts; 2.5 V is neutral).

    `longitudinal_v` > 2.5 drives forward; `angular_v` > 2.5 turns left (counter-clockwise, ISO).
    """

    stamp_ns: int
    longitudinal_v: float
    angular_v: float
    enable: bool = True
    source_seq: int = -1  # encoder frame this command was computed from (latency tracing)


class JoystickOutput(msgspec.Struct, kw_only=True, frozen=True):
    """What the gateway actually wrote to the chair, and why."""

    stamp_ns: int
    seq: int  # 16-bit host frame sequence number
    longitudinal_v: float
    angular_v: float
    enable: bool
    reason: str  # "command" | "neutral:startup" | "neutral:stale" | "neutral:estop" | ...
    clamped: bool = False


class VelocityCommand(msgspec.Struct, kw_only=True, frozen=True):
    """Desired chair velocity (m/s, rad/s; ω > 0 turns left)."""

    stamp_ns: int
    v_mps: float
    omega_radps: float
    source: str = ""  # "cli" | "control" | "teleop" | ...
    # When the deliberate act that began this command stream happened (a goal accepted, a
    # deadman pressed, a `drive` started), Unix ns. No unexpected start-up (ISO 14118): after
    # any stop the chair did not ask for, the velocity PID obeys only streams begun after it.
    stream_start_ns: int = 0


class Odometry(msgspec.Struct, kw_only=True, frozen=True):
    """Pose of the chair's drive-axle centre in `odom` (REP-105), from encoders alone."""

    stamp_ns: int
    x_m: float
    y_m: float
    yaw_rad: float  # in (-π, π]
    v_mps: float
    omega_radps: float
    distance_m: float = 0.0  # path length travelled since start
    sample_dt_s: float = 0.0  # time since the previous encoder sample, on the MCU clock
    source_seq: int = -1  # encoder frame this estimate is from
    # The link's history as the PID must know it: a new serial link (gateway reconnect or
    # restart) or a chair MCU restart (its neutral boot) means the chain stopped: a stop.
    mcu_restarts: int = 0  # chair MCU restarts seen
    link_epoch: int = 0  # EncoderSample.link_epoch of this sample
    frame_id: str = "odom"
    child_frame_id: str = "chair"


class PidStatus(msgspec.Struct, kw_only=True, frozen=True):
    """Both velocity loops: desired, measured and effort (effort C in [-1, 1])."""

    stamp_ns: int
    v_desired_mps: float
    v_measured_mps: float
    v_effort: float
    omega_desired_radps: float
    omega_measured_radps: float
    omega_effort: float
    active: bool  # False while the desired velocity is stale (zero effort)
    saturated: bool = False
    # Why the PID obeys no command now ("" while it does): e.g. "e-stop latched", "stopped
    # (owner change): waiting for a command begun after the stop".
    inhibit: str = ""
    # How old the newest command was when the loops first followed it (its stamp to that
    # step, s): the way from its sender plus the wait for an encoder sample.
    command_age_s: float = 0.0


class GroundTruth(msgspec.Struct, kw_only=True, frozen=True):
    """The simulator's true chair state (never present on a real chair)."""

    stamp_ns: int
    sim_time_s: float
    x_m: float
    y_m: float
    yaw_rad: float
    v_mps: float
    omega_radps: float
    longitudinal_v: float  # joystick voltages the simulated controller sees
    angular_v: float


class CommandOwner(msgspec.Struct, kw_only=True, frozen=True):
    """Who may move the chair: "autonomy" (keys.CMD_VEL) or "teleop" (keys.TELEOP).

    Contract (see keys.CMD_OWNER): the velocity PID obeys only the owner's key. Teleop sends
    owner="teleop" to take over (and repeats it about once a second for late joiners) and
    owner="autonomy" to hand back explicitly; a lost teleop link does NOT hand back.
    """

    stamp_ns: int
    owner: str  # "autonomy" | "teleop"
    by: str = ""  # who asked (e.g. the laptop's name), for the log


class PidProbeRequest(msgspec.Struct, kw_only=True, frozen=True):
    """A tuning probe of one velocity loop (autochair tune), run inside the PID so every gate
    of the PID still applies. action "start": open-loop probe around the operating point the
    loop holds now (a command stream must be driving); "get": its state and trace; "stop"."""

    action: str  # "start" | "get" | "stop"
    kind: str = "relay"  # "relay" (Åström–Hägglund, with hysteresis) | "step"
    axis: str = "longitudinal"  # "longitudinal" | "angular"
    amplitude: float = 0.2  # relay d or step Δ, effort units (≤ 0.5)
    hysteresis: float = 0.005  # relay ε, m/s or rad/s
    duration_s: float = 30.0
    cycles: int = 8  # relay periods wanted
    speed_bound: float = 1.0  # |measured| above this aborts the probe and stops the chair


class PidProbeReply(msgspec.Struct, kw_only=True, frozen=True):
    ok: bool
    error: str = ""
    state: str = ""  # "running" | "done" | "aborted" | "" (no probe)
    reason: str = ""
    setpoint: float = 0.0
    bias: float = 0.0  # the effort that held the setpoint
    t_s: list[float] = []  # the trace, from the probe's start (only when not running)
    measured: list[float] = []
    effort: list[float] = []
