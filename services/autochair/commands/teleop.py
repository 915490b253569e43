"""`autochair teleop`: drive the chair from a laptop: gamepad, window keys or terminal keys.

Gamepad (pygame-ce, SDL2's game-controller mapping; Xbox layout): hold LB (enable) and steer
with the left stick; RB is turbo (full teleop speed); B latches the e-stop. Keys: w/s or
arrows forward/back, a/d turn, q/e arcs, space stop, +/- speed, t take over from autonomy,
h hand back, ! latch the e-stop, x or Ctrl-C quit. In the teleop window (a local X/Wayland
session) keys have key-up: the chair stops when you let go. In the terminal there is no key-up:
the deadman tolerates the first auto-repeat delay, then the repeat period (see
autochair.commands.teleop_core). Commands go on keys.TELEOP with source "teleop"; the velocity
PID obeys them only after `t` (keys.CMD_OWNER). Settings: the [teleop] section of --config.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import queue
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING, Any

from autochair.commands.teleop_core import (
    ESTOP_KEY,
    KEYMAP,
    PAD_AXES,
    PAD_BUTTONS,
    STOP_KEY,
    PadConfig,
    Teleop,
    TeleopConfig,
    TeleopLimits,
    keys_request,
)
from autochair_msgs import CommandOwner, EStopAssert, EStopState, PidStatus, VelocityCommand, keys

if TYPE_CHECKING:
    import zenoh

ESCAPES = {"\x1b[A": "up", "\x1b[B": "down", "\x1b[C": "right", "\x1b[D": "left"}
ESTOP_CONFIRM_S = 3.0  # an e-stop press is repeated until the e-stop service shows it


def register(sub: Any) -> None:
    from autochair.commands.link import add_link_args

    p: argparse.ArgumentParser = sub.add_parser(
        "teleop", help="drive by gamepad or keyboard (deadman, speed limits, explicit takeover)",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_link_args(p)
    add_teleop_args(p)
    p.add_argument("--keys", choices=("auto", "window", "terminal"), default="auto",
                   help="key input: a window with key-up (auto: when a display is there) or "
                   "the terminal only (auto-repeat deadman)")
    p.add_argument("--no-pad", action="store_true", help="do not read a gamepad")
    p.add_argument("--take-over", action="store_true", help="take over at start (as `t`)")
    p.add_argument("--hand-back", action="store_true",
                   help="only hand the drive back to autonomy and exit")
    p.set_defaults(func=run)


def add_teleop_args(p: argparse.ArgumentParser) -> None:
    """Teleop settings shared with `autochair foxglove`: [teleop] of the config, then flags."""
    p.add_argument("--config", help="TOML file whose [teleop] section sets limits, deadman, "
                   "ramp and the pad mapping (default $AUTOCHAIR_CONFIG)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a [teleop] setting, e.g. pad.enable_button=a")
    p.add_argument("--max-v", type=float, help="m/s at full speed scale (default 0.6)")
    p.add_argument("--max-omega", type=float, help="rad/s at full speed scale (default 0.8)")
    p.add_argument("--deadman", type=float,
                   help="s tolerated between repeats, samples or panel messages (default 0.2)")
    p.add_argument("--first-repeat", type=float,
                   help="terminal keys: s tolerated for the first auto-repeat (default 0.7)")
    p.add_argument("--rate", type=float, help="command rate, Hz (default 20)")


def teleop_config(args: argparse.Namespace) -> TeleopConfig:
    """[teleop] from the config file with --set, then the explicit flags; validated."""
    from autochair.cli import CliError
    from autochair.runtime.config import ConfigError, load_section

    try:
        cfg = load_section(TeleopConfig, "teleop", args.config, args.set)
    except ConfigError as e:
        raise CliError(str(e)) from None
    for flag, name in (("max_v", "max_v_mps"), ("max_omega", "max_omega_radps"),
                       ("deadman", "deadman_s"), ("first_repeat", "first_repeat_s"),
                       ("rate", "rate_hz")):
        if getattr(args, flag, None) is not None:
            setattr(cfg, name, getattr(args, flag))
    try:
        return cfg.validate()
    except ValueError as e:
        raise CliError(str(e)) from None


def refuse_beyond_pid_caps(session: zenoh.Session, limits: TeleopLimits) -> None:
    """No teleop limit above the live velocity PID's absolute caps (read from its health)."""
    from autochair.cli import CliError
    from autochair.runtime.client import pid_caps

    caps = pid_caps(session)
    if caps is None:
        return  # no PID reports: it applies its caps anyway
    if (limits.max_v_mps > caps[0] or limits.max_v_mps * 0.5 > caps[1]
            or limits.max_omega_radps > caps[2]):
        raise CliError(f"--max-v {limits.max_v_mps:g} (reverse {limits.max_v_mps * 0.5:g}) / "
                       f"--max-omega {limits.max_omega_radps:g} exceed the velocity PID's caps "
                       f"({caps[0]:g} m/s, reverse {caps[1]:g} m/s, {caps[2]:g} rad/s; [pid] "
                       "in the chair's config)")


