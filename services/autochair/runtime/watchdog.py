"""Hung-process watchdog: a node proves its loops run; a supervisor kills it when they stop.

A service can be alive but stuck: a deadlock in a Zenoh callback or a rate loop leaves the
process, its session and its liveliness token up while nothing it should publish comes out.
Three pieces, shared by the node runtime, the launcher (`autochair up`, the tests) and the
supervisord wrapper (`autochair-watchdog`):

- `Liveness` + `late()` (pure: times are passed in): which rate loops (and worker threads that
  beat) have not completed a tick within max(watchdog_s, 3 × period), which callbacks have been
  running longer than watchdog_s, and which worker threads have ended while the node runs (an
  uncaught exception in a serial reader or a map worker must not leave a process that looks
  alive and does nothing). The node's watchdog thread asks it 4 × a second, and also wakes
  at `next_due()`, the moment the first of them would be late, so a hang is seen at its
  bound, not up to a check period later.
- The sd_notify protocol, written here (no dependency): `notify()` sends one datagram
  ("READY=1", "WATCHDOG=1", "WATCHDOG=trigger", "STOPPING=1") to $NOTIFY_SOCKET, an AF_UNIX
  datagram socket (a path, or an abstract name written with a leading '@'). The same messages
  drive systemd (`Type=notify`, `WatchdogSec=`) and our own supervisors.
- `PingWatch` (pure) + `NotifyChannel` (the socket): the supervisor's side. Armed by the first
  WATCHDOG=1; hung when the pings stop for `timeout_s`, or at once on WATCHDOG=trigger (the
  node saw its own loops late); after STOPPING=1 only a stop that takes longer than
  `stop_grace_s` counts.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import socket
import struct
import threading
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

CHECK_PERIOD_S = 0.25  # how often a node checks its loops and, when on time, pings
LOOP_PERIODS = 3.0  # a loop is late after max(watchdog_s, LOOP_PERIODS × its period)


# --- the node's side: which loops are late ------------------------------------------------------
@dataclass(frozen=True)
class Late:
    what: str  # "loop health", "callback autochair/odom" or "thread serial"
    age_s: float  # since the loop's last completed tick, the callback began or the thread ended
    bound_s: float
    ended: str = ""  # a thread's end: "returned" or the exception

    def __str__(self) -> str:
        if self.ended:
            return f"{self.what}: ended {self.age_s:.2f} s ago ({self.ended})"
        verb = "no tick for" if self.what.startswith("loop ") else "running for"
        return f"{self.what}: {verb} {self.age_s:.2f} s (bound {self.bound_s:.2f} s)"


def loop_bound(period_s: float, watchdog_s: float) -> float:
    return max(watchdog_s, LOOP_PERIODS * period_s)


def late(loops: Mapping[str, tuple[float, float]], calls: Iterable[tuple[str, float]],
         now: float, watchdog_s: float,
         ended: Mapping[str, tuple[str, float]] | None = None) -> list[Late]:
    """The pure decision. `loops`: name → (period_s, time of its last completed tick, or of
    its start before the first); `calls`: (name, start time) of callbacks still running;
    `ended`: thread name → (why, when) for worker threads that ended while the node runs
    (late at once: no bound)."""
    out = [Late(f"thread {name}", now - t, 0.0, why)
           for name, (why, t) in sorted((ended or {}).items())]
    for name, (period_s, last) in sorted(loops.items()):
        bound = loop_bound(period_s, watchdog_s)
        if now - last > bound:
            out.append(Late(f"loop {name}", now - last, bound))
    for name, started in calls:
        if now - started > watchdog_s:
            out.append(Late(f"callback {name}", now - started, watchdog_s))
    return out


def next_due(loops: Mapping[str, tuple[float, float]], calls: Iterable[tuple[str, float]],
             watchdog_s: float, ended: Mapping[str, tuple[str, float]] | None = None) -> float:
    """When the first loop or callback would become late if nothing changes (inf: never);
    an ended thread is due when it ended."""
    due = [t for _, t in (ended or {}).values()]
    due += [last + loop_bound(period_s, watchdog_s) for period_s, last in loops.values()]
    due += [started + watchdog_s for _, started in calls]
    return min(due, default=float("inf"))


class Liveness:
    """Tick times of a node's rate loops and its callbacks in flight (thread-safe; the clock
    is the caller's, so tests drive it with plain numbers)."""

    def __init__(self, watchdog_s: float) -> None:
        self.watchdog_s = watchdog_s
        self._lock = threading.Lock()
        self._loops: dict[str, tuple[float, float]] = {}
        self._calls: dict[int, tuple[str, float]] = {}
        self._ended: dict[str, tuple[str, float]] = {}
        self._ids = itertools.count()

    def add_loop(self, name: str, period_s: float, now: float) -> None:
        with self._lock:
            self._loops[name] = (period_s, now)

    def tick(self, name: str, now: float) -> None:
        with self._lock:
            period_s, _ = self._loops[name]
            self._loops[name] = (period_s, now)

    def enter(self, name: str, now: float) -> int:
        """A callback begins; pass the returned token to `leave` when it returns."""
        with self._lock:
            token = next(self._ids)
            self._calls[token] = (name, now)
        return token

    def leave(self, token: int) -> None:
        with self._lock:
            self._calls.pop(token, None)

    def ended(self, name: str, why: str, now: float) -> None:
        """A worker thread ended while its node runs: late from now on."""
        with self._lock:
            self._ended[name] = (why, now)

    def late(self, now: float) -> list[Late]:
        with self._lock:
            loops, calls, ended = dict(self._loops), list(self._calls.values()), dict(self._ended)
        return late(loops, calls, now, self.watchdog_s, ended)

    def next_due(self) -> float:
        with self._lock:
            loops, calls, ended = dict(self._loops), list(self._calls.values()), dict(self._ended)
        return next_due(loops, calls, self.watchdog_s, ended)


