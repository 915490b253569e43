"""H39: a service refuses to run next to a twin of itself in the same chair (the stack started
twice, a manual run beside the supervisor): two PIDs or gateways would both drive the chair,
and a twin's liveliness token hides the other's death from every watcher."""

from __future__ import annotations

from pathlib import Path

import pytest

from autochair.runtime.client import alive_services
from tests.helpers import client_session, spawned, stop_process, wait_for

pytestmark = pytest.mark.slow


def test_a_second_instance_of_a_service_refuses_to_start(tmp_path: Path) -> None:
    with spawned(tmp_path) as (hub, start):
        session = client_session(hub)
        try:
            first = start("autochair.odometry.node")
            wait_for(lambda: "odometry" in alive_services(session), 20, "the first odometry up")
            twin = start("autochair.odometry.node")
            code = wait_for(twin.poll, 20, "the twin to exit")
            log = (tmp_path / "node-2.log").read_text()
            assert code == 2 and "another odometry is already running" in log, log
            assert first.poll() is None  # the first runs on, untouched
            # Positive control: once the first is stopped, a new one starts and stays up.
            stop_process(first)
            wait_for(lambda: "odometry" not in alive_services(session), 10, "the first gone")
            again = start("autochair.odometry.node")
            wait_for(lambda: "odometry" in alive_services(session), 20, "the new odometry up")
            assert again.poll() is None
        finally:
            session.close()
