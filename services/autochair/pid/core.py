"""Pure PID (after simple-pid and control_toolbox) and the two-axis velocity controller.

Derivative on measurement through a first-order filter (time constant Td/N), Ki inside the
integral (gain changes are bumpless), clamping anti-windup, output saturation; dt is passed in.

With an identified model of the drive chain per axis (`autochair tune`) each loop is
two-degree-of-freedom: the desired velocity passes a short prefilter, its model inverse is the
feed-forward effort, and the PID acts on the model's own response (the prefiltered desired,
delayed by the dead time): the feed-forward drives, the feedback only trims model error, so a
smooth desired velocity is followed without the feedback's lag and overshoot.
"""

from __future__ import annotations

import enum
import math
import statistics
from collections import deque
from dataclasses import dataclass, field
from typing import Annotated

import msgspec

from autochair.tune.core import ChainModel, Probe, ProbeState
from autochair_msgs import says_stop
from autochair_msgs.keys import DRIVE_RATE_HZ

NEUTRAL_V = 2.5
VOLTS_PER_EFFORT = 1.5  # thesis eq. 5.17: V = 1.5·C + 2.5
# The stop latched for a command the safety monitor's limit bars, as `inhibit` (PidStatus)
# begins while it holds: the control service ends its goal on it (control/core.py)
SAFETY_STOP = "safety stop"
SAFETY_STOPPED = f"stopped ({SAFETY_STOP})"


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


@dataclass
class Feedforward:
    """One axis's 2-DOF part: the desired velocity through a prefilter (two lags of
    `prefilter_s`), the SOPDT inverse of that as feed-forward effort, and the model's response
    to the effort actually sent (after saturation) as the feedback's reference (IMC): the PID
    corrects only what the model does not explain.

    The prefilter is a reference governor: where its inverse would leave the effort window, it
    advances only as far as the window allows. Otherwise it would run ahead of a saturated
    chair, and once the effort came back into the window the chair would close the gap
    open-loop, at its own slow lags (the model's reference has the same gap, so the PID would
    not help): the slow ±5 % tail of a large step."""

    model: ChainModel
    prefilter_s: float = 0.1
    _x1: float = 0.0  # prefilter states
    _x2: float = 0.0
    _m1: float = 0.0  # model lag states (m2 = the model's output)
    _m2: float = 0.0
    _t: float = 0.0
    _queue: deque[tuple[float, float]] = field(default_factory=deque)  # (due, y) in transit
    _due: float = 0.0  # the model's delayed input

    def reset(self, y: float) -> None:
        """Start from the measured velocity: the model is taken to be at rest there."""
        self._x1 = self._x2 = self._m1 = self._m2 = self._due = y
        self._queue.clear()

    def effort(self, r: float, dt: float, lo: float = -math.inf, hi: float = math.inf) -> float:
        """Feed-forward effort in [lo, hi] for desired r over the next dt."""
        m, tf = self.model, max(self.prefilter_s, 1e-3)
        a = 1.0 - math.exp(-dt / tf)
        x1o, x2o = self._x1, self._x2

        def wanted(ri: float) -> float:
            """The velocity the inverse asks for with prefilter input ri (affine in ri)."""
            x1 = x1o + (ri - x1o) * a
            x2 = x2o + (x1 - x2o) * a
            d1 = (x1 - x2) / tf  # ṙ of the prefiltered desired
            d2 = ((ri - x1) / tf - d1) / tf  # r̈
            return x2 + (m.tau1_s + m.tau2_s) * d1 + m.tau1_s * m.tau2_s * d2

        u = m.effort_for(wanted(r))
        if not lo <= u <= hi:  # govern: the input that puts the inverse on the window's edge
            w0 = wanted(0.0)
            r = (m.output_for(min(max(u, lo), hi)) - w0) / (wanted(1.0) - w0)
        self._x1 = x1o + (r - x1o) * a
        self._x2 = x2o + (self._x1 - x2o) * a
        return min(max(m.effort_for(wanted(r)), lo), hi)

    def reference(self, u: float, dt: float) -> float:
        """Advance the model by dt with effort u applied; its output is the reference."""
        m = self.model
        self._t += dt
        self._queue.append((self._t + m.delay_s, m.output_for(u)))
        while self._queue and self._queue[0][0] <= self._t + 1e-9:
            self._due = self._queue.popleft()[1]
        self._m1 += (self._due - self._m1) * (1.0 - math.exp(-dt / max(m.tau1_s, 1e-3)))
        self._m2 += (self._m1 - self._m2) * (1.0 - math.exp(-dt / max(m.tau2_s, 1e-3)))
        return self._m2