class TeleopLink:
    """Publishes what the core decides; the link is up while the PID's token is visible."""

    def __init__(self, session: zenoh.Session, core: Teleop, by: str = "teleop") -> None:
        # here, not at import: `autochair --help` stays fast
        from autochair.runtime.client import Publisher, pid_hold, subscribe, watch_alive

        self.session, self.core, self.by = session, core, by
        self._pub = Publisher(session, keys.TELEOP, express=True)
        self._owner_pub = Publisher(session, keys.CMD_OWNER)
        self._estop_pub = Publisher(session, keys.ESTOP_ASSERT, express=True, reliable=True)
        self.owner = False
        self._owner_t = -1e18
        self._pid_alive = False
        self.sent = 0
        self._press, self._stream_start_ns = 0, 0
        self._estops, self._estop_until, self.estop_latched = 0, -1e18, False
        self.estop_source = f"teleop:{by}"
        def on_estop(st: EStopState) -> None:
            self.estop_latched = st.latched and any(
                c.source == self.estop_source for c in st.causes)

        subscribe(session, keys.ESTOP_STATE, on_estop)
        watch_alive(session, self._on_alive, "pid")
        # Why the PID obeys nothing now (any e-stop, the safety monitor, a stop before this
        # press): shown while driving.
        self.pid_hold = ""

        def on_pid(st: PidStatus) -> None:
            self.pid_hold = pid_hold(st.inhibit, st.stamp_ns, self._stream_start_ns)

        subscribe(session, keys.PID_STATUS, on_pid)

    def _on_alive(self, _service: str, alive: bool) -> None:
        self._pid_alive = alive

    @property
    def link_ok(self) -> bool:
        return self._pid_alive

    @property
    def stream_start_ns(self) -> int:
        return self._stream_start_ns

    def set_owner(self, teleop: bool) -> None:
        self.owner = teleop
        self._owner_pub.put(CommandOwner(
            stamp_ns=time.time_ns(), owner="teleop" if teleop else "autonomy", by=self.by))
        self._owner_t = time.monotonic()

    def step(self, now: float) -> tuple[float, float] | None:
        if self.owner and now - self._owner_t >= 1.0:
            self.set_owner(True)  # repeat the claim for late joiners (PID restart)
        if self.core.estop_presses != self._estops:  # a fresh e-stop press
            self._estops, self._estop_until = self.core.estop_presses, now + ESTOP_CONFIRM_S
            self.estop_latched = False
        if now < self._estop_until and not self.estop_latched:
            # A momentary press (active=False: latched, nothing left to clear), repeated until
            # the e-stop service shows it: a lost sample must not leave the chair moving.
            self._estop_pub.put(EStopAssert(
                stamp_ns=time.time_ns(), source=self.estop_source, reason="teleop e-stop button",
                active=False))
        cmd = self.core.tick(now, self.link_ok)
        if self.core.presses != self._press:  # a fresh deadman press begins a new stream
            self._press, self._stream_start_ns = self.core.presses, time.time_ns()
        if cmd is not None:
            self._pub.put(VelocityCommand(
                stamp_ns=time.time_ns(), v_mps=cmd[0], omega_radps=cmd[1], source="teleop",
                stream_start_ns=self._stream_start_ns))
            self.sent += 1
        return cmd

    def handle_key(self, key: str, now: float) -> bool:
        """Apply one terminal key (or a window's command key); False means quit."""
        if key in ("x", "\x03"):
            return False
        if key in KEYMAP:
            self.core.key(key, *KEYMAP[key], now)
        elif key == STOP_KEY:
            self.core.release("terminal")
        elif key == ESTOP_KEY:
            self.core.estop()
        elif key in ("+", "=", "-"):
            self.core.faster(key != "-")
        elif key == "t":
            self.set_owner(True)
        elif key == "h":
            self.set_owner(False)
        return True


