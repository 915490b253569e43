"""Foxglove's Teleop panel drives the simulated chair through `autochair foxglove`.

The panel is scripted with a real Foxglove client (node, @foxglove/ws-protocol:
tests/js/foxglove_teleop.js). The chair's hub is the generated TLS + access-control profile
(mutual TLS for laptops), so the bridge publishes with its laptop's identity: a drive laptop's
bridge drives, a view-only laptop's is refused by the hub.
Goals measured from the recording (printed with -s): no gap in the drive command while the
panel publishes, the stop after it stops, and no velocity step beyond the teleop ramp.
"""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from autochair import deploy
from autochair.commands.certs import make_all
from autochair.commands.teleop_core import TeleopConfig
from autochair.launcher import Launcher, free_port
from autochair.runtime.client import Publisher
from autochair_msgs import CommandOwner, VelocityCommand, keys
from tests.helpers import JS, Recorder, client_session, npm_ready, pid_ready, stop_process, wait_for

pytest.importorskip("foxglove", reason="foxglove-sdk (the `remote` extra) missing")
pytestmark = pytest.mark.slow

DRIVE_CHAIN = ["estop", "sim", "gateway", "odometry", "pid"]
CFG = TeleopConfig()
STALE_S = 0.3  # the velocity PID's stale-command timeout ([stale] desired_velocity_s)
# Stamps are taken when a command is published, the core's dt when it ticks: scheduling
# jitter between the two may make a step at the ramp's limit look this much steeper.
STEP_TOLERANCE = 1.3


class TlsHub:
    """Certificates for alice (drive) and bob (view), and the chair's router profile (TLS for
    laptops, default-deny ACL) given to the stack's router through AUTOCHAIR_CONFIG."""

    def __init__(self, tmp: Path, monkeypatch: pytest.MonkeyPatch) -> None:
        self.certs = tmp / "certs"
        make_all(self.certs, [], [("alice", "drive"), ("bob", "view")], "tls/127.0.0.1:1")
        self.tls = f"tls/127.0.0.1:{free_port()}"
        profile = tmp / "chair.json5"
        profile.write_text(json.dumps(deploy.chair_zenoh(str(self.certs), [self.tls])))
        toml = tmp / "chair.toml"
        toml.write_text(f'[router]\nconfig_file = "{profile}"\nlisten = ["{self.tls}"]\n')
        monkeypatch.setenv("AUTOCHAIR_CONFIG", str(toml))


class BridgeProcess:
    """`autochair foxglove` as a laptop: its output lines collected as they come."""

    def __init__(self, hub: TlsHub, laptop: str, *extra: str) -> None:
        self.lines: list[str] = []
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "autochair.cli", "foxglove", "--zenoh-config",
             str(hub.certs / f"{laptop}.json5"), "--connect", hub.tls, "--port", "0", *extra],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
            text=True)
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line.rstrip())

    def line(self, text: str, timeout: float = 15) -> str:
        def found() -> str | None:
            if self.proc.poll() is not None and not any(text in x for x in self.lines):
                pytest.fail(f"the bridge exited: {self.lines}")
            return next((x for x in self.lines if text in x), None)

        return wait_for(found, timeout, f"bridge output {text!r}")

    @property
    def url(self) -> str:
        return self.line("Foxglove bridge on ").split()[3]

    def stop(self) -> None:
        stop_process(self.proc)
        self._reader.join(timeout=5)