@dataclass
class GapFill:
    """The desired velocity the loops follow: each command as it comes, except the part of a
    step that stands for a gap in the stream.

    The feed-forward's model inverse turns a step of the desired into an effort kick (its r̈
    term: at once ~5× the step in wanted velocity). A stream at its own rate steps by one
    period of its plan at a time, kicks its plan allows for; after a stall on the way (the
    sender late, or the samples late while the commands came on, so the samples meet only the
    newest) one step carries the whole gap's plan, a kick the plan never asked for (1.149 m/s²
    at the chair in lockstep after three 40 ms stalls, 0.971 without). Such a step is followed
    along the stream's straight line between the two commands' stamps: one period of the
    stream's own (the median of its last intervals) at once, as a step within it is taken,
    the rest as the samples' clock goes on. The reference then runs behind the stream by what
    the gap left, and catches up only where the stream is flat; slowing, and the way to zero,
    are never held back. A stall so delivers the plan late, never harder; a stream without
    gaps passes bit for bit."""

    # A stream's period until its own intervals are known: the control's commands (50 Hz),
    # the one stream that starts without a deliberate act right before (a goal's first
    # command may come a stall after its acceptance, the stream's start).
    default_period_s: float = 0.02
    max_gap_s: float = 0.3  # (a longer silence is a stale stream: a stop)
    value: list[float] = field(default_factory=lambda: [0.0, 0.0])  # the reference per axis
    _end: list[float] = field(default_factory=lambda: [0.0, 0.0])  # the newest command's
    _lag_s: list[float] = field(default_factory=lambda: [0.0, 0.0])  # behind it (its stamps)
    _stamp_ns: int | None = None  # the newest command's (its stream's start before one)
    _stream_ns: int | None = None  # the stream followed (None: none since a stop)
    _intervals: deque[float] = field(default_factory=lambda: deque(maxlen=5))

    def forget(self, value: tuple[float, float]) -> None:
        """Obeying nothing: the next stream starts from `value` (the measured velocity)."""
        self.value, self._end, self._lag_s = list(value), list(value), [0.0, 0.0]
        self._stamp_ns = self._stream_ns = None
        self._intervals.clear()

    def step(self, desired: tuple[float, float], stamp_ns: int, stream_ns: int,
             dt: float) -> tuple[float, float]:
        """The reference after `dt` of the samples' clock, with `desired` the newest command's
        (within caps and limit), stamped `stamp_ns` in a stream begun at `stream_ns`."""
        if stream_ns != self._stream_ns:  # its first step counts from its start
            self._stream_ns, self._stamp_ns = stream_ns, stream_ns
            self._intervals.clear()
        gap, lead = None, 0.0
        if stamp_ns != self._stamp_ns:
            assert self._stamp_ns is not None
            gap = min(max((stamp_ns - self._stamp_ns) * 1e-9, 0.0), self.max_gap_s)
            lead = (statistics.median(self._intervals) if self._intervals
                    else self.default_period_s)
            if self._stamp_ns != stream_ns:
                self._intervals.append(gap)
            self._stamp_ns = stamp_ns
        for i in (0, 1):
            self.value[i] = self._axis(i, desired[i], gap, lead, dt)
        return self.value[0], self.value[1]

    def _axis(self, i: int, r: float, gap: float | None, lead: float, dt: float) -> float:
        x, lag = self.value[i], self._lag_s[i]
        adv = dt
        if gap is not None:
            if lag <= 0.0:  # caught up: a step within the lead at once, as it comes
                adv = max(dt, min(gap, lead))
            if r != self._end[i]:  # (a flat stretch of the stream is no lag to keep)
                lag += gap
        self._end[i] = r
        if x * r < 0.0:
            x = 0.0  # the way to zero is free; the growth beyond it is not
        if abs(r) <= abs(x) or lag <= adv:  # slowing (never held back), or caught up
            self._lag_s[i] = 0.0
            return r
        self._lag_s[i] = lag - adv
        return x + (r - x) * adv / lag


