"""Every session opens through runtime.session.open_session, which turns Zenoh's own log on:
$RUST_LOG when set (e.g. `zenoh=debug` while chasing a TLS or ACL refusal), else warnings for
services and the hub, errors for people's tools."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from autochair.launcher import free_port, wait_port
from tests.helpers import stop_process, wait_for


def hub_log(tmp_path: Path, rust_log: str | None) -> str:
    port = free_port()
    env = {k: v for k, v in os.environ.items() if k != "RUST_LOG"}
    if rust_log is not None:
        env["RUST_LOG"] = rust_log
    log = tmp_path / f"hub-{rust_log}.log"
    with open(log, "wb") as out:
        p = subprocess.Popen([sys.executable, "-m", "autochair.router.node", "--listen",
                              f"tcp/127.0.0.1:{port}"], stdout=out, stderr=out, env=env)
        try:
            assert wait_port("127.0.0.1", port, 20.0), "hub never listened"
            wait_for(lambda: "listening on" in log.read_text(), 10, "the hub's own log line")
        finally:
            stop_process(p)
    return log.read_text()


@pytest.mark.slow
def test_zenohs_log_is_on_and_follows_rust_log(tmp_path: Path) -> None:
    # With RUST_LOG=info, Zenoh's own lines appear (the log is initialised)...
    assert "Zenoh can be reached at" in hub_log(tmp_path, "info")
    # ...and by default (warn) only warnings and worse do: no info lines, no noise.
    assert "Zenoh can be reached at" not in hub_log(tmp_path, None)
