"""`autochair teleop`: drive the chair from a laptop keyboard (or a gamepad, if `inputs` finds one).

Keys: w/s or arrows forward/back, a/d turn, q/e arcs, space stop, +/- speed, t take over from
autonomy, h hand back, x or Ctrl-C quit. Commands go on keys.TELEOP with source "teleop"; the
velocity PID obeys them only after `t` (keys.CMD_OWNER). Deadman: see autochair.teleop.
"""

from __future__ import annotations

import argparse
import contextlib
import queue
import sys
import threading
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

from autochair.teleop import KEYMAP, Teleop, TeleopLimits
from autochair_msgs import CommandOwner, VelocityCommand, keys

if TYPE_CHECKING:
    import zenoh

ESCAPES = {"\x1b[A": "up", "\x1b[B": "down", "\x1b[C": "right", "\x1b[D": "left"}


def register(sub: Any) -> None:
    from autochair.remote import add_link_args

    p: argparse.ArgumentParser = sub.add_parser(
        "teleop", help="drive by keyboard or gamepad (deadman, speed limits, explicit takeover)",
        description=__doc__)
    add_link_args(p)
    d = TeleopLimits()
    p.add_argument("--max-v", type=float, default=d.max_v_mps, help="m/s at full speed scale")
    p.add_argument("--max-omega", type=float, default=d.max_omega_radps, help="rad/s")
    p.add_argument("--deadman", type=float, default=d.deadman_s,
                   help="s without input before stopping")
    p.add_argument("--rate", type=float, default=20.0, help="command rate, Hz")
    p.add_argument("--take-over", action="store_true", help="take over at start (as `t`)")
    p.add_argument("--hand-back", action="store_true",
                   help="only hand the drive back to autonomy and exit")
    p.set_defaults(func=run)


class TeleopLink:
    """Publishes what the core decides; the link is up while the PID's token is visible."""

    def __init__(self, session: zenoh.Session, core: Teleop, by: str = "teleop") -> None:
        import zenoh  # here, not at import: `autochair --help` stays fast

        self._put_kind = zenoh.SampleKind.PUT
        self.session, self.core, self.by = session, core, by
        self._pub = session.declare_publisher(keys.TELEOP.key, express=True)
        self._owner_pub = session.declare_publisher(keys.CMD_OWNER.key)
        self.owner = False
        self._owner_t = -1e18
        self._pid_alive = False
        self.sent = 0
        self._press, self._stream_start_ns = 0, 0
        session.liveliness().declare_subscriber(f"{keys.PREFIX}/alive/pid", self._on_alive,
                                                history=True)

    def _on_alive(self, sample: zenoh.Sample) -> None:
        self._pid_alive = sample.kind == self._put_kind

    @property
    def link_ok(self) -> bool:
        return self._pid_alive

    def set_owner(self, teleop: bool) -> None:
        self.owner = teleop
        self._owner_pub.put(msgspec_encode(CommandOwner(
            stamp_ns=time.time_ns(), owner="teleop" if teleop else "autonomy", by=self.by)))
        self._owner_t = time.monotonic()

    def step(self, now: float) -> tuple[float, float] | None:
        if self.owner and now - self._owner_t >= 1.0:
            self.set_owner(True)  # repeat the claim for late joiners (PID restart)
        cmd = self.core.tick(now, self.link_ok)
        if self.core.presses != self._press:  # a fresh deadman press begins a new stream
            self._press, self._stream_start_ns = self.core.presses, time.time_ns()
        if cmd is not None:
            self._pub.put(msgspec_encode(VelocityCommand(
                stamp_ns=time.time_ns(), v_mps=cmd[0], omega_radps=cmd[1], source="teleop",
                stream_start_ns=self._stream_start_ns)))
            self.sent += 1
        return cmd

    def handle_key(self, key: str, now: float) -> bool:
        """Apply one key; False means quit."""
        if key in ("x", "\x03"):
            return False
        if key in KEYMAP:
            self.core.request(*KEYMAP[key], now)
        elif key in "+=-":
            self.core.faster(key != "-")
        elif key == "t":
            self.set_owner(True)
        elif key == "h":
            self.set_owner(False)
        return True


def msgspec_encode(msg: Any) -> bytes:
    from autochair.runtime.node import encode

    return encode(msg)