@dataclass(frozen=True)
class PidOutput:
    v_effort: float
    omega_effort: float
    longitudinal_v: float
    angular_v: float
    active: bool
    desired: tuple[float, float] = (0.0, 0.0)  # within caps and limit ((0, 0) when stopped)
    saturated: bool = False  # an effort at the joystick window's edge
    probe: str = ""  # "" or "<kind> <axis> <state>" while a tuning probe runs
    # Of each effort, the model's feed-forward (0 for an axis without a model): the rest is the
    # feedback's correction.
    feedforward: tuple[float, float] = (0.0, 0.0)


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
    # Its stream "began" after its own stamp: no sender's act comes after its command (a clock
    # stepped back mid-stream, a bug), and such a start would outlive every stop (H49).
    STREAM_AHEAD = "stream_ahead"
    SUPERSEDED = "superseded"  # a stream begun later drives: two sources are never mixed (H37)
    TOOK_OVER = "took_over"  # obeyed: a stream begun later than the one obeyed replaces it


def same_arc(v: float, omega: float, lv: float, lw: float) -> tuple[float, float]:
    """(v, ω) bounded to (lv, lw) axis by axis, as the velocity on v's own arc: a moving
    command limited on either axis is slowed on both by the same factor, so the chair keeps
    the arc it was sent on (the one the planner checked and the monitor sweeps), only slower.
    Clamped alone, ω straightened a planned turn into the wall it was avoiding, and v alone
    tightened it (H64). Not moving (lv 0: a turn in place, or forward blocked), ω keeps its
    own bound."""
    if lv == 0.0:
        return lv, lw
    s = min(lv / v, lw / omega if omega != 0.0 else 1.0)
    return v * s, omega * s


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
    # Identified drive chain per axis (None: feedback only, as the thesis) and the prefilter.
    v_model: ChainModel | None = None
    omega_model: ChainModel | None = None
    prefilter_s: float = 0.1
    d_filter_n: float = 10.0
    # The encoders' period: a parked chair's samples come every 50 ms (the gateway idles the
    # chain), so the sample that starts a drive carries the parked interval as its dt, while
    # its output acts only until the next sample, one period later.
    period_s: float = 1.0 / DRIVE_RATE_HZ
    v_pid: PID = field(init=False)
    omega_pid: PID = field(init=False)
    probe: Probe | None = field(init=False, default=None)  # a tuning probe (autochair tune)
    _ff: tuple[Feedforward | None, Feedforward | None] = field(init=False)
    _last_effort: tuple[float, float] = (0.0, 0.0)  # low-passed
    _sent: list[float] = field(default_factory=lambda: [0.0, 0.0])  # last feed-forward
    _held: tuple[float, float] = (0.0, 0.0)  # the last desired driven (within caps, limit)
    stop_ns: int = field(init=False)  # commands must have begun after this (Unix ns)
    stop_reason: str = field(init=False)
    _desired: tuple[float, float] = (0.0, 0.0)
    _desired_t: float = -math.inf  # -inf: obeying nothing
    _desired_ns: int = 0  # its stamp (the sender's clock)
    _ref: GapFill = field(default_factory=GapFill)  # what the loops follow (see GapFill)
    _active: bool = False
    # fwd, rev (> 0), |ω|, rev for autonomy (> 0) bounds
    _limit: tuple[float, float, float, float] | None = None
    _limit_t: float = -math.inf
    _estop_latched: bool = False
    _estop_t: float = -math.inf
    _last_update_t: float | None = None
    _link: tuple[int, int] | None = None
    _stream_ns: int = 0  # the start of the newest stream obeyed
    # How old the newest command was when a loop step first followed it (its sender's stamp to
    # that step, s): its way here and the wait for a sample, a delay the sender's model of the
    # chain does not hold (ControlCore.on_command_age).
    command_age_s: float = 0.0
    _aged_ns: int = 0  # the stamp of the command command_age_s is of

    def __post_init__(self) -> None:
        lo = (self.min_v - NEUTRAL_V) / VOLTS_PER_EFFORT
        hi = (self.max_v - NEUTRAL_V) / VOLTS_PER_EFFORT
        self.v_pid = PID(*self.v_gains, out_min=lo, out_max=hi, d_filter_n=self.d_filter_n)
        self.omega_pid = PID(*self.omega_gains, out_min=lo, out_max=hi,
                             d_filter_n=self.d_filter_n)
        self._ff = tuple(None if m is None else Feedforward(m, self.prefilter_s)
                         for m in (self.v_model, self.omega_model))  # type: ignore[assignment]
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
        if cmd.stream_start_ns > cmd.stamp_ns:
            return Verdict.STREAM_AHEAD
        if cmd.stream_start_ns <= self.stop_ns:
            return Verdict.BEFORE_STOP
        # One stream at a time (H37): two sources on one key (a goal and `autochair drive`,
        # two teleop laptops) would otherwise interleave into a command neither asked for.
        # The latest deliberate act drives; an older stream never again.
        if cmd.stream_start_ns < self._stream_ns:
            return Verdict.SUPERSEDED
        took_over = self.obeying and cmd.stream_start_ns > self._stream_ns
        self._stream_ns = cmd.stream_start_ns
        self._desired, self._desired_t = (cmd.v, cmd.omega), now_s
        self._desired_ns = cmd.stamp_ns
        return Verdict.TOOK_OVER if took_over else Verdict.OK

    def stop(self, reason: str, now_ns: int) -> bool:
        """A stop nobody asked for: obey nothing begun before `now_ns`. True if it ended
        obeying a stream (the node says so once)."""
        was = self.obeying
        # Also past the stream it knew, whatever the sender's clock: one up to the skew ahead
        # would otherwise make a stream begun just before the stop pass for one begun after it.
        self.stop_ns = max(self.stop_ns, now_ns, self._stream_ns)
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
                  v_rev_autonomy: float = 0.0, age_s: float = 0.0) -> bool:
        """A limit from the safety monitor; `age_s` by its own stamp: one delivered late (a
        backlog) is not fresh however recently it arrived (H38)."""
        if not all(math.isfinite(x) and x >= 0 for x in (v_fwd, v_rev, omega, v_rev_autonomy)):
            return False
        if not -self.skew_s <= age_s <= self.limit_stale_s:
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
                and says_stop(self._limit[0], self._limit[2]):
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
            # Stopped as of the stream's last command (its sender's stamp), not of now: a
            # stream begun after that is a new act (a goal sent as the last one's stream ended)
            # whose first command may come just after this; stopped as of now, it was refused
            # for ever and the goal aborted "does not follow" (bench control_stack, session 21).
            self.stop("command stream stale", self._desired_ns)
            return None
        v0, omega0 = self._desired
        c = self.caps
        v, omega = min(max(v0, -c.v_rev_mps), c.v_fwd_mps), min(max(omega0, -c.omega_radps),
                                                                 c.omega_radps)
        limit = self._limit if now_s - self._limit_t <= self.limit_stale_s else None
        if limit is None:
            if not self.require_limit:
                return same_arc(v0, omega0, v, omega)
            limit, why = (0.0, 0.0, 0.0, 0.0), "no fresh safety limit"
        else:
            why = SAFETY_STOP
        fwd, rev, w, rev_auto = limit
        rev = rev if self.owner == "teleop" else rev_auto  # unattended: only what is sensed
        lv, lw = same_arc(v0, omega0, min(max(v, -rev), fwd), min(max(omega, -w), w))
        # Stopped by the limit: brake by neutral, never reverse. Left only a creep of turn
        # (≤ stop_eps: the chair stands) is stopped too, else the old stream drove on by
        # itself once the limit re-opened (H03). Judged on the arc kept: an arc whose turn is
        # bounded to 0 is slowed to 0 on both axes, a stop like any other.
        if lv == 0.0 and abs(lw) <= self.stop_eps and (abs(v) > 1e-3 or abs(omega - lw) > 1e-3):
            self.stop(why, now_ns)
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
        # Freshness is judged as of the next sample (one dt ahead): a stream or heartbeat that
        # would be stale by then is stale now, so each timeout holds whatever the sample rate.
        ahead = now_s + dt if 0 < dt <= 1.0 else now_s
        if self.require_estop and ahead - self._estop_t > self.estop_stale_s:
            self.stop("e-stop silent", now_ns)
        elif self._estop_latched:
            self.stop("e-stop latched", now_ns)
        if not (math.isfinite(v_meas) and math.isfinite(omega_meas)):
            # A bad measurement must not poison the integrators: a stop, nothing learned.
            self.stop("non-finite measurement", now_ns)
            v_meas = omega_meas = 0.0
        desired = self.desired(ahead, now_ns)
        if desired is not None and self._desired_ns != self._aged_ns:
            self._aged_ns = self._desired_ns
            self.command_age_s = max((now_ns - self._desired_ns) / 1e9, 0.0)
        at_rest = desired is not None and desired == (0.0, 0.0) and \
            abs(v_meas) < self.stop_eps and abs(omega_meas) < self.stop_eps
        # (a first sample has dt 0; a non-finite or absurd dt is skipped the same way)
        if desired is None or at_rest or not 0 < dt <= 1.0:
            if self.probe is not None and desired is None:
                self.probe.end(ProbeState.ABORTED, f"stopped ({self.stop_reason})")
            # Stopped or parked: exact neutral, integrators cleared for a bumpless restart.
            self._active = False
            self._restart(v_meas, omega_meas)
            if desired is None:
                self._ref.forget((v_meas, omega_meas))
            else:  # (parked: the stream's next step counts from this command)
                self._ref.step(desired, self._desired_ns, self._stream_ns,
                               dt if 0 < dt <= 1.0 else 0.0)
            return PidOutput(0.0, 0.0, NEUTRAL_V, NEUTRAL_V, False, desired or (0.0, 0.0),
                             probe=self._probe_text())
        if not self._active:
            self._active = True  # re-seeded from the measured velocity: nothing lunges
            self._restart(v_meas, omega_meas)
            # The feed-forward advances over the dt its output will act for: a parked
            # interval's dt (50 ms) here advanced the prefilter 5 steps in one, and the 0.5
            # step through the processes settled in 1.6-1.8 s instead of 1.16 s (measured).
            dt = min(dt, self.period_s)
        meas = (v_meas, omega_meas)
        self._held = desired
        ref = self._ref.step(desired, self._desired_ns, self._stream_ns, dt)
        efforts = [self._axis(i, ref[i], meas[i], dt) for i in (0, 1)]
        if self.probe is not None and self.probe.state is ProbeState.RUNNING \
                and not self._probe_step(efforts, meas, now_s, now_ns):
            return PidOutput(0.0, 0.0, NEUTRAL_V, NEUTRAL_V, False, (0.0, 0.0),
                             probe=self._probe_text())
        cv, cw = efforts
        # The effort that holds the operating point (a probe's bias): filtered over ~0.5 s,
        # since the derivative term passes the odometry's quantisation noise.
        a = min(dt / 0.5, 1.0)
        self._last_effort = (self._last_effort[0] + a * (cv - self._last_effort[0]),
                             self._last_effort[1] + a * (cw - self._last_effort[1]))
        lo, hi = self._window
        sat = any(c <= lo + 1e-9 or c >= hi - 1e-9 for c in (cv, cw))
        return PidOutput(cv, cw, effort_to_volts(cv, self.min_v, self.max_v),
                         effort_to_volts(cw, self.min_v, self.max_v), True, desired, sat,
                         self._probe_text(), (self._sent[0], self._sent[1]))

    @property
    def _window(self) -> tuple[float, float]:
        """The effort range of the joystick window."""
        return ((self.min_v - NEUTRAL_V) / VOLTS_PER_EFFORT,
                (self.max_v - NEUTRAL_V) / VOLTS_PER_EFFORT)

    def _probe_step(self, efforts: list[float], meas: tuple[float, float], now_s: float,
                    now_ns: int) -> bool:
        """The running probe replaces its axis's effort; False when it aborted (a stop:
        exact neutral, as any stop)."""
        assert self.probe is not None
        i = 0 if self.probe.axis == "longitudinal" else 1
        u = self.probe.effort(meas[i], now_s)
        if u is not None:
            lo, hi = self._window
            efforts[i] = min(max(u, lo), hi)
        elif self.probe.is_(ProbeState.ABORTED):
            self.stop(f"tuning probe aborted: {self.probe.reason}", now_ns)
            self._active = False
            self._restart(*meas)
            return False
        else:  # done: the loop takes over again, bumpless from the probe's bias
            self._resume(i, meas[i], self.probe.bias)
        return True

    def _axis(self, i: int, r: float, y: float, dt: float) -> float:
        """One loop: feed-forward (if modelled) plus the PID on the model's response to what
        was sent; the PID's window is what the feed-forward leaves (anti-windup on the total)."""
        pid, ff = (self.v_pid, self.omega_pid)[i], self._ff[i]
        lo, hi = self._window
        if ff is None:
            return pid.update(r, y, dt)
        u_ff = ff.effort(r, dt, lo, hi)
        pid.out_min, pid.out_max = lo - u_ff, hi - u_ff
        # The reference is the model's response to the feed-forward alone (advanced by the
        # previous one, which is what acted over the last dt): the feedback's correction must
        # not move its own reference, or it could never remove a steady error.
        ref = ff.reference(self._sent[i], dt)
        self._sent[i] = u_ff
        # Derivative on the error here (the reference is the model's smooth output, so no
        # kick): on the measurement it would brake the very motion the feed-forward makes.
        return u_ff + pid.update(0.0, y - ref, dt)

    def _resume(self, i: int, y: float, effort: float) -> None:
        pid, ff = (self.v_pid, self.omega_pid)[i], self._ff[i]
        if ff is not None:
            ff.reset(y)
            self._sent[i] = ff.model.effort_for(y)
        pid.reset(y if ff is None else 0.0,
                  effort - (0.0 if ff is None else ff.model.effort_for(y)))

    def _restart(self, v_meas: float, omega_meas: float) -> None:
        for i, y in enumerate((v_meas, omega_meas)):
            ff = self._ff[i]
            (self.v_pid, self.omega_pid)[i].reset(y if ff is None else 0.0)  # (see _axis)
            if ff is not None:
                ff.reset(y)
                self._sent[i] = ff.model.effort_for(y)

    # --- tuning probes (autochair tune) -------------------------------------------------------
    def start_probe(self, probe: Probe, now_s: float) -> str:
        """Run an open-loop probe on one axis around where the loop holds the chair now: ''
        or why not. Only while obeying a command and driving (so every gate above still
        applies: a stop of any kind aborts the probe), and only one at a time."""
        why = probe.check()
        if why:
            return why
        if self.probe is not None and self.probe.state is ProbeState.RUNNING:
            return "a probe is already running"
        if not (self.obeying and self._active):
            return "not driving: hold the operating point with a command stream first"
        i = 0 if probe.axis == "longitudinal" else 1
        probe.start(self._held[i], self._last_effort[i], now_s)
        self.probe = probe
        return ""

    def stop_probe(self) -> None:
        if self.probe is not None:
            self.probe.end(ProbeState.ABORTED, "stopped by request")

    def _probe_text(self) -> str:
        p = self.probe
        return "" if p is None or p.state is not ProbeState.RUNNING else \
            f"{p.kind.value} {p.axis}"


