"""deploy/ is generated from the process list: drift, coverage and `docker-compose config`."""

from __future__ import annotations

import json
import os
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
        assert p.script in services[p.name]["command"]  # type: ignore[operator]
        assert f"[program:{p.name}]" in conf
        unit = (DEPLOY / "systemd" / f"autochair-{p.name}.service").read_text()
        assert f"ExecStart={deploy.Paths().bin_dir}/{p.script}" in unit
        assert f"autochair-{p.name}.service" in target
        svc = services[p.name]
        assert svc["network_mode"] == "host" and svc["restart"] == "unless-stopped"
        assert svc["healthcheck"]["test"] == [  # type: ignore[index]
            "CMD", "autochair", "health", "--service", p.name]
        env = svc["environment"]
        assert env["AUTOCHAIR_CONNECT"] == "tcp/127.0.0.1:${AUTOCHAIR_HUB_PORT:-7447}"  # type: ignore[index]
        if p.name != "router":
            assert svc["depends_on"]["router"] == {  # type: ignore[index]
                "condition": "service_started"}  # peers retry the hub: no wait needed
        if p.hardware:  # on the chair: the device by its stable path; in `sim`: the sim's pty
            assert svc["profiles"] == ["chair"]
            assert services[f"sim-{p.name}"]["profiles"] == ["sim"]
        for h in p.hardware:
            var, by_id = deploy.COMPOSE_DEVICES[h]
            dev = deploy.CHAIR_VALUES[deploy.HARDWARE_PLACEHOLDER[h]]
            assert by_id.startswith("/dev/serial/by-id/")
            assert f"${{{var}:-{by_id}}}:{dev}" in svc["devices"]  # type: ignore[operator]
    assert "{" not in conf.replace("{}", "")  # every placeholder filled


def test_compose_profiles_volumes_and_the_tls_listener() -> None:
    doc = compose_doc()
    services = doc["services"]
    sims = {p.name for p in PROCESSES if p.sim_only}
    assert {n for n, s in services.items() if s.get("profiles") == ["sim"]} == sims | {
        f"sim-{p.name}" for p in PROCESSES if p.hardware}
    assert all("profiles" not in s for n, s in services.items()
               if n in {p.name for p in PROCESSES if not (p.sim_only or p.hardware)})
    router = services["router"]["command"]
    assert "tcp/127.0.0.1:${AUTOCHAIR_HUB_PORT:-7447},tls/${AUTOCHAIR_TLS_LISTEN:-0.0.0.0:7448}" \
        in router  # type: ignore[operator]
    assert "${AUTOCHAIR_CERTS:-./certs}:/etc/autochair/certs:ro" in services["router"][
        "volumes"]  # type: ignore[operator]
    # The latch and the recordings live on named volumes, where their placeholders point.
    assert "autochair-state:/var/lib/autochair/state" in services["estop"]["volumes"]  # type: ignore[operator]
    assert "autochair-recordings:/var/lib/autochair/recordings" in services["logger"][
        "volumes"]  # type: ignore[operator]
    assert "state_file=/var/lib/autochair/state/estop.json" in services["estop"]["command"]  # type: ignore[operator]
    for name in ("sim", "sim-gateway", "lidar-sim", "sim-lidar"):
        assert "autochair-sim-pts:/dev/pts" in services[name]["volumes"]  # type: ignore[operator]
    assert doc["volumes"]["autochair-sim-pts"]["driver_opts"]["type"] == "devpts"  # type: ignore[index]
    # Every service, the hub too, runs under the hung-process watchdog, as under supervisord.
    for name in ("pid", "router"):
        assert services[name]["command"][:5] == [  # type: ignore[index]
            "autochair-watchdog", "--timeout", str(deploy.WATCHDOG_TIMEOUT_S), "--",
            f"autochair-{name}"]


def test_dockerfile_takes_its_base_and_installs_offline_as_a_user() -> None:
    text = (DEPLOY / "Dockerfile").read_text()
    assert f"ARG BASE={deploy.PUBLIC_BASE}\n" in text and "FROM ${BASE}" in text
    assert text.count("pip install") == text.count("pip install -q --no-index") == 2
    assert "USER autochair" in text
    assert f"--uid {deploy.IMAGE_UID}" in text


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
    for p in PROCESSES:
        assert f"  {p.name}:" in out.stdout
    assert "/dev/serial/by-id/usb-Hokuyo_Data_Flex_for_USB_URG-Series_USB_Driver-if00:" \
        "/dev/ttyACM1" in out.stdout
    env = {"PATH": os.environ.get("PATH", ""), "AUTOCHAIR_ARDUINO": "/dev/serial/by-id/usb-x",
           "AUTOCHAIR_HUB_PORT": "17447"}
    out = subprocess.run([exe, "-f", str(DEPLOY / "docker-compose.yml"), "config"],
                         capture_output=True, text=True, timeout=60, env=env)
    assert out.returncode == 0, out.stderr
    assert "/dev/serial/by-id/usb-x:/dev/ttyACM0" in out.stdout
    assert "tcp/127.0.0.1:17447,tls/0.0.0.0:7448" in out.stdout