def loop(link: TeleopLink, events: queue.Queue[str], stop: threading.Event,
         rate_hz: float, status: Any = None) -> None:
    """Apply queued keys and publish at `rate_hz` until `stop` or a quit key."""
    period = 1.0 / rate_hz
    next_t = time.monotonic()
    while not stop.is_set():
        now = time.monotonic()
        try:
            while True:
                if not link.handle_key(events.get_nowait(), now):
                    stop.set()
        except queue.Empty:
            pass
        cmd = link.step(now)
        if status is not None:
            status(link, cmd)
        next_t += period
        stop.wait(max(0.0, next_t - time.monotonic()))
    link.core.request(0.0, 0.0, -1e18)  # quitting: one final zero if we were moving
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


def read_keys(events: queue.Queue[str], stop: threading.Event) -> None:
    import os
    import select

    fd = sys.stdin.fileno()
    while not stop.is_set():
        ready, _, _ = select.select([fd], [], [], 0.1)
        if not ready:
            continue
        data = os.read(fd, 16).decode(errors="replace")
        for esc, name in ESCAPES.items():
            data = data.replace(esc, f"\0{name}\0")
        for part in data.split("\0"):
            for key in [part] if part in ESCAPES.values() else list(part):
                events.put(key)


def read_gamepad(core: Teleop, stop: threading.Event) -> bool:
    """Feed a gamepad's left stick (y: v, x: ω) into the core; False if none is present."""
    try:
        import inputs  # type: ignore[import-not-found]
    except ImportError:
        return False
    if not inputs.devices.gamepads:
        return False
    axes = {"ABS_Y": 0.0, "ABS_X": 0.0}

    def run() -> None:
        while not stop.is_set():
            for ev in inputs.get_gamepad():
                if ev.code in axes:
                    axes[ev.code] = ev.state / 32768.0
                    # Stick at rest (dead zone) is no input: the deadman then stops the chair.
                    if abs(axes["ABS_Y"]) > 0.1 or abs(axes["ABS_X"]) > 0.1:
                        core.request(-axes["ABS_Y"], -axes["ABS_X"], time.monotonic())

    threading.Thread(target=run, daemon=True).start()
    return True


def run(args: argparse.Namespace) -> int:
    import getpass
    import socket

    from autochair.cli import CliError
    from autochair.remote import open_session
    from autochair.runtime.client import pid_caps

    session = open_session(args)
    caps = None if args.hand_back else pid_caps(session)
    if caps is not None and (args.max_v > caps[0] or args.max_omega > caps[2]):
        session.close()
        raise CliError(f"--max-v {args.max_v:g} / --max-omega {args.max_omega:g} exceed the "
                       f"velocity PID's caps ({caps[0]:g} m/s, {caps[2]:g} rad/s; [pid] in the "
                       "chair's config)")
    core = Teleop(TeleopLimits(args.max_v, args.max_omega, args.deadman))
    link = TeleopLink(session, core, by=f"{getpass.getuser()}@{socket.gethostname()}")
    try:
        if args.hand_back:
            link.set_owner(False)
            print("drive handed back to autonomy")
            return 0
        if not sys.stdin.isatty():
            raise CliError("teleop needs a terminal (keyboard) on standard input")
        if args.take_over:
            link.set_owner(True)
        events: queue.Queue[str] = queue.Queue()
        stop = threading.Event()
        pad = read_gamepad(core, stop)

        def status(lk: TeleopLink, cmd: tuple[float, float] | None) -> None:
            v, w = cmd or (0.0, 0.0)
            sys.stdout.write(f"\r{'TELEOP OWNS' if lk.owner else 'autonomy owns (t: take over)'}"
                             f" | link {'ok' if lk.link_ok else 'LOST'} | scale "
                             f"{core.scale:.1f} | v {v:+.2f} w {w:+.2f} | pad "
                             f"{'yes' if pad else 'no'}   ")
            sys.stdout.flush()

        with raw_tty():
            reader = threading.Thread(target=read_keys, args=(events, stop), daemon=True)
            reader.start()
            try:
                loop(link, events, stop, args.rate, status)
            finally:
                stop.set()
        print("\nstopped" + ("; teleop still owns the drive: `autochair teleop --hand-back`"
                             if link.owner else ""))
        return 0
    finally:
        session.close()