Model = tuple[float, float, float, float, float]  # SOPDT: K, u_db, τ1 s, τ2 s, θ s
Gains3 = tuple[Annotated[float, msgspec.Meta(ge=0)], Annotated[float, msgspec.Meta(ge=0)],
               Annotated[float, msgspec.Meta(ge=0)]]


class PidConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """[pid] section. Gains (SIMC) and models (SOPDT) as `autochair tune --lockstep` identifies
    them at 100 Hz: deterministic, and on the real process stack the same probes found the same
    chain within their scatter (θ 0.357–0.370 s against 0.372 s; K, τ within 0.5 %), so the
    Zenoh hops add no dead time worth modelling at this rate. ZN,
    the thesis's table 5.1, is (0.90, 1.03, 0.20) / (0.72, 1.08, 0.12) with no model."""

    # (Kp, Ki 1/s, Kd s)
    v_gains: Gains3 = (0.523, 0.731, 0.094)
    omega_gains: Gains3 = (0.401, 0.832, 0.048)
    # Drive chain per axis (see autochair.tune.core.ChainModel); None = feedback only.
    v_model: Model | None = (1.839, 0.049, 0.358, 0.358, 0.372)
    omega_model: Model | None = (1.888, 0.049, 0.241, 0.241, 0.318)
    prefilter_s: Annotated[float, msgspec.Meta(gt=0, le=2)] = 0.15
    min_v: float = 1.1
    max_v: float = 3.9
    d_filter_n: float = 10.0
    # Drive only within a fresh limit from the safety monitor (stale limit → stop). The process
    # list sets it whenever the stack runs the monitor (processes.stack_values).
    require_safety_limit: bool = True
    # Drive only while the e-stop service says "released" (as the gateway does).
    require_estop: bool = True
    # Absolute caps whatever the source (CLI, teleop, autonomy); tools read them from health.
    v_max_fwd_mps: Annotated[float, msgspec.Meta(gt=0, le=3)] = 1.2
    v_max_rev_mps: Annotated[float, msgspec.Meta(gt=0, le=3)] = 0.5
    omega_max_radps: Annotated[float, msgspec.Meta(gt=0, le=3)] = 1.0

    def models(self) -> tuple[ChainModel | None, ChainModel | None]:
        return tuple(None if m is None else ChainModel(*m)  # type: ignore[return-value]
                     for m in (self.v_model, self.omega_model))


