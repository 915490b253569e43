"""One clear line, not a traceback, for bad config, a missing port or a wrong argument."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from autochair.launcher import free_port


def run(*argv: str, timeout: float = 30) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, *argv], capture_output=True, text=True,
                          timeout=timeout, stdin=subprocess.DEVNULL)


def one_line_error(proc: subprocess.CompletedProcess[str], *needles: str) -> None:
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert "Traceback" not in proc.stderr
    errors = [ln for ln in lines if "error:" in ln]
    assert len(errors) == 1, proc.stderr
    for needle in needles:
        assert needle in errors[0], errors[0]


def test_up_needs_sim_or_port() -> None:
    one_line_error(run("-m", "autochair.cli", "up"), "--port", "--sim")


def test_up_missing_serial_port() -> None:
    one_line_error(run("-m", "autochair.cli", "up", "--port", "/dev/ttyNOPE0"),
                   "/dev/ttyNOPE0 not found")


def test_up_unknown_process() -> None:
    one_line_error(run("-m", "autochair.cli", "up", "--sim", "--only", "gatewy"), "gatewy")


def test_up_unknown_map(tmp_path: Path) -> None:
    (tmp_path / "maps").mkdir()
    (tmp_path / "maps" / "hall.yaml").write_text("image: hall.pgm\n")
    proc = run("-m", "autochair.cli", "up", "--sim", "--map", "hal", "--state-dir",
               str(tmp_path), "--hub", f"tcp/127.0.0.1:{free_port()}")
    one_line_error(proc, "no map 'hal'", "known: hall", "autochair map save")


def test_up_keepout_needs_a_map_and_an_existing_mask(tmp_path: Path) -> None:
    (tmp_path / "maps").mkdir()
    (tmp_path / "maps" / "hall.yaml").write_text("image: hall.pgm\n")
    hub = f"tcp/127.0.0.1:{free_port()}"
    one_line_error(run("-m", "autochair.cli", "up", "--sim", "--keepout", "hall", "--state-dir",
                       str(tmp_path), "--hub", hub), "--keepout needs --map")
    one_line_error(run("-m", "autochair.cli", "up", "--sim", "--map", "hall", "--keepout",
                       "stairs", "--state-dir", str(tmp_path), "--hub", hub),
                   "no mask 'stairs'", "known: hall")


def test_up_refuses_a_mask_not_drawn_over_the_map(tmp_path: Path) -> None:
    """H42 before anything starts: the monitor would stop the chair for it; say why at once."""
    from autochair.commands.up import _check_mask
    from autochair.mapping.mapfile import save_map
    from tests.test_safety_keepout import mask

    maps = tmp_path / "maps"
    maps.mkdir()
    save_map(mask([]), maps / "hall.yaml")
    save_map(mask([(2.5, -2.0, 3.0, 3.0)], walls=False), maps / "bare.yaml")
    save_map(mask([(2.5, -2.0, 3.0, 3.0)]), maps / "stairs.yaml")
    one_line_error(run("-m", "autochair.cli", "up", "--sim", "--map", "hall", "--keepout", "bare",
                       "--state-dir", str(tmp_path), "--hub", f"tcp/127.0.0.1:{free_port()}"),
                   "--keepout bare does not fit --map hall", "0 of the map's 1600 wall cells")
    _check_mask(maps / "stairs.yaml", maps / "hall.yaml")  # positive control: drawn over it


def test_drive_out_of_range() -> None:
    one_line_error(run("-m", "autochair.cli", "drive", "5", "0"), "|v|")


def test_drive_wrong_argument_is_argparse_error() -> None:
    proc = run("-m", "autochair.cli", "drive", "fast", "0")
    one_line_error(proc, "invalid float value")


def test_status_without_hub() -> None:
    proc = run("-m", "autochair.cli", "status", "--connect", f"tcp/127.0.0.1:{free_port()}")
    one_line_error(proc, "no autochair hub")


@pytest.mark.parametrize("setting,needle", [
    ("keepalive_hz=abc", "Expected `float`"),
    ("stale.joystick_s=0", "joystick_s"),
    ("no_such_field=1", "no_such_field"),
])
def test_service_bad_setting(setting: str, needle: str) -> None:
    proc = run("-m", "autochair.gateway.node", "--set", setting, "--set", "port=loop://",
               "--connect", f"tcp/127.0.0.1:{free_port()}")
    one_line_error(proc, "[stale]" if setting.startswith("stale.") else "[gateway]", needle)


def test_service_bad_config_file(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[pid]\nv_gains = [1, 2\n")
    one_line_error(run("-m", "autochair.pid.node", "--config", str(bad)), str(bad))
    one_line_error(run("-m", "autochair.pid.node", "--config", str(tmp_path / "none.toml")),
                   "not found")


def test_gateway_without_port() -> None:
    proc = run("-m", "autochair.gateway.node", "--connect", f"tcp/127.0.0.1:{free_port()}")
    one_line_error(proc, "port is not set")


def test_up_refuses_a_busy_hub_port() -> None:
    import socket

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        one_line_error(run("-m", "autochair.cli", "up", "--sim", "--hub",
                           f"tcp/127.0.0.1:{port}"), "already listens")


@pytest.mark.parametrize("setting,needle", [
    ("chair.laser_x_m=nan", "laser_x_m"), ("chair.front_m=0", "front_m"),
    ("stale.scan_s=inf", "scan_s"), ("stale.watchdog_s=11", "watchdog_s"),
])
def test_shared_sections_are_validated_by_constraints_naming_the_field(setting: str,
                                                                       needle: str) -> None:
    proc = run("-m", "autochair.gateway.node", "--set", setting, "--set", "port=loop://",
               "--connect", f"tcp/127.0.0.1:{free_port()}")
    one_line_error(proc, f"[{setting.split('.')[0]}]", needle)


def test_localize_reports_the_outcome_or_what_it_saw_instead(
        capsys: pytest.CaptureFixture[str]) -> None:
    import queue

    from autochair.commands.localize import _outcome
    from autochair_msgs import LocalizedPose, Pose2D

    def pose(state: str, x: float) -> LocalizedPose:
        return LocalizedPose(stamp_ns=1, x_m=x, y_m=0.0, yaw_rad=0.0, covariance=[0.0] * 9,
                             quality=0.4, state=state, mode="localization")

    seen: queue.Queue[LocalizedPose] = queue.Queue()
    for m in (pose("initializing", 3.0), pose("lost", 3.0)):
        seen.put(m)
    assert _outcome(seen, 0.2, Pose2D(3.0, 0.0, 0.0)) == 1
    assert "not tracking after 0.2 s (lost, quality 0.40" in capsys.readouterr().out
    seen.put(pose("tracking", 0.5))  # positive control: tracking is reported, with the offset
    assert _outcome(seen, 0.2, Pose2D(0.0, 0.0, 0.0)) == 0
    assert "tracking at (0.50 m, 0.00 m, 0.0°), quality 0.40, 50 cm from" in capsys.readouterr().out
    assert _outcome(queue.Queue(), 0.05, None) == 1
    assert "no pose reported" in capsys.readouterr().out
