"""Two simulated chairs on ONE hub, each a stack from the process list in its own namespace
($AUTOCHAIR_CHAIR, as `autochair up --chair NAME` gives it): driven independently (chair A
forward, chair B turning in place), each recorded alone by its own logger, and `autochair
status` lists both."""

from __future__ import annotations

import itertools
import json
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import TypeVar

import msgspec
import pytest
import zenoh

from autochair.launcher import Launcher
from autochair.logger.reader import Recording
from autochair.runtime.client import open_client
from autochair.runtime.config import ENV_CHAIR
from autochair_msgs import Odometry, VelocityCommand, keys
from tests.helpers import Recorder, Stream, make_stack, pid_ready, wait_for

pytestmark = pytest.mark.slow
T = TypeVar("T", bound=msgspec.Struct)

STACK = ["estop", "sim", "gateway", "odometry", "pid", "logger"]
CHAIRS = {"chair-a": (0.4, 0.0), "chair-b": (0.0, 0.6)}  # (v m/s, ω rad/s) each is driven at


def recorded(path: Path, key: str, type_: type[T]) -> list[T]:
    return [msgspec.json.decode(m.data, type=type_) for m in Recording(str(path)).messages()
            if m.topic == key and not m.derived]


def test_two_chairs_on_one_hub_driven_and_recorded_apart(hub: str, tmp_path: Path) -> None:
    stacks: dict[str, Launcher] = {}
    sessions: dict[str, zenoh.Session] = {}
    records = {c: tmp_path / f"{c}.mcap" for c in CHAIRS}
    try:
        for i, chair in enumerate(CHAIRS):  # the first stack brings the hub; the second joins
            stack = make_stack((["router"] if i == 0 else []) + STACK, hub, tmp_path / chair,
                               record_path=str(records[chair]))
            stack.env[ENV_CHAIR] = chair
            stacks[chair] = stack
            stack.start(ready_timeout_s=30)
        plain = open_client(hub, chair="")  # outside every chair
        sessions[""] = plain
        leaked: list[str] = []  # anything on un-namespaced keys
        plain.declare_subscriber(f"{keys.PREFIX}/**", lambda s: leaked.append(str(s.key_expr)))
        for chair in CHAIRS:
            sessions[chair] = open_client(hub, chair=chair)
        odom = {c: Recorder(sessions[c], keys.ODOM) for c in CHAIRS}
        status = subprocess.Popen(
            [sys.executable, "-m", "autochair.cli", "status", "--json", "--connect", hub],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, stdin=subprocess.DEVNULL)
        for chair in CHAIRS:
            pid_ready(sessions[chair])
        streams = {c: Stream.on(sessions[c], v, w, source=f"test-{c}")
                   for c, (v, w) in CHAIRS.items()}

        def moved() -> bool:
            for s in streams.values():
                s.put()
            a, b = odom["chair-a"].latest(), odom["chair-b"].latest()
            time.sleep(0.05)  # 20 Hz command streams (pacing, not synchronisation)
            return a is not None and b is not None and a.x_m > 0.5 and abs(b.yaw_rad) > 0.8

        wait_for(moved, 20, "chair A 0.5 m forward and chair B turned 0.8 rad", interval=0)
        out, err = status.communicate(timeout=30)
        assert status.returncode == 0, err
        seen = json.loads(out)
        for chair in CHAIRS:
            for name in STACK:
                entry = seen[f"{chair}/{name}"]
                assert entry["chair"] == chair and entry["service"] == name and entry["alive"]
        assert {e["chair"] for e in seen.values()} == set(CHAIRS)  # nothing un-namespaced
        assert leaked == []  # no chair's key is un-namespaced
        a, b = odom["chair-a"].latest(), odom["chair-b"].latest()
        assert abs(a.yaw_rad) < 0.05 and abs(b.x_m) < 0.05 and abs(b.y_m) < 0.05
        text = subprocess.run(
            [sys.executable, "-m", "autochair.cli", "status", "--connect", hub, "--chair",
             "chair-b"], capture_output=True, text=True, timeout=30, stdin=subprocess.DEVNULL)
        assert text.returncode == 0, text.stderr
        assert text.stdout.splitlines()[0] == f"chair chair-b: {len(STACK)} services alive"
    finally:
        for s in sessions.values():
            s.close()
        clean = {c: stacks[c].stop() for c in reversed(stacks)}  # the hub's stack last
    assert all(clean.values()), clean  # (the loggers finished their files)

    for chair, (v, w) in CHAIRS.items():
        cmds = recorded(records[chair], keys.CMD_VEL.key, VelocityCommand)
        assert cmds, chair
        assert {(c.source, c.v_mps, c.omega_radps) for c in cmds} == {(f"test-{chair}", v, w)}
        poses = recorded(records[chair], keys.ODOM.key, Odometry)
        assert len(poses) > 200, chair
        xs = [p.x_m for p in poses]
        yaws = [abs(p.yaw_rad) for p in poses]
        if chair == "chair-a":  # forward motion only
            assert max(xs) > 0.5 and max(yaws) < 0.05 and max(abs(p.y_m) for p in poses) < 0.05
        else:  # turning in place only
            assert max(yaws) > 0.8 and max(abs(x) for x in xs) < 0.05
        # One chair's odometry, not two interleaved: its encoder sequence only moves forward.
        seqs = [p.source_seq for p in poses]
        back = sum(1 for s0, s1 in itertools.pairwise(seqs) if (s1 - s0) % 65536 > 32768)
        assert back == 0, (chair, back)


def test_up_chair_and_join_put_two_chairs_on_one_hub(tmp_path: Path) -> None:
    """`autochair up --chair a` brings the hub; `autochair up --join --chair b` joins it; every
    process each starts is in its chair (status lists both), and each stops cleanly."""
    from autochair.launcher import free_port
    from tests.helpers import stop_process

    hub = f"tcp/127.0.0.1:{free_port()}"
    procs: dict[str, subprocess.Popen[str]] = {}
    lines: dict[str, list[str]] = {}

    def up(chair: str, *extra: str) -> None:
        procs[chair] = p = subprocess.Popen(
            [sys.executable, "-m", "autochair.cli", "up", "--sim", "--only", "estop,odometry",
             "--hub", hub, "--no-record", "--chair", chair, "--run-dir",
             str(tmp_path / chair), "--state-dir", str(tmp_path / "state" / chair), *extra],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            stdin=subprocess.DEVNULL)
        out: list[str] = []
        lines[chair] = out

        def read() -> None:
            assert p.stdout is not None
            out.extend(ln.rstrip() for ln in p.stdout)

        threading.Thread(target=read, daemon=True).start()
        wait_for(lambda: any("all up as chair " + chair in ln for ln in out)
                 or p.poll() is not None, 60, f"`up --chair {chair}`")
        assert p.poll() is None, out

    try:
        up("a")
        up("b", "--join")
        status = subprocess.run(
            [sys.executable, "-m", "autochair.cli", "status", "--json", "--connect", hub],
            capture_output=True, text=True, timeout=30, stdin=subprocess.DEVNULL)
        assert status.returncode == 0, status.stderr
        alive = {k for k, v in json.loads(status.stdout).items() if v["alive"]}
        assert alive == {"a/estop", "a/odometry", "b/estop", "b/odometry"}
        for chair in ("b", "a"):  # the joined chair first: the hub is a's
            procs[chair].send_signal(signal.SIGTERM)
            assert procs[chair].wait(timeout=30) == 0, lines[chair][-10:]
    finally:
        for p in procs.values():
            stop_process(p)
