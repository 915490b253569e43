"""supervisord runs part of the stack from a generated config and restarts a killed service."""

from __future__ import annotations

import os
import signal
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from autochair.runtime.client import alive_services, open_client
from tests.helpers import supervised, supervisorctl

BIN = Path(sys.executable).parent
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not (BIN / "supervisord").exists(),
                                 reason="pip supervisor is not installed in this venv")]


def wait_for(cond: Callable[[], bool], timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.1)
    return False


@pytest.fixture()
def stack(tmp_path: Path) -> Iterator[tuple[Path, str]]:
    with supervised(tmp_path, ["router", "odometry"]) as (conf, hub):
        yield conf, hub


def test_supervisord_runs_the_stack_and_restarts_a_killed_service(
        stack: tuple[Path, str]) -> None:
    conf, hub = stack
    session = open_client(hub, timeout_ms=15000)
    try:
        assert wait_for(lambda: "odometry" in alive_services(session, 0.5), 60), \
            supervisorctl(conf, "status")
        pid = int(supervisorctl(conf, "pid", "odometry"))
        os.kill(pid, signal.SIGKILL)
        assert wait_for(lambda: "odometry" not in alive_services(session, 0.5), 10)
        assert wait_for(lambda: "odometry" in alive_services(session, 0.5), 60), \
            supervisorctl(conf, "status")
        new_pid = int(supervisorctl(conf, "pid", "odometry"))
        assert new_pid not in (0, pid)
        assert "RUNNING" in supervisorctl(conf, "status", "router")
    finally:
        session.close()