# --- sd_notify: one datagram per message ----------------------------------------------------------
def socket_address(address: str) -> str | bytes:
    """$NOTIFY_SOCKET as a bind/connect address: '@name' is the abstract name '\\0name'."""
    if address.startswith("@"):
        return b"\0" + address[1:].encode()
    return address


class Notifier:
    """Sends sd_notify messages to one socket; never blocks, never raises (a supervisor that
    is gone or slow must not stall the node: a lost ping costs at worst a restart)."""

    def __init__(self, address: str) -> None:
        self.address = address
        self._addr = socket_address(address)
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC)
        self.failures = 0

    @classmethod
    def from_env(cls, environ: Mapping[str, str] | None = None) -> Notifier | None:
        """A notifier for $NOTIFY_SOCKET, or None when there is none (not supervised)."""
        address = (os.environ if environ is None else environ).get("NOTIFY_SOCKET", "")
        return cls(address) if address else None

    def send(self, message: str) -> bool:
        try:
            self._sock.sendto(message.encode(), socket.MSG_DONTWAIT, self._addr)
            return True
        except OSError:
            self.failures += 1
            return False

    def close(self) -> None:
        self._sock.close()


def notify(message: str, environ: Mapping[str, str] | None = None) -> bool:
    """sd_notify(3) in one call: False when there is no $NOTIFY_SOCKET or the send failed."""
    n = Notifier.from_env(environ)
    if n is None:
        return False
    try:
        return n.send(message)
    finally:
        n.close()


def parse(datagram: bytes) -> dict[str, str]:
    """'READY=1\\nWATCHDOG=1' → {'READY': '1', 'WATCHDOG': '1'} (malformed lines skipped)."""
    fields = {}
    for line in datagram.decode(errors="replace").splitlines():
        key, sep, value = line.partition("=")
        if sep and key:
            fields[key] = value
    return fields


