"""deploy/ is generated from the process list: drift, coverage and `docker-compose config`."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

from autochair import deploy
from autochair.cli import main as cli
from autochair.processes import PROCESSES, Process

DEPLOY = Path(__file__).parent.parent / "deploy"


def compose_doc() -> dict[str, dict[str, dict[str, object]]]:
    text = (DEPLOY / "docker-compose.yml").read_text()
    return json.loads(text.split("\n", 1)[1])  # type: ignore[no-any-return]


def test_committed_deploy_files_match_the_process_list() -> None:
    assert deploy.drift(DEPLOY) == [], "run `autochair deploy generate`"
    assert cli(["deploy", "check"]) == 0


def test_every_deployed_process_is_in_every_file() -> None:
    procs = deploy.deployed()
    assert {p.name for p in procs} == {p.name for p in PROCESSES if not p.sim_only}
    services = compose_doc()["services"]
    assert next(iter(services)) == "router"
    conf = (DEPLOY / "supervisord.conf").read_text()
    target = (DEPLOY / "systemd" / "autochair.target").read_text()
    for p in procs:
        assert services[p.name]["command"][0] == p.script  # type: ignore[index]
        assert f"[program:{p.name}]" in conf
        unit = (DEPLOY / "systemd" / f"autochair-{p.name}.service").read_text()
        assert f"ExecStart={deploy.Paths().bin_dir}/{p.script}" in unit
        assert f"autochair-{p.name}.service" in target
        if p.name != "router":
            env = services[p.name]["environment"]
            assert env["AUTOCHAIR_CONNECT"] == "tcp/router:7447"  # type: ignore[index]
            assert services[p.name]["depends_on"]["router"] == {  # type: ignore[index]
                "condition": "service_healthy"}
        for h in p.hardware:
            dev = deploy.CHAIR_VALUES[deploy.HARDWARE_PLACEHOLDER[h]]
            assert f"{dev}:{dev}" in services[p.name]["devices"]  # type: ignore[operator]
    assert "{" not in conf.replace("{}", "")  # every placeholder filled


def test_a_new_process_row_shows_up_and_drift_is_caught(tmp_path: Path) -> None:
    extra = Process("extra", "autochair.extra", "autochair-extra", ("--set", "x={run_dir}"))
    files = deploy.files([*deploy.deployed(), extra])
    assert "autochair-extra --set x=/var/lib/autochair" in files["supervisord.conf"]
    assert "systemd/autochair-extra.service" in files
    deploy.write(tmp_path)
    (tmp_path / "systemd" / "autochair-gone.service").write_text("stale")
    (tmp_path / "supervisord.conf").write_text("edited by hand")
    assert sorted(deploy.drift(tmp_path)) == ["supervisord.conf",
                                              "systemd/autochair-gone.service"]
    assert cli(["deploy", "check", "--dir", str(tmp_path)]) == 2


def test_unknown_placeholder_is_a_clear_error() -> None:
    bad = Process("bad", "m", "autochair-bad", ("--set", "x={nowhere}"))
    with pytest.raises(deploy.DeployError, match=r"\{nowhere\}.*CHAIR_VALUES"):
        deploy.files([bad])


def test_compose_file_validates_with_docker_compose() -> None:
    exe = shutil.which("docker-compose")  # Debian's v1 validates without a Docker daemon
    if exe is None:
        pytest.skip("docker-compose missing: run ./dev test as root, or "
                    "apt-get install -y docker-compose")
    out = subprocess.run([exe, "-f", str(DEPLOY / "docker-compose.yml"), "config"],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    for p in deploy.deployed():
        assert f"  {p.name}:" in out.stdout
    assert "/dev/ttyACM0:/dev/ttyACM0" in out.stdout
