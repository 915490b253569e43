"""Teleop logic (pure: no Zenoh, no tty, no clock; times passed in, monotonic seconds).

Every input is a SOURCE that is either held (live) or not; the chair moves only while one is:

- Terminal keys (`key`): a terminal gives no key-up, only the OS auto-repeat of a held key. A
  press is live for `first_repeat_s` (0.7 s: longer than the usual 500–660 ms first-repeat
  delay), then, once it repeats, for `deadman_s` after each repeat. A held key drives
  continuously; a released one stops within `deadman_s` + one tick of its last repeat.
- Held state (`hold`): a gamepad's enable button or a window's keys, sampled at the command rate
  from their current state (not from change events). Live while the enable is held; a sample
  with it released stops the chair at that tick (within one sample period).
- Message streams (`message`): Foxglove's Teleop panel publishes at a fixed rate while its
  button is held and nothing on release. A stream becomes live on its second message within
  `deadman_s` (so a panel set to 1 Hz never lurches) and stops `deadman_s` after its last one.

DEADMAN: when no source is live or the link to the chair is lost, `tick` yields ONE zero
command and then nothing, so the chair's own stale-command timeout also holds it still.
After a stop the person did not make (link lost, e-stop pressed), or a press made while the
link is down, nothing drives until every input has been let go: a press held through the
stop (or the outage) is not a new deliberate act.
Each time the core goes from silent to sending, `presses` counts one: the link gives that
command stream a new `stream_start_ns` (the velocity PID obeys, after any stop, only streams
begun after it). A held input is one stream; a new press is a new stream.

RAMP: the command is slew-limited per tick (`accel_*` while speeding up, the faster `decel_*`
while slowing down), starting from zero on every press, so a press or a key change never
steps the velocity. A stop (release, link lost, e-stop) is NOT ramped: it is one zero at once,
and the PID and the chair's controller brake.

Speed limits: requests are fractions of `max_v_mps` (reverse half of it) and
`max_omega_radps`, times the source's scale (keyboard: `scale`, +/-; pad: its scale or turbo).
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field

import msgspec

# SDL2 game-controller names (SDL_GameControllerGetStringForAxis / ForButton): every pad SDL
# knows is mapped to this Xbox layout (a = bottom face button, b = right, ...).
PAD_AXES = ("leftx", "lefty", "rightx", "righty", "lefttrigger", "righttrigger")
PAD_BUTTONS = ("a", "b", "x", "y", "back", "guide", "start", "leftstick", "rightstick",
               "leftshoulder", "rightshoulder", "dpup", "dpdown", "dpleft", "dpright")


class PadConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """[teleop.pad]: the gamepad (SDL2 game-controller names, Xbox layout by default)."""

    axis_v: str = "lefty"  # left stick up/down drives
    axis_omega: str = "leftx"  # left stick left/right turns
    invert_v: bool = True  # SDL: stick up is negative; up must drive forward
    invert_omega: bool = True  # stick left (negative) turns left (ω > 0)
    dead_zone: float = 0.15  # fraction of full deflection read as rest (rescaled: no step)
    enable_button: str = "leftshoulder"  # LB: held for any motion (deadman)
    turbo_button: str = "rightshoulder"  # RB: `turbo_scale` instead of `scale` while held
    estop_button: str = "b"  # B (red): latches the e-stop
    scale: float = 0.5  # fraction of the teleop caps without turbo
    turbo_scale: float = 1.0  # with turbo (never above the caps: at most 1)


class TeleopConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """[teleop] section of the laptop's config file (`--config`, $AUTOCHAIR_CONFIG)."""

    max_v_mps: float = 0.6  # forward at full scale; reverse is half (chairs reverse slowly)
    max_omega_radps: float = 0.8
    deadman_s: float = 0.2  # gap tolerated between repeats, messages or samples
    first_repeat_s: float = 0.7  # terminal keys: wait tolerated for the first auto-repeat
    accel_mps2: float = 0.6  # ramp while speeding up (the control law's a_max·chain_margin)
    decel_mps2: float = 1.2  # ramp while slowing down with the input still held
    omega_accel_radps2: float = 1.6
    omega_decel_radps2: float = 3.2
    rate_hz: float = 20.0  # command (and pad sampling) rate
    pad: PadConfig = msgspec.field(default_factory=PadConfig)

    def validate(self) -> TeleopConfig:
        """Raises ValueError with a one-line message naming the field."""
        for name in ("max_v_mps", "max_omega_radps", "deadman_s", "first_repeat_s",
                     "accel_mps2", "decel_mps2", "omega_accel_radps2", "omega_decel_radps2",
                     "rate_hz"):
            if not getattr(self, name) > 0:  # also refuses NaN
                raise ValueError(f"[teleop] {name} must be > 0")
        if 1.0 / self.rate_hz >= self.deadman_s:
            raise ValueError("[teleop] rate_hz must tick more than once per deadman_s")
        p = self.pad
        for name in ("axis_v", "axis_omega"):
            if getattr(p, name) not in PAD_AXES:
                raise ValueError(f"[teleop.pad] {name} must be one of {', '.join(PAD_AXES)}")
        for name in ("enable_button", "turbo_button", "estop_button"):
            if getattr(p, name) not in PAD_BUTTONS:
                raise ValueError(f"[teleop.pad] {name} must be one of {', '.join(PAD_BUTTONS)}")
        if len({p.enable_button, p.turbo_button, p.estop_button}) != 3:
            raise ValueError("[teleop.pad] enable, turbo and e-stop need three different buttons")
        if not 0 <= p.dead_zone < 1:
            raise ValueError("[teleop.pad] dead_zone must be within [0, 1)")
        if not (0 < p.scale <= 1 and 0 < p.turbo_scale <= 1):
            raise ValueError("[teleop.pad] scale and turbo_scale must be within (0, 1]")
        return self

    def limits(self) -> TeleopLimits:
        return TeleopLimits(self.max_v_mps, self.max_omega_radps, self.deadman_s,
                            self.first_repeat_s, self.accel_mps2, self.decel_mps2,
                            self.omega_accel_radps2, self.omega_decel_radps2)


