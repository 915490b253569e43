"""Pure PID (after simple-pid and control_toolbox) and the two-axis velocity controller.

Derivative on measurement through a first-order filter (time constant Td/N), Ki inside the
integral (gain changes are bumpless), clamping anti-windup, output saturation; dt is passed in.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

NEUTRAL_V = 2.5
VOLTS_PER_EFFORT = 1.5  # thesis eq. 5.17: V = 1.5·C + 2.5


@dataclass
class PID:
    kp: float
    ki: float
    kd: float
    out_min: float = -1.0
    out_max: float = 1.0
    d_filter_n: float = 10.0  # derivative filter: Tf = (Kd/Kp)/N
    integral: float = 0.0  # already multiplied by Ki
    _d: float = 0.0  # filtered derivative of the measurement
    _prev_meas: float | None = None

    def reset(self, measurement: float | None = None, output: float = 0.0) -> None:
        """Bumpless restart: the next output continues from `output` with no derivative kick."""
        self._d = 0.0
        self._prev_meas = measurement
        self.integral = min(max(output, self.out_min), self.out_max)

    def update(self, setpoint: float, measurement: float, dt: float) -> float:
        if dt <= 0:
            raise ValueError("dt must be > 0")
        error = setpoint - measurement
        if self._prev_meas is not None and self.kd > 0:
            tf = (self.kd / self.kp) / self.d_filter_n if self.kp > 0 else 0.0
            raw = -(measurement - self._prev_meas) / dt  # derivative on measurement: no kick
            alpha = dt / (tf + dt)
            self._d += alpha * (raw - self._d)
        self._prev_meas = measurement
        p, d = self.kp * error, self.kd * self._d
        candidate = self.integral + self.ki * error * dt
        # Clamping anti-windup: integrate only if that does not push further into saturation.
        unsat = p + candidate + d
        if not ((unsat > self.out_max and error > 0) or (unsat < self.out_min and error < 0)):
            self.integral = min(max(candidate, self.out_min), self.out_max)
        return min(max(p + self.integral + d, self.out_min), self.out_max)


@dataclass(frozen=True)
class PidOutput:
    v_effort: float
    omega_effort: float
    longitudinal_v: float
    angular_v: float
    active: bool
    desired: tuple[float, float] = (0.0, 0.0)  # within caps and limit ((0, 0) when stopped)


@dataclass(frozen=True)
class Command:
    """A desired velocity as received: who sent it, its own stamp and its stream's start."""

    v: float
    omega: float
    source: str  # "autonomy" (keys.CMD_VEL) or "teleop" (keys.TELEOP)
    stamp_ns: int  # Unix ns, the sender's clock
    stream_start_ns: int  # when the deliberate act that began the stream happened (Unix ns)


class Verdict(enum.Enum):
    """What became of a command (the node counts them as `desired_<name>`)."""

    OK = "ok"
    REJECTED = "rejected"  # not finite
    NOT_OWNER = "not_owner"
    OLD = "old"  # its stamp is older than the stale threshold
    FUTURE = "future"  # stamped further ahead than the allowed clock skew
    BEFORE_STOP = "before_stop"  # its stream began before the last stop (no unexpected start)


@dataclass(frozen=True)
class Caps:
    """Absolute bounds on the desired velocity, whatever its source (CLI, teleop, autonomy)."""

    v_fwd_mps: float = 1.2
    v_rev_mps: float = 0.5
    omega_radps: float = 1.0


