"""Test helpers: bounded waiting, Zenoh clients, a private stack from the process list."""

from __future__ import annotations

import contextlib
import fcntl
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

import pytest
import zenoh

from autochair.launcher import Launcher
from autochair.processes import PROCESSES, local_values
from autochair.runtime.session import client_settings, open_session

T = TypeVar("T")


def wait_for(cond: Callable[[], T | None], timeout: float,
             what: str | Callable[[], str] = "condition", interval: float = 0.01) -> T:
    """Poll `cond` until it returns something truthy; fail the test after `timeout` seconds.
    `what` may be a function: what was seen instead, worked out only on a failure."""
    deadline = time.monotonic() + timeout
    while True:
        value = cond()
        if value:
            return value
        if time.monotonic() > deadline:
            pytest.fail(f"timed out after {timeout} s waiting for "
                        f"{what() if callable(what) else what}")
        time.sleep(interval)


def client_session(hub: str) -> zenoh.Session:
    return open_session(client_settings(hub))


class Recorder:
    """Collects the decoded messages of one key-table row with their receive time (monotonic),
    through the runtime's typed `subscribe`; `key` narrows a per-service row (health)."""

    def __init__(self, session: zenoh.Session, topic: Any, key: str | None = None) -> None:
        from autochair.runtime.client import subscribe

        self.items: list[tuple[float, Any]] = []
        self.errors = 0
        self._lock = threading.Lock()

        def on_msg(msg: Any) -> None:
            with self._lock:
                self.items.append((time.monotonic(), msg))

        def on_error() -> None:
            self.errors += 1

        self._sub = subscribe(session, topic, on_msg, key, on_error)

    def close(self) -> None:
        self._sub.undeclare()

    def messages(self) -> list[Any]:
        with self._lock:
            return [m for _, m in self.items]

    def latest(self) -> Any:
        with self._lock:
            return self.items[-1][1] if self.items else None


def make_stack(names: list[str], hub: str, run_dir: Path, restart: bool = False,
               **values: str) -> Launcher:
    procs = [p for p in PROCESSES if p.name in names]
    values = {"record_path": str(run_dir / "rec.mcap"), **values}
    return Launcher(procs, local_values(run_dir, hub, **values), run_dir, restart=restart)


def pid_ready(session: zenoh.Session, timeout: float = 15) -> None:
    """Wait until the velocity PID would obey a stream begun now: it hears the e-stop (and the
    safety limit when required), so only the wait for a deliberate act remains."""
    from autochair_msgs import keys

    status = Recorder(session, keys.PID_STATUS)
    try:
        wait_for(lambda: (lambda m: m is not None and (m.active or m.inhibit.startswith(
            "stopped")))(status.latest()), timeout, "the velocity PID ready for a command")
    finally:
        status.close()


def goal_ready(session: zenoh.Session, timeout: float = 20) -> None:
    """Wait until a goal sent now would be taken and obeyed: the velocity PID ready
    (`pid_ready`) and the control service hearing the same (its health says "ready for
    goals", not why a goal would be refused)."""
    from autochair_msgs import keys

    pid_ready(session, timeout)
    health = Recorder(session, keys.HEALTH, keys.HEALTH.for_service("control"))
    try:
        wait_for(lambda: (lambda h: h is not None and h.detail == "ready for goals")(
            health.latest()), timeout, lambda: "the control service ready for goals, not "
                                               f"{getattr(health.latest(), 'detail', None)!r}")
    finally:
        health.close()


class Stream:
    """One command stream (a deliberate act): every command carries the time it began, so the
    velocity PID obeys it only if it began after the PID's last stop."""

    def __init__(self, pub: Any, v: float, omega: float = 0.0, source: str = "test") -> None:
        """`pub`: a runtime.client.Publisher of keys.CMD_VEL (or of keys.TELEOP)."""
        self.pub, self.v, self.omega, self.source = pub, v, omega, source
        self.start_ns = time.time_ns()

    @classmethod
    def on(cls, session: zenoh.Session, v: float, omega: float = 0.0,
           source: str = "test") -> Stream:
        """A stream on keys.CMD_VEL of `session`."""
        from autochair.runtime.client import Publisher
        from autochair_msgs import keys

        return cls(Publisher(session, keys.CMD_VEL), v, omega, source)

    def put(self, v: float | None = None, omega: float | None = None) -> None:
        from autochair_msgs import VelocityCommand

        self.pub.put(VelocityCommand(
            stamp_ns=time.time_ns(), v_mps=self.v if v is None else v,
            omega_radps=self.omega if omega is None else omega, source=self.source,
            stream_start_ns=self.start_ns))


