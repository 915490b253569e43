"""supervisord runs part of the stack from a generated config and restarts a killed service."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from autochair import deploy
from autochair.processes import by_name
from autochair.runtime.client import alive_services, open_client

BIN = Path(sys.executable).parent
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not (BIN / "supervisord").exists(),
                                 reason="pip supervisor is not installed in this venv")]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_for(cond: Callable[[], bool], timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.1)
    return False


@pytest.fixture()
def stack(tmp_path: Path) -> Iterator[tuple[Path, str]]:
    hub = f"tcp/127.0.0.1:{free_port()}"
    paths = deploy.Paths(bin_dir=str(BIN), config=str(tmp_path / "chair.toml"),
                         log_dir=str(tmp_path), run_dir=str(tmp_path))
    (tmp_path / "chair.toml").write_text(f'[zenoh]\nconnect = ["{hub}"]\n')
    values = {**deploy.CHAIR_VALUES, "hub": hub, "run_dir": str(tmp_path)}
    conf = tmp_path / "supervisord.conf"
    conf.write_text(deploy.supervisord_conf([by_name("router"), by_name("odometry")], values,
                                            paths))
    proc = subprocess.Popen([str(BIN / "supervisord"), "-c", str(conf)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        yield conf, hub
    finally:
        proc.send_signal(signal.SIGTERM)  # supervisord stops its programs (TERM) first
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def ctl(conf: Path, *args: str) -> str:
    return subprocess.run([str(BIN / "supervisorctl"), "-c", str(conf), *args],
                          capture_output=True, text=True, timeout=20).stdout.strip()


def test_supervisord_runs_the_stack_and_restarts_a_killed_service(
        stack: tuple[Path, str]) -> None:
    conf, hub = stack
    session = open_client(hub, timeout_ms=15000)
    try:
        assert wait_for(lambda: "odometry" in alive_services(session, 0.5), 60), \
            ctl(conf, "status")
        pid = int(ctl(conf, "pid", "odometry"))
        os.kill(pid, signal.SIGKILL)
        assert wait_for(lambda: "odometry" not in alive_services(session, 0.5), 10)
        assert wait_for(lambda: "odometry" in alive_services(session, 0.5), 60), \
            ctl(conf, "status")
        new_pid = int(ctl(conf, "pid", "odometry"))
        assert new_pid not in (0, pid)
        assert "RUNNING" in ctl(conf, "status", "router")
    finally:
        session.close()