def make_core(cfg: PidConfig, *, stale_s: float = 0.3, skew_s: float = 0.1,
              limit_stale_s: float = 0.5, estop_stale_s: float = 0.5, odom_gap_s: float = 0.3,
              start_ns: int = 0, require_estop: bool | None = None) -> VelocityPidCore:
    """The core as the [pid] section (and the [stale] thresholds) configure it."""
    for m in (cfg.v_model, cfg.omega_model):
        if m is not None and not (m[0] > 0 and all(x >= 0 for x in m[1:])):
            raise ValueError(f"[pid] model {m}: K must be > 0, the rest ≥ 0")
    v_model, omega_model = cfg.models()
    return VelocityPidCore(
        v_gains=cfg.v_gains, omega_gains=cfg.omega_gains, min_v=cfg.min_v, max_v=cfg.max_v,
        stale_s=stale_s, skew_s=skew_s, require_limit=cfg.require_safety_limit,
        limit_stale_s=limit_stale_s,
        require_estop=cfg.require_estop if require_estop is None else require_estop,
        estop_stale_s=estop_stale_s, odom_gap_s=odom_gap_s,
        caps=Caps(cfg.v_max_fwd_mps, cfg.v_max_rev_mps, cfg.omega_max_radps),
        start_ns=start_ns, v_model=v_model, omega_model=omega_model,
        prefilter_s=cfg.prefilter_s, d_filter_n=cfg.d_filter_n)


def probe_reply(probe: Probe | None) -> dict[str, object]:
    """The fields of a PidProbeReply for the probe (its trace once it has ended)."""
    if probe is None:
        return {"ok": True}
    ended = probe.state is not ProbeState.RUNNING
    tr = probe.trace if ended else []
    return {"ok": True, "state": probe.state.value, "reason": probe.reason,
            "setpoint": probe.setpoint, "bias": probe.bias, "t_s": [s[0] for s in tr],
            "measured": [s[1] for s in tr], "effort": [s[2] for s in tr]}


def effort_to_volts(c: float, min_v: float = 1.1, max_v: float = 3.9) -> float:
    return min(max(VOLTS_PER_EFFORT * c + NEUTRAL_V, min_v), max_v)