Event = str | tuple[str, float]  # a key, or a key and when it was read (monotonic s)


def loop(link: TeleopLink, events: queue.Queue[Event], stop: threading.Event,
         rate_hz: float, status: Any = None,
         samplers: Sequence[Callable[[float], None]] = ()) -> None:
    """Apply queued keys (at the time they were read, when given), sample held inputs (pad,
    window) and publish at `rate_hz` until `stop` or a quit key."""
    period = 1.0 / rate_hz
    next_t = time.monotonic()
    while not stop.is_set():
        now = time.monotonic()
        for sample in samplers:  # the current state, every tick: a steady stick is input too
            sample(now)
        try:
            while True:
                ev = events.get_nowait()
                key, at = ev if isinstance(ev, tuple) else (ev, now)
                if not link.handle_key(key, min(at, now)):
                    stop.set()
        except queue.Empty:
            pass
        cmd = link.step(now)
        if status is not None:
            status(link, cmd)
        next_t += period
        if next_t < time.monotonic() - period:  # fell behind (suspended): do not burst
            next_t = time.monotonic()
        stop.wait(max(0.0, next_t - time.monotonic()))
    link.core.release()  # quitting: one final zero if we were moving
    link.step(time.monotonic())


@contextlib.contextmanager
def raw_tty() -> Iterator[None]:
    import termios
    import tty

    fd = sys.stdin.fileno()
    old = termios.tcgetattr(fd)
    tty.setcbreak(fd)
    try:
        yield
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, old)


def split_keys(data: str) -> list[str]:
    """Terminal input as key names (arrows from their escape sequences)."""
    for esc, name in ESCAPES.items():
        data = data.replace(esc, f"\0{name}\0")
    out: list[str] = []
    for part in data.split("\0"):
        out += [part] if part in ESCAPES.values() else list(part)
    return out


def read_keys(events: queue.Queue[Event], stop: threading.Event) -> None:
    import select

    fd = sys.stdin.fileno()
    while not stop.is_set():
        ready, _, _ = select.select([fd], [], [], 0.1)
        if not ready:
            continue
        data = os.read(fd, 16).decode(errors="replace")
        at = time.monotonic()  # the deadman counts from when the key came, not the next tick
        for key in split_keys(data):
            events.put((key, at))