@dataclass
class TeleopLimits:
    max_v_mps: float = 0.6  # forward; reverse is half of it (chairs reverse slowly)
    max_omega_radps: float = 0.8
    deadman_s: float = 0.2  # > auto-repeat period (≤ 90 ms); + a 50 ms tick: a stop ≤ 0.25 s
    first_repeat_s: float = 0.7  # > the OS first-repeat delay (500–660 ms by default)
    accel_mps2: float = 0.6  # math.inf: no ramp
    decel_mps2: float = 1.2
    omega_accel_radps2: float = 1.6
    omega_decel_radps2: float = 3.2
    max_dt_s: float = 0.1  # a late tick does not allow a bigger step than this


# keyboard: (v, ω) unit requests; arrows arrive as escape sequences mapped by the reader
KEYMAP: dict[str, tuple[float, float]] = {
    "w": (1.0, 0.0), "s": (-1.0, 0.0), "a": (0.0, 1.0), "d": (0.0, -1.0),
    "q": (1.0, 1.0), "e": (1.0, -1.0), "up": (1.0, 0.0), "down": (-1.0, 0.0),
    "left": (0.0, 1.0), "right": (0.0, -1.0),
}
STOP_KEY = " "  # space: stop now (the terminal's only "key-up")
ESTOP_KEY = "!"  # latch the e-stop (a momentary press, as `autochair estop`)


def keys_request(held: set[str]) -> tuple[float, float] | None:
    """The motion of several keys held at once (a window reports them all): w+a arcs left.
    None when no motion key is held."""
    motions = [KEYMAP[k] for k in held if k in KEYMAP]
    if not motions:
        return None
    return (_clamp(sum(m[0] for m in motions)), _clamp(sum(m[1] for m in motions)))


def stick(value: float, dead_zone: float, invert: bool = False) -> float:
    """A stick axis in [-1, 1] with a dead zone rescaled so the output is continuous (0 at the
    edge of the zone, ±1 at full deflection): no step where the stick leaves the zone."""
    x = -value if invert else value
    mag = abs(x)
    if not mag > dead_zone:  # also NaN
        return 0.0
    return math.copysign(min(1.0, (mag - dead_zone) / (1.0 - dead_zone)), x)


