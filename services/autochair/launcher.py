"""Start the processes of the one process list, watch them, restart them, stop them cleanly.

Used by `autochair up` and by the system tests, so both run exactly what deploy/ runs.

Hung children: each child gets its own $NOTIFY_SOCKET (sd_notify, see runtime/watchdog.py).
Once it has sent its first WATCHDOG=1, `poll()` SIGKILLs it when its pings stop for
`watchdog_s`, or at once when it reports its own loops late (WATCHDOG=trigger); it shows as
state "hung", then "restarting" with the usual backoff. `poll()` must be called often (`up`
does, every 0.1 s).
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import zenoh

from autochair.backoff import Backoff
from autochair.processes import Process, stack_values
from autochair.runtime.client import watch_alive
from autochair.runtime.config import chair_in
from autochair.runtime.session import client_settings, open_session
from autochair.runtime.watchdog import NotifyChannel

PR_SET_PDEATHSIG = 1


def _die_with_parent(sig: int = signal.SIGTERM) -> None:
    """Children get `sig` if the launcher itself is killed (Linux), so nothing is orphaned."""
    with contextlib.suppress(Exception):
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(PR_SET_PDEATHSIG, sig)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def wait_port(host: str, port: int, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while True:  # at least once, even with timeout 0
        with socket.socket() as s:
            s.settimeout(0.2)
            if s.connect_ex((host, port)) == 0:
                return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.05)


@dataclass
class Child:
    proc: Process
    argv: list[str]
    popen: subprocess.Popen[bytes] | None = None
    state: str = "stopped"  # starting | up | hung | exited | restarting | stopped
    restarts: int = 0
    # Restarts in a row without a long run: the delay doubles, 0.5 s to 8 s (no jitter: one
    # machine, and a person watching wants predictable restarts).
    backoff: Backoff = field(default_factory=lambda: Backoff(0.5, 2.0, 8.0, 0.0))
    spawned_at: float = 0.0
    exit_code: int | None = None
    next_start: float = 0.0
    log_path: Path | None = None
    killed: bool = False  # had to be SIGKILLed on stop
    notify: NotifyChannel | None = None  # its $NOTIFY_SOCKET and ping bookkeeping
    hangs: int = 0  # times it was killed as hung
    hung_reason: str = ""  # why, the last time
    hung_at: float | None = None  # monotonic time of the last kill as hung


@dataclass
class Launcher:
    processes: list[Process]
    values: dict[str, str]  # placeholder values: run_dir, hub, hub_port, serial_port, ...
    run_dir: Path
    restart: bool = True
    env: dict[str, str] = field(default_factory=dict)
    on_change: Callable[[Child], None] = lambda c: None
    watchdog_s: float = 1.5  # a child that pinged, then stops pinging this long, is killed
    children: dict[str, Child] = field(default_factory=dict)
    _session: zenoh.Session | None = None
    _stopping: bool = False
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def __post_init__(self) -> None:
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self.values = stack_values(self.processes, self.values)
        for p in self.processes:
            argv = [sys.executable, "-m", p.module, *(a.format(**self.values) for a in p.args)]
            self.children[p.name] = Child(p, argv, log_path=self.run_dir / f"{p.name}.log")

    @property
    def hub(self) -> str:
        return self.values["hub"]

    def start(self, ready_timeout_s: float = 20.0) -> None:
        """Start everything in the process list's order, each once the processes it comes
        `after` are up; returns once all are up or raises TimeoutError."""
        deadline = time.monotonic() + ready_timeout_s
        pending = list(self.children.values())
        while pending:
            for child in [c for c in pending if all(
                    self.children[d].state == "up" for d in c.proc.after if d in self.children)]:
                self._spawn(child)
                pending.remove(child)
            self._hub_ready(watch=True)
            if time.monotonic() > deadline:
                waiting = {c.proc.name: [d for d in c.proc.after if d in self.children
                                         and self.children[d].state != "up"] for c in pending}
                raise TimeoutError(f"not started after {ready_timeout_s:.0f} s, waiting for "
                                   f"{waiting} (logs in {self.run_dir})")
            if pending:
                time.sleep(0.05)
        self.wait_up(max(deadline - time.monotonic(), 0.1))

    def _hub_ready(self, watch: bool = False) -> None:
        """A process that is the hub is up once it listens; with `watch`, tokens are watched
        from then on (or at once when the hub is not ours)."""
        host, port = self.hub.split("/", 1)[1].rsplit(":", 1)
        for child in self.children.values():
            if child.proc.ready == "hub_port" and child.state == "starting" \
                    and wait_port(host, int(port), 0.0):
                self._set(child, "up")
        hubs = [c for c in self.children.values() if c.proc.ready == "hub_port"]
        if watch and self._session is None and all(c.state == "up" for c in hubs):
            self._watch_liveliness()

    def wait_up(self, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            self.poll()
            if all(c.state == "up" for c in self.children.values()):
                return
            time.sleep(0.05)
        late = [c.proc.name for c in self.children.values() if c.state != "up"]
        raise TimeoutError(f"not up after {timeout_s:.0f} s: {', '.join(late)} "
                           f"(logs in {self.run_dir})")

    def _watch_liveliness(self) -> None:
        chair = chair_in({**os.environ, **self.env})  # the children's namespace, if any
        self._session = open_session(client_settings(self.hub, chair))

        def on_token(name: str, alive: bool) -> None:
            child = self.children.get(name)
            if child is None:
                return
            if alive:
                self._set(child, "up")
            elif child.state == "up":
                # token gone: the process is hung, dying or being stopped; poll() decides
                self._set(child, "stopping" if self._stopping else "starting")

        watch_alive(self._session, on_token)

    def _spawn(self, child: Child) -> None:
        if child.notify is None:
            child.notify = NotifyChannel.open(child.proc.name, self.watchdog_s)
        env = {**os.environ, "PYTHONUNBUFFERED": "1", "AUTOCHAIR_CONNECT": self.hub, **self.env,
               "NOTIFY_SOCKET": child.notify.address}
        assert child.log_path is not None
        log = child.log_path.open("ab")
        child.popen = subprocess.Popen(child.argv, stdout=log, stderr=subprocess.STDOUT,
                                       stdin=subprocess.DEVNULL, env=env,
                                       start_new_session=True, preexec_fn=_die_with_parent)
        log.close()
        child.notify.expect(child.popen.pid)
        child.exit_code, child.spawned_at = None, time.monotonic()
        self._set(child, "starting")

    def _set(self, child: Child, state: str) -> None:
        with self._lock:
            if child.state == state:
                return
            child.state = state
        self.on_change(child)

    def poll(self) -> None:
        """Notice exits and hangs; restart with exponential backoff (0.5 s doubling to 8 s)."""
        now = time.monotonic()
        for child in self.children.values():
            if child.popen is not None and child.popen.poll() is None:
                self._check_hung(child, now)
            elif child.popen is not None:
                child.exit_code = child.popen.returncode
                child.popen = None
                if self.restart:
                    if now - child.spawned_at >= 30:  # it ran a while: afresh
                        child.backoff.reset()
                    child.next_start = now + child.backoff.next_s(0.0)
                    self._set(child, "restarting")
                else:
                    self._set(child, "exited")
            elif child.state == "restarting" and now >= child.next_start:
                child.restarts += 1
                self._spawn(child)
        if not self._stopping:
            self._hub_ready()  # the hub is up once it listens (again, after a restart)

    def _check_hung(self, child: Child, now: float) -> None:
        """SIGKILL a running child whose watchdog pings stopped; the next poll restarts it."""
        if child.notify is None or self._stopping or child.state == "hung":
            return
        reason = child.notify.poll(now)
        if reason is None:
            return
        assert child.popen is not None
        child.hangs += 1
        child.hung_reason, child.hung_at = reason, now
        self._set(child, "hung")
        with contextlib.suppress(ProcessLookupError):
            child.popen.kill()
        if child.log_path is not None:
            with child.log_path.open("a") as log:
                print(f"launcher: {child.proc.name} (pid {child.popen.pid}) hung: {reason}; "
                      "killed (SIGKILL)", file=log)

    def kill(self, name: str, sig: int = signal.SIGKILL) -> None:
        """Signal one child (fault injection in tests)."""
        popen = self.children[name].popen
        if popen is not None:
            popen.send_signal(sig)

    def pid(self, name: str) -> int | None:
        popen = self.children[name].popen
        return popen.pid if popen else None

    def stop(self, timeout_s: float = 5.0) -> bool:
        """SIGTERM in reverse start order, then SIGKILL stragglers. True if all exited cleanly."""
        self.restart, self._stopping = False, True
        now = time.monotonic()
        for c in self.children.values():  # a stop is not a hang
            if c.notify is not None:
                c.notify.watch.stopping(now)
        clean = True
        # In waves, the reverse of the start order: a process goes once nothing still running
        # needs it (`after`), so the hub, which every other process needs, goes last.
        remaining = [c for c in reversed(list(self.children.values())) if c.popen is not None]
        while remaining:
            needed = {d for c in remaining for d in c.proc.after}
            wave = [c for c in remaining if c.proc.name not in needed] or remaining
            for child in wave:
                assert child.popen is not None
                child.popen.terminate()
            deadline = time.monotonic() + timeout_s
            for child in wave:
                clean &= self._reap(child, deadline)
            remaining = [c for c in remaining if c not in wave]
        if self._session is not None:
            with contextlib.suppress(zenoh.ZError):
                self._session.close()
            self._session = None
        for c in self.children.values():
            if c.notify is not None:
                c.notify.close()
                c.notify = None
        return clean

    def _reap(self, child: Child, deadline: float) -> bool:
        assert child.popen is not None
        try:
            code = child.popen.wait(max(0.0, deadline - time.monotonic()))
            clean = code in (0, -signal.SIGTERM)
        except subprocess.TimeoutExpired:
            child.popen.kill()
            code = child.popen.wait()
            clean, child.killed = False, True
        child.exit_code, child.popen = code, None
        self._set(child, "stopped")
        return clean