# --- the supervisor's side --------------------------------------------------------------------
@dataclass
class PingWatch:
    """Supervisor bookkeeping of one child's pings (pure: times are passed in)."""

    timeout_s: float = 1.5
    stop_grace_s: float = 5.0
    ready: bool = False
    pings: int = 0
    last_ping: float | None = None  # None: not armed yet (no WATCHDOG=1 so far)
    triggered: str = ""  # the node reported itself hung (WATCHDOG=trigger)
    stopping_since: float | None = None
    status: str = ""  # the child's last STATUS=

    def reset(self) -> None:
        """A new child process: nothing armed until its first ping."""
        self.ready, self.pings, self.last_ping = False, 0, None
        self.triggered, self.stopping_since, self.status = "", None, ""

    def on_message(self, fields: Mapping[str, str], now: float) -> None:
        if fields.get("READY") == "1":
            self.ready = True
        if "STATUS" in fields:
            self.status = fields["STATUS"]
        if fields.get("STOPPING") == "1" and self.stopping_since is None:
            self.stopping_since = now
        wd = fields.get("WATCHDOG")
        if wd == "1":
            self.pings += 1
            self.last_ping = now
        elif wd == "trigger":
            self.triggered = self.status or "the service reported its own loops late"

    def stopping(self, now: float) -> None:
        """The supervisor itself asked the child to stop: a stop is not a hang."""
        if self.stopping_since is None:
            self.stopping_since = now

    def hung(self, now: float) -> str | None:
        """Why the child counts as hung now, or None."""
        if self.stopping_since is not None:
            if now - self.stopping_since > self.stop_grace_s:
                return f"still not stopped {now - self.stopping_since:.1f} s after stopping"
            return None
        if self.triggered:
            return f"watchdog trigger: {self.triggered}"
        if self.last_ping is not None and now - self.last_ping > self.timeout_s:
            return f"no watchdog ping for {now - self.last_ping:.2f} s"
        return None


_UCRED = struct.Struct("3i")  # struct ucred: pid, uid, gid


@dataclass
class NotifyChannel:
    """The socket a supervisor gives one child as $NOTIFY_SOCKET, plus its PingWatch.

    Abstract (no file to clean up, no 108-byte path limit); SO_PASSCRED tells the sender's pid,
    so only the expected main process counts (systemd's NotifyAccess=main): a grandchild that
    inherited the variable, or a killed predecessor's last datagram, is ignored.
    """

    watch: PingWatch
    address: str
    sock: socket.socket
    pid: int | None = None
    foreign: int = 0  # datagrams from another pid, ignored
    _lock: threading.Lock = field(default_factory=threading.Lock)

    @classmethod
    def open(cls, name: str, timeout_s: float = 1.5, stop_grace_s: float = 5.0) -> NotifyChannel:
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_PASSCRED, 1)
        address = f"@autochair/{os.getpid()}/{os.urandom(4).hex()}/{name}"
        sock.bind(socket_address(address))
        sock.setblocking(False)
        return cls(PingWatch(timeout_s, stop_grace_s), address, sock)

    def expect(self, pid: int) -> None:
        """A new child: forget the last one's pings; only `pid` counts from now on (datagrams
        still queued from a predecessor are dropped by the pid check)."""
        with self._lock:
            self.pid = pid
            self.watch.reset()

    def drain(self, now: float) -> int:
        """Feed every queued datagram of the expected pid to the watch; how many were read."""
        n = 0
        while True:
            try:
                data, anc, _flags, _addr = self.sock.recvmsg(4096, socket.CMSG_SPACE(_UCRED.size))
            except (BlockingIOError, InterruptedError):
                return n
            except OSError:
                return n
            n += 1
            sender = None
            for level, kind, payload in anc:
                if level == socket.SOL_SOCKET and kind == socket.SCM_CREDENTIALS:
                    sender = _UCRED.unpack(payload[:_UCRED.size])[0]
            if self.pid is not None and sender != self.pid:
                self.foreign += 1
                continue
            self.watch.on_message(parse(data), now)

    def poll(self, now: float) -> str | None:
        """Read what arrived; why the child is hung, or None."""
        with self._lock:
            self.drain(now)
            return self.watch.hung(now)

    def fileno(self) -> int:
        return self.sock.fileno()

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.sock.close()