@dataclass
class VelocityPidCore:
    """Two PIDs (longitudinal, angular) with the thesis's Ziegler–Nichols gains by default, and
    the drive chain's arbiter: which command may move the chair.

    No unexpected start-up (ISO 14118): after any stop the chair did not ask for (this core's
    own start, an e-stop latch, a silent e-stop, an owner change, a command stream going stale,
    a safety stop, an odometry gap, the gateway lost) the core obeys only a command stream that
    BEGAN after the stop (`Command.stream_start_ns` > `stop_ns`): a new goal, a fresh deadman
    press, a new `drive`. A stream that simply goes on is refused. While it obeys nothing the
    output is exact neutral: the chair's own controller brakes, which never reverses.

    `now_s` is monotonic (timeouts); `now_ns` is the Unix clock (stamps, stream starts).
    """

    v_gains: tuple[float, float, float] = (0.90, 1.03, 0.20)
    omega_gains: tuple[float, float, float] = (0.72, 1.08, 0.12)
    min_v: float = 1.1  # joystick window, volts
    max_v: float = 3.9
    stale_s: float = 0.3  # desired velocity older than this → stop
    skew_s: float = 0.1  # commands stamped further ahead than this are rejected
    stop_eps: float = 0.02  # |desired| and |measured| below this with a zero goal → exact neutral
    require_limit: bool = False  # True: no fresh safety limit → stop
    limit_stale_s: float = 0.5
    require_estop: bool = True  # no e-stop heartbeat → stop (as the gateway does)
    estop_stale_s: float = 0.5
    # No measurement for this long → stop (a dead or restarted odometry, a stalled link; the
    # token and the link epoch catch the quick ones).
    odom_gap_s: float = 0.3
    caps: Caps = field(default_factory=Caps)
    start_ns: int = 0  # when this core started: a restarted PID obeys nothing begun before
    owner: str = "autonomy"  # whose commands count: "autonomy" (CMD_VEL) or "teleop"
    v_pid: PID = field(init=False)
    omega_pid: PID = field(init=False)
    stop_ns: int = field(init=False)  # commands must have begun after this (Unix ns)
    stop_reason: str = field(init=False)
    _desired: tuple[float, float] = (0.0, 0.0)
    _desired_t: float = -math.inf  # -inf: obeying nothing
    _active: bool = False
    # fwd, rev (> 0), |ω|, rev for autonomy (> 0) bounds
    _limit: tuple[float, float, float, float] | None = None
    _limit_t: float = -math.inf
    _estop_latched: bool = False
    _estop_t: float = -math.inf
    _last_update_t: float | None = None
    _link: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        lo = (self.min_v - NEUTRAL_V) / VOLTS_PER_EFFORT
        hi = (self.max_v - NEUTRAL_V) / VOLTS_PER_EFFORT
        self.v_pid = PID(*self.v_gains, out_min=lo, out_max=hi)
        self.omega_pid = PID(*self.omega_gains, out_min=lo, out_max=hi)
        self.stop_ns, self.stop_reason = self.start_ns, "started"

    # --- inputs -----------------------------------------------------------------------------
    def set_desired(self, cmd: Command, now_s: float, now_ns: int) -> Verdict:
        """Take a desired velocity; only an OK command moves the chair."""
        if not (math.isfinite(cmd.v) and math.isfinite(cmd.omega)):
            return Verdict.REJECTED
        if cmd.source != self.owner:
            return Verdict.NOT_OWNER
        if now_ns - cmd.stamp_ns > self.stale_s * 1e9:
            return Verdict.OLD
        if cmd.stamp_ns - now_ns > self.skew_s * 1e9:
            return Verdict.FUTURE
        if cmd.stream_start_ns <= self.stop_ns:
            return Verdict.BEFORE_STOP
        self._desired, self._desired_t = (cmd.v, cmd.omega), now_s
        return Verdict.OK

    def stop(self, reason: str, now_ns: int) -> bool:
        """A stop nobody asked for: obey nothing begun before `now_ns`. True if it ended
        obeying a stream (the node says so once)."""
        was = self.obeying
        self.stop_ns = max(self.stop_ns, now_ns)
        self._desired_t = -math.inf
        self.stop_reason = reason
        return was

    def set_owner(self, owner: str, now_ns: int) -> bool:
        """Hand the drive to "autonomy" or "teleop": a stop; the new owner must begin anew."""
        if owner not in ("autonomy", "teleop"):
            return False
        if owner != self.owner:
            self.owner = owner
            self.stop(f"drive handed to {owner}", now_ns)
        return True

    def set_limit(self, v_fwd: float, v_rev: float, omega: float, now_s: float,
                  v_rev_autonomy: float = 0.0) -> bool:
        if not all(math.isfinite(x) and x >= 0 for x in (v_fwd, v_rev, omega, v_rev_autonomy)):
            return False
        self._limit, self._limit_t = (v_fwd, v_rev, omega, v_rev_autonomy), now_s
        return True

    def set_estop(self, latched: bool, now_s: float, now_ns: int) -> bool:
        self._estop_latched, self._estop_t = latched, now_s
        return self.stop("e-stop latched", now_ns) if latched else False

    def estop_gone(self, now_ns: int) -> bool:
        """The e-stop service's token vanished: silent now, not after the heartbeat timeout."""
        self._estop_t = -math.inf
        return self.stop("e-stop service gone", now_ns)

    def limit_gone(self, now_ns: int) -> bool:
        """The safety monitor's token vanished: its limit is gone now, not when it goes
        stale; a stop when the limit is required."""
        self._limit_t = -math.inf
        return self.stop("safety monitor gone", now_ns) if self.require_limit else False

    # --- state ------------------------------------------------------------------------------
    @property
    def obeying(self) -> bool:
        return self._desired_t > -math.inf

    def inhibit(self, now_s: float) -> str:
        """Why no command moves the chair now ("" while one does): a condition that still
        holds, or "stopped (...)" when a new command would be obeyed."""
        if self._estop_latched:
            return "e-stop latched"
        if self.require_estop and now_s - self._estop_t > self.estop_stale_s:
            return "e-stop silent"
        if self.require_limit and now_s - self._limit_t > self.limit_stale_s:
            return "no fresh safety limit"
        if self._limit is not None and now_s - self._limit_t <= self.limit_stale_s \
                and self._limit[0] == 0.0 and self._limit[2] == 0.0:
            return "the safety monitor says stop"
        if self.obeying:
            return ""
        return f"stopped ({self.stop_reason}): waiting for a command begun after the stop"

    def desired(self, now_s: float, now_ns: int) -> tuple[float, float] | None:
        """The desired velocity within the caps and the safety limit, or None when obeying
        nothing (stale, stopped)."""
        if not self.obeying:
            return None
        if now_s - self._desired_t > self.stale_s:
            self.stop("command stream stale", now_ns)
            return None
        v, omega = self._desired
        c = self.caps
        v, omega = min(max(v, -c.v_rev_mps), c.v_fwd_mps), min(max(omega, -c.omega_radps),
                                                               c.omega_radps)
        limit = self._limit if now_s - self._limit_t <= self.limit_stale_s else None
        if limit is None:
            if not self.require_limit:
                return v, omega
            limit, why = (0.0, 0.0, 0.0, 0.0), "no fresh safety limit"
        else:
            why = "safety stop"
        fwd, rev, w, rev_auto = limit
        rev = rev if self.owner == "teleop" else rev_auto  # unattended: only what is sensed
        lv, lw = min(max(v, -rev), fwd), min(max(omega, -w), w)
        if (lv, lw) == (0.0, 0.0) and (abs(v) > 1e-3 or abs(omega) > 1e-3):
            self.stop(why, now_ns)  # stopped by the limit: brake by neutral, never reverse
            return None
        return lv, lw

    def update(self, v_meas: float, omega_meas: float, dt: float, now_s: float,
               now_ns: int, link: tuple[int, int] = (0, 0)) -> PidOutput:
        """One loop step on a measurement. `link` is (MCU restarts, serial link epoch) as the
        odometry saw them: a new link or a restarted MCU (booted at neutral) is a stop,
        however short the gap."""
        gap = self._last_update_t is not None and now_s - self._last_update_t > self.odom_gap_s
        self._last_update_t = now_s
        if gap:
            self.stop("odometry gap", now_ns)
        if self._link is not None and link != self._link:
            self.stop("serial link or chair MCU restarted", now_ns)
        self._link = link
        if self.require_estop and now_s - self._estop_t > self.estop_stale_s:
            self.stop("e-stop silent", now_ns)
        elif self._estop_latched:
            self.stop("e-stop latched", now_ns)
        if not (math.isfinite(v_meas) and math.isfinite(omega_meas)):
            # A bad measurement must not poison the integrators: a stop, nothing learned.
            self.stop("non-finite measurement", now_ns)
            v_meas = omega_meas = 0.0
        desired = self.desired(now_s, now_ns)
        at_rest = desired is not None and desired == (0.0, 0.0) and \
            abs(v_meas) < self.stop_eps and abs(omega_meas) < self.stop_eps
        # (a first sample has dt 0; a non-finite or absurd dt is skipped the same way)
        if desired is None or at_rest or not 0 < dt <= 1.0:
            # Stopped or parked: exact neutral, integrators cleared for a bumpless restart.
            self._active = False
            self.v_pid.reset(v_meas)
            self.omega_pid.reset(omega_meas)
            return PidOutput(0.0, 0.0, NEUTRAL_V, NEUTRAL_V, False, desired or (0.0, 0.0))
        if not self._active:
            self._active = True  # re-seeded from the measured velocity: nothing lunges
            self.v_pid.reset(v_meas)
            self.omega_pid.reset(omega_meas)
        cv = self.v_pid.update(desired[0], v_meas, dt)
        cw = self.omega_pid.update(desired[1], omega_meas, dt)
        return PidOutput(cv, cw, effort_to_volts(cv, self.min_v, self.max_v),
                         effort_to_volts(cw, self.min_v, self.max_v), True, desired)


def effort_to_volts(c: float, min_v: float = 1.1, max_v: float = 3.9) -> float:
    return min(max(VOLTS_PER_EFFORT * c + NEUTRAL_V, min_v), max_v)
