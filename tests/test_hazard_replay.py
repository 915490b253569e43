"""Hazard: `autochair replay` moving a live chair. A recording holds drive commands, e-stop
"released" states, limits, odometry and scans; republished onto a bus where the drive chain
runs, they would act on the chair. Replay publishes into its own namespace by default
(replay/autochair/..., tests/test_namespaces.py); asked onto a chair's keys (here `--namespace
''`, a chair without a namespace) it refuses while a drive-chain service (gateway, pid) is alive
there, before the first message and at any moment during the replay; under another namespace
NS (every key as NS/...) where no service listens it publishes."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import msgspec
import pytest
import zenoh

from autochair.launcher import Launcher
from autochair.logger.replay import drive_chain_alive, refusal
from autochair.logger.writer import LoggerConfig, Recorder
from autochair.runtime.client import declare_alive
from autochair.runtime.config import ZenohSettings
from autochair.runtime.session import open_session
from autochair_msgs import keys
from tests.helpers import client_session, stop_process, wait_for
from tests.logger_samples import QUERY_SAMPLES, T0, samples

ENC = msgspec.msgpack.Encoder()


# --- pure parts ----------------------------------------------------------------------------------
def test_refusal_names_the_services_the_reason_and_the_way_out() -> None:
    assert drive_chain_alive(["odometry", "pid", "logger", "gateway"]) == ["gateway", "pid"]
    assert drive_chain_alive(["odometry", "logger"]) == []
    line = refusal(["pid", "gateway", "logger"])
    assert "\n" not in line
    assert "autochair/alive/gateway, autochair/alive/pid" in line and "logger" not in line
    for why in ("drive commands", "e-stop \"released\" states", "limits", "odometry", "scans"):
        assert why in line
    assert "--namespace NAME" in line


def isolated_session() -> zenoh.Session:
    return open_session(ZenohSettings(connect=[]))


def test_watch_sees_tokens_and_fails_closed_when_it_cannot_ask(
        monkeypatch: pytest.MonkeyPatch) -> None:
    from autochair.commands.replay import DriveChainWatch

    session = isolated_session()
    try:
        declare_alive(session, "odometry")
        quiet = DriveChainWatch(session)  # control: no drive chain, nothing to refuse
        assert not quiet.appeared.is_set() and not quiet.unsure
        quiet.close()
        pid = declare_alive(session, "pid")
        watch = DriveChainWatch(session)
        assert watch.appeared.is_set() and "autochair/alive/pid" in watch.refusal()
        watch.close()
        pid.undeclare()
        monkeypatch.setattr(DriveChainWatch, "QUERY_S", 0.0)  # a query that cannot finish
        blind = DriveChainWatch(session)
        assert blind.appeared.is_set() and blind.refusal().startswith(
            "cannot tell whether a drive-chain service is alive")
        assert "--namespace NAME" in blind.refusal()
        blind.close()
    finally:
        session.close()


# --- system ---------------------------------------------------------------------------------
def write_recording(path: Path, rounds: int, period_ns: int,
                    only: tuple[str, ...] = ()) -> list[tuple[str, bytes]]:
    """A recording made by the project's own writer: every logged key (or `only` these), one
    distinct message each per round. Returns (key, msgpack payload) in order."""
    rec = Recorder(LoggerConfig(path=str(path)), T0, 0.0)
    sent: list[tuple[str, bytes]] = []
    for i in range(rounds):
        # keys.JOYSTICK is no longer recorded, but older recordings hold it.
        joystick = {keys.JOYSTICK.key: QUERY_SAMPLES[keys.JOYSTICK.key]}
        for key, msg in {**samples(i), **joystick}.items():
            if only and key not in only:
                continue
            payload = ENC.encode(msg)
            assert rec.write(key, payload, T0 + i * period_ns)
            sent.append((key, payload))
    rec.finish()
    return sent


class Collector:
    """Every sample under a key expression, with its arrival time (monotonic)."""

    def __init__(self, session: zenoh.Session, expr: str) -> None:
        self.items: list[tuple[float, str, bytes]] = []
        self._lock = threading.Lock()
        self._sub = session.declare_subscriber(expr, self._on)

    def _on(self, s: zenoh.Sample) -> None:
        with self._lock:
            self.items.append((time.monotonic(), str(s.key_expr), s.payload.to_bytes()))

    def snapshot(self) -> list[tuple[float, str, bytes]]:
        with self._lock:
            return list(self.items)


def replay_cmd(hub: str, path: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "autochair.cli", "replay", str(path), "--connect", hub,
            "--quiet", *extra]


@pytest.mark.slow
def test_replay_refused_next_to_a_live_drive_chain_unless_namespaced(
        stack_factory: Callable[..., Launcher], hub: str, tmp_path: Path) -> None:
    path = tmp_path / "drive.mcap"
    sent = write_recording(path, rounds=10, period_ns=20_000_000)
    recorded = {payload for _, payload in sent}
    assert {keys.CMD_VEL.key, keys.ESTOP_STATE.key, keys.JOYSTICK.key, keys.SAFETY_LIMIT.key,
            keys.ODOM.key, keys.SCAN.key} <= {k for k, _ in sent}
    stack_factory(["sim", "gateway", "pid"])
    session = client_session(hub)
    try:
        live = Collector(session, f"{keys.PREFIX}/**")
        spaced = Collector(session, "x/**")
        # The subscriber sees the live bus (so silence below means nothing was published).
        wait_for(lambda: any(k == keys.JOYSTICK_OUT.key for _, k, _ in live.snapshot()), 10,
                 "live gateway output")
        refused = subprocess.run(replay_cmd(hub, path, "--namespace", ""), capture_output=True,
                                 text=True, timeout=30, stdin=subprocess.DEVNULL)
        assert refused.returncode == 2, refused.stderr
        lines = refused.stderr.strip().splitlines()
        assert len(lines) == 1, refused.stderr
        assert lines[0].startswith("autochair replay: error: drive-chain services alive")
        assert "autochair/alive/gateway, autochair/alive/pid" in lines[0]
        assert "--namespace NAME" in lines[0]
        # Positive control: under a namespace the same recording is published, every message,
        # byte for byte; the live keys get none of it.
        ok = subprocess.run(replay_cmd(hub, path, "--namespace", "x", "--rate", "4"),
                            capture_output=True, text=True, timeout=30, stdin=subprocess.DEVNULL)
        assert ok.returncode == 0, ok.stderr
        wait_for(lambda: len(spaced.snapshot()) >= len(sent), 10, "namespaced replay")
        assert [(k, b) for _, k, b in spaced.snapshot()] == [
            (f"x/{k}", b) for k, b in sent]
        leaked = [k for _, k, b in live.snapshot() if b in recorded]
        assert leaked == [], f"recorded messages reached live keys: {leaked[:5]}"
    finally:
        session.close()


@pytest.mark.slow
def test_replay_stops_when_a_drive_chain_service_appears(
        stack_factory: Callable[..., Launcher], hub: str, tmp_path: Path) -> None:
    path = tmp_path / "odom.mcap"
    sent = write_recording(path, rounds=200, period_ns=50_000_000, only=(keys.ODOM.key,))
    recorded = {payload for _, payload in sent}
    stack_factory([])  # the hub alone: no drive chain
    session = client_session(hub)
    proc = subprocess.Popen(replay_cmd(hub, path, "--namespace", ""), stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    token: zenoh.LivelinessToken | None = None
    try:
        got = Collector(session, keys.ODOM.key)
        # Positive control: with no drive chain alive a plain replay publishes as before.
        wait_for(lambda: len(got.snapshot()) >= 5, 15, "replay publishing")
        appeared = time.monotonic()
        token = declare_alive(session, "pid")  # a PID starts
        _, err = proc.communicate(timeout=10)
        exited = time.monotonic()
        assert proc.returncode == 2, err
        line = err.strip().splitlines()[-1]
        assert line.startswith("autochair replay: error: drive-chain service alive")
        assert "autochair/alive/pid" in line and "--namespace NAME" in line
        items = got.snapshot()
        assert all(b in recorded for _, _, b in items)
        assert 5 <= len(items) < len(sent) // 2
        after = [t - appeared for t, _, _ in items if t > appeared]
        # At 20 Hz a replay that kept going would publish one message every 50 ms.
        assert len(after) <= 1, after
        print(f"\nreplay stopped {exited - appeared:.3f} s after the PID's token appeared; "
              f"{len(after)} message(s) after it")
    finally:
        if token is not None:
            token.undeclare()
        stop_process(proc)
        session.close()
