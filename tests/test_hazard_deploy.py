"""Fail-closed deployment: any stack that runs the safety monitor requires its limit; the PID's
absolute caps hold whatever the source, and the CLI cannot ask beyond them."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from autochair import deploy
from autochair.launcher import Launcher
from autochair.pid.node import PidConfig
from autochair.processes import PROCESSES, by_name, local_values, stack_values
from tests.helpers import make_stack


def pid_setting(args: list[str]) -> str:
    return next(a.split("=", 1)[1] for a in args if a.startswith("require_safety_limit="))


def test_every_generated_deploy_file_requires_the_limit() -> None:
    assert "safety" in {p.name for p in deploy.deployed()}
    assert pid_setting(deploy.fill(by_name("pid"), deploy.CHAIR_VALUES)) == "true"
    files = deploy.files()
    pid_files = [name for name, text in files.items() if "require_safety_limit" in text]
    # supervisord, systemd, compose: every file that runs the PID
    assert {"supervisord.conf", "docker-compose.yml", "systemd/autochair-pid.service"} <= \
        set(pid_files)
    for name in pid_files:
        assert "require_safety_limit=true" in files[name], name
        assert "require_safety_limit=false" not in files[name], name


def test_the_launcher_requires_the_limit_whenever_the_monitor_runs(tmp_path: Path) -> None:
    hub = "tcp/127.0.0.1:1"
    with_monitor = stack_values(list(PROCESSES), local_values(tmp_path, hub))
    assert with_monitor["safety_required"] == "true"
    without = stack_values([p for p in PROCESSES if p.name != "safety"],
                           local_values(tmp_path, hub))
    assert without["safety_required"] == "false"  # (positive control: it does change)
    launcher = make_stack(["router", "pid", "safety"], hub, tmp_path / "run")
    assert pid_setting(launcher.children["pid"].argv) == "true"


def test_the_pid_requires_limit_and_estop_by_default() -> None:
    cfg = PidConfig()
    assert cfg.require_safety_limit and cfg.require_estop


@pytest.mark.slow
def test_drive_and_teleop_refuse_speeds_beyond_the_pids_caps(
        stack_factory: Callable[..., Launcher], hub: str) -> None:
    stack_factory(["estop", "pid"])
    base = [sys.executable, "-m", "autochair.cli", "drive", "--connect", hub]

    def drive(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([*base, "--for", "0.2", "--", *args], capture_output=True,
                              text=True,
                              timeout=30, stdin=subprocess.DEVNULL)

    over = drive("1.5", "0")
    assert over.returncode != 0 and "beyond the velocity PID's caps" in over.stderr
    within = drive("0.3", "0")  # positive control
    assert within.returncode == 0, within.stderr
    teleop = subprocess.run([sys.executable, "-m", "autochair.cli", "teleop", "--connect", hub,
                             "--max-v", "2.0"], capture_output=True, text=True, timeout=30,
                            stdin=subprocess.DEVNULL)
    assert teleop.returncode != 0 and "exceed the velocity PID's caps" in teleop.stderr
    within = subprocess.run([sys.executable, "-m", "autochair.cli", "teleop", "--connect", hub],
                            capture_output=True, text=True, timeout=30, stdin=subprocess.DEVNULL)
    assert "needs a terminal" in within.stderr  # positive control: past the caps check