def _clamp(x: float) -> float:
    return max(-1.0, min(1.0, x)) if math.isfinite(x) else 0.0


def slew(cur: float, target: float, up: float, down: float, dt: float) -> float:
    """One ramp step from `cur` toward `target`: at most `up`·dt while |speed| grows, at most
    `down`·dt while it falls; a reversal slows to zero, then speeds up for the rest of dt."""
    if cur == 0.0 or ((cur > 0) == (target > 0) and abs(target) >= abs(cur)):
        return _toward(cur, target, up, dt)
    if target == 0.0 or (cur > 0) == (target > 0):
        return _toward(cur, target, down, dt)
    to_zero = abs(cur) / down if math.isfinite(down) else 0.0
    if to_zero >= dt:
        return _toward(cur, 0.0, down, dt)
    return _toward(0.0, target, up, dt - to_zero)


def _toward(cur: float, goal: float, rate: float, dt: float) -> float:
    if not math.isfinite(rate):
        return goal
    step = rate * dt
    return cur + max(-step, min(step, goal - cur))


@dataclass
class _Source:
    want: tuple[float, float]  # unit request
    live_until: float  # -inf: not (yet) live
    last_t: float  # when its last input came
    scale: float | None  # None: the keyboard's `scale`
    key: str | None = None  # terminal: the key whose repeats are awaited