class SdlInputs:
    """Gamepads and a key window through pygame-ce (SDL2), sampled from their current state.

    pygame-ce, not evdev: SDL2's game-controller database maps hundreds of pads (Xbox,
    PlayStation, Switch, generic) to one Xbox layout on Linux, macOS and Windows laptops alike,
    its wheels bundle SDL2 (no compiler, no kernel headers), it needs no access to
    /dev/input, and the same library gives a window with real key-up events. evdev is Linux
    only, reports each pad's raw axis codes, and reads a keyboard whatever window has the focus.
    """

    def __init__(self, pad: PadConfig | None, window: bool, events: queue.Queue[Event]) -> None:
        os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
        # Read the pad while the terminal (not an SDL window) has the focus.
        os.environ.setdefault("SDL_JOYSTICK_ALLOW_BACKGROUND_EVENTS", "1")
        if not window:  # pygame pumps events only with a display: a dummy one, no window
            os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
        os.environ.setdefault("SDL_VIDEO_X11_WMCLASS", "autochair")  # the window's class
        import pygame
        from pygame._sdl2 import controller

        self.pg, self.ctl, self.cfg, self.events = pygame, controller, pad, events
        pygame.display.init()
        self.window = None
        self._font: Any = None
        if window:
            pygame.display.set_caption("autochair teleop: hold keys here")
            self.window = pygame.display.set_mode((600, 112))
            pygame.font.init()
            self._font = pygame.font.Font(None, 22)
        self.pad: Any = None
        self.pad_name = ""
        if pad is not None:
            controller.init()
            self._axes = {n: getattr(pygame, f"CONTROLLER_AXIS_{_SDL_AXIS.get(n, n).upper()}")
                          for n in PAD_AXES}
            self._buttons = {
                n: getattr(pygame, f"CONTROLLER_BUTTON_{_SDL_BUTTON.get(n, n).upper()}")
                for n in PAD_BUTTONS}
            self._open_pad()
        self._wkeys = {"w": pygame.K_w, "s": pygame.K_s, "a": pygame.K_a, "d": pygame.K_d,
                       "q": pygame.K_q, "e": pygame.K_e, "up": pygame.K_UP,
                       "down": pygame.K_DOWN, "left": pygame.K_LEFT, "right": pygame.K_RIGHT}

    def _open_pad(self) -> None:
        if self.pad is not None and self.pad.attached():
            return
        self.pad, self.pad_name = None, ""
        for i in range(self.ctl.get_count()):
            if self.ctl.is_controller(i):
                self.pad = self.ctl.Controller(i)
                self.pad_name = self.pad.name
                return

    def sample(self, core: Teleop, now: float) -> None:
        pg = self.pg
        for ev in pg.event.get():
            if ev.type in (pg.CONTROLLERDEVICEADDED, pg.CONTROLLERDEVICEREMOVED):
                if self.cfg is not None:
                    self._open_pad()
            elif ev.type == pg.QUIT:
                self.events.put("x")
            elif ev.type == pg.KEYDOWN and ev.unicode and ev.unicode in "thx+=-! ":
                self.events.put(ev.unicode)  # commands; motion keys are sampled below
        if self.cfg is not None:
            self._sample_pad(core, now)
        if self.window is not None:
            pressed = pg.key.get_pressed()
            held = {n for n, k in self._wkeys.items() if pressed[k]}
            req = keys_request(held) if pg.key.get_focused() else None
            core.hold("window", *(req or (0.0, 0.0)), now, req is not None)

    def _sample_pad(self, core: Teleop, now: float) -> None:
        pad = self.pad
        if pad is None or not pad.attached():
            core.pad(self.cfg or PadConfig(), {}, set(), now)  # unplugged: released
            return
        axes = {n: pad.get_axis(a) / 32767.0 for n, a in self._axes.items()}
        pressed = {n for n, b in self._buttons.items() if pad.get_button(b)}
        core.pad(self.cfg or PadConfig(), axes, pressed, now)

    def show(self, text: str) -> None:
        if self.window is None or self._font is None:
            return
        self.window.fill((20, 20, 20))
        parts = text.split(" | ")
        lines = ["Hold keys here: the chair stops when you let go.",
                 *(" | ".join(parts[i:i + 2]) for i in range(0, len(parts), 2))]
        for i, line in enumerate(lines):
            self.window.blit(self._font.render(line, True, (230, 230, 230)), (10, 8 + 24 * i))
        self.pg.display.flip()

    def close(self) -> None:
        self.pg.quit()


# SDL's names that pygame-ce spells differently in its constants
_SDL_AXIS = {"lefttrigger": "triggerleft", "righttrigger": "triggerright"}
_SDL_BUTTON = {"dpup": "dpad_up", "dpdown": "dpad_down", "dpleft": "dpad_left",
               "dpright": "dpad_right"}