@contextlib.contextmanager
def supervised(tmp_path: Path, names: list[str]) -> Iterator[tuple[Path, str]]:
    """supervisord running `names` from the config `autochair.deploy` generates, on a free
    loopback hub; yields (supervisord.conf, hub) and stops it (TERM stops its programs)."""
    from autochair import deploy
    from autochair.launcher import free_port
    from autochair.processes import by_name

    bin_dir = Path(sys.executable).parent
    hub = f"tcp/127.0.0.1:{free_port()}"
    paths = deploy.Paths(bin_dir=str(bin_dir), config=str(tmp_path / "chair.toml"),
                         log_dir=str(tmp_path), run_dir=str(tmp_path))
    (tmp_path / "chair.toml").write_text(f'[zenoh]\nconnect = ["{hub}"]\n')
    values = {**deploy.CHAIR_VALUES, "hub": hub, "run_dir": str(tmp_path)}
    conf = tmp_path / "supervisord.conf"
    conf.write_text(deploy.supervisord_conf([by_name(n) for n in names], values, paths))
    proc = subprocess.Popen([str(bin_dir / "supervisord"), "-c", str(conf)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        yield conf, hub
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def supervisorctl(conf: Path, *args: str) -> str:
    return subprocess.run([str(Path(sys.executable).parent / "supervisorctl"), "-c", str(conf),
                           *args], capture_output=True, text=True, timeout=20).stdout.strip()


Spawn = Callable[..., "subprocess.Popen[bytes]"]


@contextlib.contextmanager
def spawned(tmp_path: Path) -> Iterator[tuple[str, Spawn]]:
    """A private hub on a free loopback port, and a way to start services on it (each logging
    to tmp_path); everything is stopped afterwards."""
    from autochair.launcher import free_port, wait_port

    port = free_port()
    hub = f"tcp/127.0.0.1:{port}"
    procs: list[subprocess.Popen[bytes]] = []

    def start(module: str, *args: str) -> subprocess.Popen[bytes]:
        name = module.rsplit(".", 1)[-1]
        log = open(tmp_path / f"{name}-{len(procs)}.log", "wb")  # noqa: SIM115
        p = subprocess.Popen([sys.executable, "-m", module, *args], stdout=log, stderr=log)
        procs.append(p)
        return p

    try:
        start("autochair.router.node", "--listen", hub)
        assert wait_port("127.0.0.1", port, 10), "hub did not come up"
        yield hub, lambda module, *a: start(module, "--connect", hub, *a)
    finally:
        for p in reversed(procs):
            stop_process(p)


def stop_process(p: subprocess.Popen[bytes] | subprocess.Popen[str]) -> None:
    """Terminate, then kill if it does not exit within 5 s."""
    if p.poll() is None:
        p.terminate()
        try:
            p.wait(timeout=5)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def session_when_up(hub: str, timeout: float = 20) -> zenoh.Session:
    """A client session, retried until the hub (started by the test) accepts it."""

    def try_open() -> zenoh.Session | None:
        try:
            return client_session(hub)
        except zenoh.ZError:
            return None  # the hub is still starting

    return wait_for(try_open, timeout, "zenoh hub", interval=0.2)


JS = Path(__file__).parent / "js"


def npm_ready() -> Path:
    """The committed npm packages (Foxglove's reader, schemas, WebSocket client) in tests/js,
    installed with `npm ci` whenever node_modules does not match the lock. Node itself comes
    from `./dev test` (Debian's nodejs) when missing."""
    if not (shutil.which("node") and shutil.which("npm")):
        pytest.fail("node and npm are needed for the Foxglove tests: run ./dev test as root, "
                    "or apt-get install -y nodejs npm")
    stamp = JS / "node_modules" / ".package-lock.json"
    lock = JS / "package-lock.json"
    with lock.open() as held:
        fcntl.flock(held, fcntl.LOCK_EX)  # one `npm ci` at a time (xdist workers share tests/js)
        if not stamp.exists() or stamp.stat().st_mtime < lock.stat().st_mtime:
            r = subprocess.run(["npm", "ci", "--no-audit", "--no-fund", "--loglevel=error"],
                               cwd=JS, capture_output=True, text=True, timeout=600)
            assert r.returncode == 0, f"npm ci failed: {r.stderr[-2000:]}"
    return JS
