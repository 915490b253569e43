"""`autochair up --sim` as a person runs it: every process of the list up, status sees them,
SIGTERM (as Ctrl-C) stops them all cleanly and leaves nothing behind."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from autochair.launcher import free_port
from autochair.processes import selected
from tests.helpers import stop_process, wait_for

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_up_runs_the_whole_list_and_stops_cleanly(tmp_path: Path, sig: int) -> None:
    hub = f"tcp/127.0.0.1:{free_port()}"
    proc = subprocess.Popen(
        [sys.executable, "-m", "autochair.cli", "up", "--sim", "--hub", hub,
         "--record", str(tmp_path / "rec"), "--run-dir", str(tmp_path / "run")],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, stdin=subprocess.DEVNULL)
    lines: list[str] = []

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line.rstrip())

    threading.Thread(target=read, daemon=True).start()
    try:
        wait_for(lambda: any("all up" in ln for ln in lines), 60, "`all up`")
        expected = {p.name for p in selected(sim=True)}
        pids = {int(m.group(2)) for ln in lines
                if (m := re.search(r"(\S+)\s+up\s+pid (\d+)", ln))}
        assert len(pids) == len(expected)
        status = subprocess.run([sys.executable, "-m", "autochair.cli", "status", "--json",
                                 "--connect", hub], capture_output=True, text=True, timeout=30)
        alive = {name for name, s in json.loads(status.stdout).items() if s["alive"]}
        assert alive == expected - {"router"}  # the hub holds no token of its own
        proc.send_signal(sig)
        code = proc.wait(timeout=30)
        assert code == 0, f"exit {code}: " + "\n".join(lines[-25:])
        assert any(ln.endswith("autochair: stopped") for ln in lines), lines[-5:]
        for pid in pids:  # every child is gone, none orphaned
            with pytest.raises(ProcessLookupError):
                os.kill(pid, 0)
        assert list((tmp_path / "rec").glob("*.mcap")), "the run was not recorded"
    finally:
        stop_process(proc)
