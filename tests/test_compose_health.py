"""The pieces compose relies on: `autochair health` (the containers' healthcheck) against real
services, and `autochair deploy image`'s one-line errors when Docker or debootstrap is missing."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from autochair.cli import CliError
from autochair.commands import deploy as deploy_cmd
from autochair.launcher import Launcher, free_port

AUTOCHAIR = [sys.executable, "-m", "autochair.cli"]


def health(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*AUTOCHAIR, "health", *args], capture_output=True, text=True,
                          timeout=60)


@pytest.mark.slow
def test_health_is_0_only_for_a_live_service_saying_ok(
        stack_factory: Callable[..., Launcher], hub: str) -> None:
    stack_factory(["estop"])
    r = health("--service", "estop", "--connect", hub)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.startswith("estop: ok, up ") and r.stdout.count("\n") == 1
    r = health("--service", "pid", "--connect", hub, "--timeout", "1.5")
    assert (r.returncode, r.stdout) == (1, "pid: not alive (no liveliness token)\n")
    r = health("--service", "router", "--connect", hub)
    assert (r.returncode, r.stdout) == (0, "router: the hub accepts sessions\n")


def test_health_without_a_hub_is_one_line_and_exit_1() -> None:
    r = health("--service", "pid", "--connect", f"tcp/127.0.0.1:{free_port()}", "--timeout", "1")
    assert r.returncode == 1 and r.stdout.startswith("pid: no autochair hub at "), r.stdout
    assert r.stdout.count("\n") == 1 and not r.stderr


def test_image_without_docker_is_a_one_line_error(tmp_path: Path) -> None:
    env = {**os.environ, "PATH": str(tmp_path)}  # no docker on it
    r = subprocess.run([*AUTOCHAIR, "deploy", "image", "--work-dir", str(tmp_path / "w")],
                       capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == 2
    assert r.stderr == ("autochair deploy: error: docker not found: install Docker "
                        "(Debian: apt-get install docker.io)\n")


def test_image_without_a_docker_daemon_is_a_one_line_error(tmp_path: Path) -> None:
    if shutil.which("docker") is None:
        pytest.skip("no docker CLI: apt-get install -y docker.io")
    env = {**os.environ, "DOCKER_HOST": f"unix://{tmp_path}/none.sock"}
    r = subprocess.run([*AUTOCHAIR, "deploy", "image", "--work-dir", str(tmp_path / "w")],
                       capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == 2 and r.stderr.count("\n") == 1
    assert r.stderr.startswith("autochair deploy: error: cannot reach the Docker daemon")


def test_offline_base_without_debootstrap_or_root_is_a_one_line_error(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    real_which = shutil.which
    monkeypatch.setattr(shutil, "which",
                        lambda name: None if name == "debootstrap" else real_which(name))
    with pytest.raises(CliError, match=r"^debootstrap not found: apt-get install debootstrap"):
        deploy_cmd.bootstrap_base("x:y", tmp_path, deploy_cmd.DEFAULT_MIRROR)
    monkeypatch.setattr(shutil, "which", lambda name: f"/usr/sbin/{name}")
    monkeypatch.setattr(os, "geteuid", lambda: 1000)
    with pytest.raises(CliError, match=r"^debootstrap needs root"):
        deploy_cmd.bootstrap_base("x:y", tmp_path, deploy_cmd.DEFAULT_MIRROR)
    assert not list(tmp_path.iterdir())  # nothing started, nothing left