@dataclass
class Teleop:
    limits: TeleopLimits = field(default_factory=TeleopLimits)
    scale: float = 0.5  # keyboard: fraction of the limits; +/- change it
    deadman_stops: int = 0  # stops by release (or a lapsed deadman)
    link_stops: int = 0  # stops because the link to the chair was lost
    presses: int = 0  # deadman presses: each begins a new command stream (a deliberate act)
    estop_presses: int = 0  # e-stop presses the link must publish (and count down)
    driving_source: str = ""  # the source of the last command sent ("" when silent)
    _sources: dict[str, _Source] = field(default_factory=dict)
    _sending: bool = False
    _out: tuple[float, float] = (0.0, 0.0)  # the ramped command
    _last_tick: float | None = None
    _need_release: bool = False
    _pad_estop: bool = False

    # --- inputs -----------------------------------------------------------------------------
    def key(self, key: str, v_unit: float, omega_unit: float, now: float,
            source: str = "terminal") -> None:
        """A key event without key-up (a terminal): the first one of a press, or a repeat."""
        s = self._sources.get(source)
        repeat = s is not None and s.key == key and s.live_until > now
        window = self.limits.deadman_s if repeat else self.limits.first_repeat_s
        self._sources[source] = _Source((_clamp(v_unit), _clamp(omega_unit)), now + window,
                                        now, None, key)

    def request(self, v_unit: float, omega_unit: float, now: float) -> None:
        """A terminal key event named by its motion (the same motion is the same key)."""
        self.key(f"{v_unit:g},{omega_unit:g}", v_unit, omega_unit, now)

    def hold(self, source: str, v_unit: float, omega_unit: float, now: float, enabled: bool,
             scale: float | None = None) -> None:
        """A sample of held state (a pad's enable button, a window's keys): live while
        `enabled`; a sample with it released stops the chair at the next tick."""
        if not enabled:
            self._sources.pop(source, None)
            return
        self._sources[source] = _Source((_clamp(v_unit), _clamp(omega_unit)),
                                        now + self.limits.deadman_s, now, scale)

    def message(self, source: str, v_unit: float, omega_unit: float, now: float,
                scale: float | None = 1.0) -> None:
        """One message of a stream published at a fixed rate while held (Foxglove's Teleop
        panel): live from its second message within `deadman_s`."""
        s = self._sources.get(source)
        want = (_clamp(v_unit), _clamp(omega_unit))
        if s is not None and now - s.last_t <= self.limits.deadman_s:
            s.want, s.live_until, s.last_t, s.scale = want, now + self.limits.deadman_s, now, scale
        else:
            self._sources[source] = _Source(want, -math.inf, now, scale)

    def pad(self, cfg: PadConfig, axes: Mapping[str, float], pressed: Collection[str],
            now: float, source: str = "pad") -> None:
        """A sample of a gamepad's current state: axes in [-1, 1] and the buttons held, by
        SDL game-controller name. The e-stop button acts when it goes down."""
        estop = cfg.estop_button in pressed
        if estop and not self._pad_estop:
            self.estop()
        self._pad_estop = estop
        v = stick(axes.get(cfg.axis_v, 0.0), cfg.dead_zone, cfg.invert_v)
        w = stick(axes.get(cfg.axis_omega, 0.0), cfg.dead_zone, cfg.invert_omega)
        scale = cfg.turbo_scale if cfg.turbo_button in pressed else cfg.scale
        self.hold(source, v, w, now, cfg.enable_button in pressed, scale)

    def release(self, source: str | None = None) -> None:
        """Key-up (or space, or quitting): stop now. None releases every source."""
        if source is None:
            self._sources.clear()
        else:
            self._sources.pop(source, None)

    def estop(self) -> None:
        """The e-stop button: stop now, and nothing drives until every input is let go."""
        self.estop_presses += 1
        self._need_release = True

    def faster(self, up: bool) -> None:
        self.scale = min(1.0, max(0.1, round(self.scale + (0.1 if up else -0.1), 2)))

    # --- state ------------------------------------------------------------------------------
    def live(self, now: float) -> list[str]:
        """The sources held now."""
        return [n for n, s in self._sources.items() if s.live_until > now]

    @property
    def waiting_for_release(self) -> bool:
        return self._need_release

    def target(self, source: str) -> tuple[float, float]:
        """The (unramped) command a source asks for, in m/s and rad/s."""
        s = self._sources[source]
        v, w = s.want
        scale = self.scale if s.scale is None else s.scale
        vmax = self.limits.max_v_mps * (1.0 if v >= 0 else 0.5)
        return v * vmax * scale, w * self.limits.max_omega_radps * scale

    def command(self) -> tuple[float, float]:
        """The last command sent (ramped)."""
        return self._out

    def tick(self, now: float, link_ok: bool) -> tuple[float, float] | None:
        """The command to publish now, or None to publish nothing."""
        dt = 0.0 if self._last_tick is None else min(max(0.0, now - self._last_tick),
                                                     self.limits.max_dt_s)
        self._last_tick = now
        live = self.live(now)
        if self._need_release and not live:
            self._need_release = False  # everything let go: the next press may drive
        if live and not link_ok:
            self._need_release = True  # held through a lost link: not a new act when it returns
        if link_ok and live and not self._need_release:
            src = max(live, key=lambda n: self._sources[n].last_t)  # the latest input leads
            if not self._sending:
                self.presses += 1
                self._sending, self._out = True, (0.0, 0.0)
            tv, tw = self.target(src)
            lim = self.limits
            self._out = (slew(self._out[0], tv, lim.accel_mps2, lim.decel_mps2, dt),
                         slew(self._out[1], tw, lim.omega_accel_radps2, lim.omega_decel_radps2,
                              dt))
            self.driving_source = src
            return self._out
        if self._sending:  # released, link lost or e-stop: one explicit zero, then silence
            self._sending, self._out, self.driving_source = False, (0.0, 0.0), ""
            if not link_ok:
                self.link_stops += 1
            else:
                self.deadman_stops += 1
            return (0.0, 0.0)
        return None


def twist_units(v_mps: float, omega_radps: float, limits: TeleopLimits) -> tuple[float, float]:
    """A Twist in m/s and rad/s (Foxglove's Teleop panel) as fractions of the limits (scale
    1): clamped to them, reverse to half the forward limit."""
    vmax = limits.max_v_mps * (1.0 if v_mps >= 0 else 0.5)
    return _clamp(v_mps / vmax), _clamp(omega_radps / limits.max_omega_radps)


def parse_twist(data: bytes) -> tuple[float, float] | None:
    """(linear.x, angular.z) of a geometry_msgs/Twist-like JSON message, or None if it is not
    one (or not finite)."""
    try:
        msg = msgspec.json.decode(data)
        v, w = msg["linear"]["x"], msg["angular"]["z"]
    except (msgspec.DecodeError, KeyError, TypeError):
        return None
    if not all(isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)
               for x in (v, w)):
        return None
    return float(v), float(w)