def has_display() -> bool:
    return sys.platform in ("darwin", "win32") or bool(
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def open_inputs(args: argparse.Namespace, cfg: TeleopConfig,
                events: queue.Queue[Event]) -> tuple[SdlInputs | None, str]:
    """The SDL inputs wanted (pad, window), or None and why not."""
    want_window = args.keys == "window" or (args.keys == "auto" and has_display())
    if args.no_pad and not want_window:
        return None, "pad off"
    os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    try:
        import pygame  # noqa: F401
    except ImportError:
        return None, "no pad or key window: pygame-ce missing (pip install 'autochair[remote]')"
    try:
        return SdlInputs(None if args.no_pad else cfg.pad, want_window, events), ""
    except Exception as e:  # pygame.error: no display, no SDL video driver
        if not want_window:
            return None, f"no pad: {e}"
        try:
            return SdlInputs(None if args.no_pad else cfg.pad, False, events), \
                f"no key window ({e})"
        except Exception as e2:
            return None, f"no pad or key window: {e2}"


def key_mode(inputs: SdlInputs | None) -> str:
    return "window" if inputs is not None and inputs.window is not None else "terminal"


def mode_lines(inputs: SdlInputs | None, cfg: TeleopConfig) -> list[str]:
    """What the person needs to know once: which key mode is in use, and the pad's buttons."""
    p = cfg.pad
    term = (f"the terminal has no key-up: a held key drives on (its first auto-repeat is "
            f"awaited {cfg.first_repeat_s:g} s) and stops {cfg.deadman_s:g} s after its last "
            "repeat")
    lines = ["keys: w/s/a/d or arrows, q/e arcs, space stop, +/- speed, t take over, "
             "h hand back, ! e-stop, x quit"]
    if key_mode(inputs) == "window":
        lines.append("key mode WINDOW: hold keys in the 'autochair teleop' window (key-up: "
                     f"stops when you let go); in this terminal, {term}")
    else:
        lines.append(f"key mode TERMINAL: {term}")
    if inputs is not None and inputs.cfg is not None:
        lines.append(f"pad: hold {p.enable_button} to drive ({p.axis_v}/{p.axis_omega}), "
                     f"{p.turbo_button} turbo, {p.estop_button} e-stop")
    return lines


def status_text(link: TeleopLink, core: Teleop, inputs: SdlInputs | None,
                cmd: tuple[float, float] | None) -> str:
    """One short status line: who owns, link, command, state, key mode and pad."""
    v, w = cmd or (0.0, 0.0)
    pad = "off" if inputs is None or inputs.cfg is None else (
        inputs.pad_name if inputs.pad is not None else "none found")
    state = (f"driving ({core.driving_source})" if core.driving_source else
             "LET GO of every input to drive again" if core.waiting_for_release else "idle")
    if link.estop_latched:
        state += ", E-STOP LATCHED"
    elif core.driving_source and link.pid_hold:
        state += f", HELD BY THE PID: {link.pid_hold}"
    return (f"{'TELEOP OWNS' if link.owner else 'autonomy owns (t: take over)'} | link "
            f"{'ok' if link.link_ok else 'LOST'} | v {v:+.2f} w {w:+.2f} x{core.scale:.1f} | "
            f"{state} | keys: {key_mode(inputs)} | pad: {pad}")


def run(args: argparse.Namespace) -> int:
    import getpass
    import socket

    from autochair.cli import CliError
    from autochair.commands.link import tool_session

    cfg = teleop_config(args)
    session = tool_session(args)
    try:
        if not args.hand_back:
            refuse_beyond_pid_caps(session, cfg.limits())
        core = Teleop(cfg.limits())
        link = TeleopLink(session, core, by=f"{getpass.getuser()}@{socket.gethostname()}")
        if args.hand_back:
            link.set_owner(False)
            print("drive handed back to autonomy")
            return 0
        if not sys.stdin.isatty():
            raise CliError("teleop needs a terminal (keyboard) on standard input")
        if args.take_over:
            link.set_owner(True)
        events: queue.Queue[Event] = queue.Queue()
        stop = threading.Event()
        inputs, why = open_inputs(args, cfg, events)
        if why:
            print(why)
        print("\n".join(mode_lines(inputs, cfg)))
        samplers = [] if inputs is None else [lambda now: inputs.sample(core, now)]

        def status(lk: TeleopLink, cmd: tuple[float, float] | None) -> None:
            import shutil

            text = status_text(lk, core, inputs, cmd)
            width = shutil.get_terminal_size().columns - 1  # one line: \r rewrites it
            sys.stdout.write("\r\x1b[2K" + text[:width])
            sys.stdout.flush()
            if inputs is not None:
                inputs.show(text)

        try:
            with raw_tty():
                reader = threading.Thread(target=read_keys, args=(events, stop), daemon=True)
                reader.start()
                try:
                    loop(link, events, stop, cfg.rate_hz, status, samplers)
                finally:
                    stop.set()
        finally:
            if inputs is not None:
                inputs.close()
        print("\nstopped" + ("; teleop still owns the drive: `autochair teleop --hand-back`"
                             if link.owner else ""))
        return 0
    finally:
        session.close()