@pytest.fixture
def tls_hub(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> TlsHub:
    return TlsHub(tmp_path, monkeypatch)


@pytest.fixture
def bridges() -> Iterator[Callable[..., BridgeProcess]]:
    started: list[BridgeProcess] = []

    def start(hub: TlsHub, laptop: str, *extra: str) -> BridgeProcess:
        b = BridgeProcess(hub, laptop, *extra)
        started.append(b)
        return b

    try:
        yield start
    finally:
        for b in started:
            b.stop()


def panel(url: str, schedule: list[dict[str, float]], rate_hz: float = 20.0) -> dict[str, Any]:
    """Run the scripted Teleop panel; its per-hold send times (Unix ms)."""
    r = subprocess.run(["node", str(JS / "foxglove_teleop.js"), url, "autochair/cmd/teleop",
                        str(rate_hz), json.dumps(schedule)],
                       capture_output=True, text=True, timeout=60)
    out: dict[str, Any] = json.loads(r.stdout or "{}")
    assert out and "error" not in out, (out, r.stderr)
    return out


class Chair:
    """The test's own view of the chair: a services identity on the plain TCP hub."""

    def __init__(self, hub: str) -> None:
        self.session = client_session(hub)
        self.cmds = Recorder(self.session, keys.TELEOP)
        self.pid = Recorder(self.session, keys.PID_STATUS)
        self.truth = Recorder(self.session, keys.SIM_TRUTH)
        wait_for(self.truth.latest, 15, "ground truth")

    def handed_to_teleop(self) -> bool:
        st = self.pid.latest()
        return st is not None and "handed to teleop" in st.inhibit

    def close(self) -> None:
        self.session.close()


def stream_figures(cmds: list[VelocityCommand], hold: dict[str, float]) -> dict[str, float]:
    """One hold of the panel against the commands of its stream: gap, stop, steps."""
    first_ns, last_ns = hold["first"] * 1e6, hold["last"] * 1e6
    mine = [c for c in cmds if first_ns <= c.stamp_ns <= last_ns + 1e9]
    moving = [c for c in mine if (c.v_mps, c.omega_radps) != (0.0, 0.0)]
    assert moving, "no command while the panel published"
    starts = {c.stream_start_ns for c in moving}
    assert len(starts) == 1, "one hold must be one command stream"
    zero = next(c for c in mine if c.stamp_ns > moving[-1].stamp_ns)
    assert (zero.v_mps, zero.omega_radps) == (0.0, 0.0) and zero.stream_start_ns in starts
    sent = [*moving, zero]
    gaps = [(b.stamp_ns - a.stamp_ns) / 1e9 for a, b in itertools.pairwise(sent)]
    # The ramp: per step at most accel·dt while speeding up, decel·dt while slowing down
    # (dt between the commands' stamps; the core bounds it by 0.1 s). The stop itself is one
    # zero by design, so it is not a step of the stream. A ratio of 1 is the ramp's own slope.
    ratios = []
    for a, b in itertools.pairwise(moving):
        dt = min((b.stamp_ns - a.stamp_ns) / 1e9, 0.1)
        for x0, x1, up, down in ((a.v_mps, b.v_mps, CFG.accel_mps2, CFG.decel_mps2),
                                 (a.omega_radps, b.omega_radps, CFG.omega_accel_radps2,
                                  CFG.omega_decel_radps2)):
            rate = up if abs(x1) > abs(x0) and x0 * x1 >= 0 else down
            ratios.append(abs(x1 - x0) / (rate * dt))
    worst = max(ratios, default=0.0)
    beyond = sum(r > STEP_TOLERANCE for r in ratios)
    return {"first_cmd_after_press_s": (moving[0].stamp_ns - first_ns) / 1e9,
            "max_gap_s": max(gaps), "stop_after_release_s": (zero.stamp_ns - last_ns) / 1e9,
            "v_first": moving[0].v_mps, "v_max": max(c.v_mps for c in moving),
            "worst_step_vs_ramp": worst, "steps_beyond_ramp": float(beyond),
            "commands": float(len(sent)), "stream_start_ns": float(starts.pop()),
            "zero_ns": float(zero.stamp_ns)}


def test_teleop_panel_drives_while_it_publishes_and_stops_when_it_stops(
        stack_factory: Callable[..., Launcher], hub: str, tls_hub: TlsHub,
        bridges: Callable[..., BridgeProcess]) -> None:
    npm_ready()
    stack_factory(DRIVE_CHAIN)
    chair = Chair(hub)
    try:
        pid_ready(chair.session)
        bridge = bridges(tls_hub, "alice", "--take-over")
        url = bridge.url
        bridge.line("link to the chair's velocity PID ok")
        wait_for(chair.handed_to_teleop, 10, "the drive handed to teleop by the bridge")
        out = panel(url, [{"hold": 2.0, "v": 0.4}, {"idle": 1.2}, {"hold": 1.0, "v": 0.4},
                          {"idle": 1.0}])
        assert out["serverInfo"]["supportedEncodings"] == ["json"]
        cmds = chair.cmds.messages()
        figs = [stream_figures(cmds, h) for h in out["holds"]]
        for i, f in enumerate(figs):
            print(f"hold {i + 1}: " + ", ".join(f"{k} {v:.3f}" for k, v in f.items()
                                                if not k.endswith("_ns")))
            assert f["first_cmd_after_press_s"] < 0.25  # the 2nd message confirms the hold
            assert f["max_gap_s"] < 2.0 / CFG.rate_hz, "a gap in the drive command"
            assert f["stop_after_release_s"] <= 0.3
            assert f["steps_beyond_ramp"] == 0, "a step beyond the ramp"
            assert f["v_first"] <= CFG.accel_mps2 * 0.1 + 1e-9  # a press starts from rest
        assert figs[1]["stream_start_ns"] > figs[0]["zero_ns"], "a new hold, a new stream"
        assert figs[0]["v_max"] == pytest.approx(0.4)  # the panel's 0.4 m/s, under the cap
        # The PID obeyed the stream throughout (no stale stop while held), and stopped
        # obeying within deadman + tick + its stale timeout of the release.
        status = [(m.stamp_ns, m) for m in chair.pid.messages()]
        for h, f in zip(out["holds"], figs, strict=True):
            on = [m for t, m in status
                  if h["first"] * 1e6 + 0.3e9 <= t <= h["last"] * 1e6]
            assert on and all(m.active for m in on), "the PID stopped obeying mid-hold"
            off = next(t for t, m in status if t > f["zero_ns"] and (
                not m.active or m.v_desired_mps == 0.0))  # (the test ran on for 1 s since)
            pid_stop = (off - h["last"] * 1e6) / 1e9
            print(f"PID desired zero or inactive {pid_stop:.3f} s after the release")
            assert pid_stop <= CFG.deadman_s + 1.0 / CFG.rate_hz + STALE_S
        truth = [(t, m.v_mps) for t, m in chair.truth.items]
        assert max(v for _, v in truth) > 0.3, "the simulated chair did not drive"
        # and it came to rest after each hold
        wait_for(lambda: abs(chair.truth.latest().v_mps) < 0.01, 5, "the chair at rest")
        assert bridge.line("stream 2 began")
    finally:
        chair.close()


def test_a_view_only_laptop_cannot_drive_through_the_panel(
        stack_factory: Callable[..., Launcher], hub: str, tls_hub: TlsHub,
        bridges: Callable[..., BridgeProcess]) -> None:
    npm_ready()
    stack_factory(DRIVE_CHAIN)
    chair = Chair(hub)
    try:
        pid_ready(chair.session)
        # The drive is already teleop's: only the identity can refuse the panel now.
        owner = Publisher(chair.session, keys.CMD_OWNER)

        def handed() -> bool:
            owner.put(CommandOwner(stamp_ns=time.time_ns(), owner="teleop", by="test"))
            return chair.handed_to_teleop()

        wait_for(handed, 10, "the drive handed to teleop")
        viewer = bridges(tls_hub, "bob")
        url = viewer.url
        viewer.line("link to the chair's velocity PID ok")  # bob sees the chair ...
        out = panel(url, [{"hold": 1.5, "v": 0.4}, {"idle": 0.5}])
        assert out["holds"][0]["n"] >= 25
        assert viewer.line("stream 1 began")  # ... and its bridge tried to drive
        assert chair.cmds.messages() == [], "a view-only laptop's command reached the chair"
        assert max(abs(m.v_mps) for m in chair.truth.messages()) < 0.01
        assert not any(m.active for m in chair.pid.messages())
        # Positive control: the same panel through a drive laptop's bridge drives.
        driver = bridges(tls_hub, "alice")
        url = driver.url
        driver.line("link to the chair's velocity PID ok")
        panel(url, [{"hold": 1.0, "v": 0.4}, {"idle": 0.5}])
        assert any(c.v_mps > 0 for c in chair.cmds.messages())
        assert max(m.v_mps for m in chair.truth.messages()) > 0.1
    finally:
        chair.close()


def test_the_bridge_refuses_teleop_limits_beyond_the_pids_caps(
        stack_factory: Callable[..., Launcher], hub: str) -> None:
    stack_factory(["estop", "pid"])
    r = subprocess.run([sys.executable, "-m", "autochair.cli", "foxglove", "--connect", hub,
                        "--port", "0", "--max-v", "2.0"], capture_output=True, text=True,
                       timeout=30, stdin=subprocess.DEVNULL)
    assert r.returncode == 2 and "exceed the velocity PID's caps" in r.stderr
