"""The launcher's restart backoff: doubles while a child keeps failing fast, starts afresh
after a long run (a service that failed once an hour ago is not penalised for ever)."""

from __future__ import annotations

import time
from pathlib import Path

from autochair.launcher import Launcher
from autochair.processes import Process, local_values
from tests.helpers import wait_for


def test_backoff_doubles_on_fast_failures_and_resets_after_a_long_run(tmp_path: Path) -> None:
    proc = Process("failing", "autochair.no_such_module", "none")
    launcher = Launcher([proc], local_values(tmp_path, "tcp/127.0.0.1:1"), tmp_path,
                        restart=True)
    child = launcher.children["failing"]
    delays = []

    def exited() -> bool:
        launcher.poll()
        return child.state == "restarting"

    try:
        for ran_long in (False, False, False, True):
            launcher._spawn(child)
            if ran_long:
                child.spawned_at -= 60  # as if it had run for a minute
            wait_for(exited, 20, "the child's exit")
            delays.append(round(child.next_start - time.monotonic(), 1))
    finally:
        launcher.stop()
    assert delays[:3] == [0.5, 1.0, 2.0] and delays[3] == 0.5, delays
