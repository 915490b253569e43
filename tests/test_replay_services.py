"""Replay → services → same outputs: odometry re-run on a recording's encoder samples computes
exactly what it computed live."""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import msgspec
import pytest

from autochair.launcher import Launcher, free_port
from autochair.logger.reader import Recording
from autochair_msgs import EncoderSample, Odometry, keys
from tests.helpers import Recorder, Stream, client_session, make_stack, pid_ready, wait_for

pytestmark = pytest.mark.slow


def test_odometry_rerun_on_replayed_encoders_matches_the_recording(
        stack_factory: Callable[..., Launcher], hub: str, tmp_path: Path) -> None:
    rec_path = tmp_path / "run.mcap"
    live = stack_factory(["estop", "sim", "gateway", "odometry", "pid", "logger"],
                         record_path=str(rec_path))
    session = client_session(hub)
    try:
        odom = Recorder(session, keys.ODOM)
        wait_for(lambda: odom.latest(), 10, "odometry")
        pid_ready(session)
        stream = Stream.on(session, 0.4, 0.5)
        t0 = time.monotonic()
        while time.monotonic() - t0 < 3.0:  # an arc: both wheels, both signs of change
            stream.put()
            time.sleep(0.05)
        wait_for(lambda: abs(odom.latest().yaw_rad) > 0.2, 10, "the chair turning")
    finally:
        session.close()
    assert live.stop(), "live stack did not stop cleanly (logger must finish the file)"

    recording = Recording(str(rec_path))
    recorded: dict[int, Odometry] = {}
    n_enc = 0
    for m in recording.messages():
        if m.topic == keys.ODOM.key and not m.derived:
            o = msgspec.json.decode(m.data, type=Odometry)
            recorded[o.source_seq] = o
        elif m.topic == keys.ENCODERS.key and not m.derived:
            msgspec.json.decode(m.data, type=EncoderSample)
            n_enc += 1
    assert n_enc > 300 and len(recorded) > 300

    hub2 = f"tcp/127.0.0.1:{free_port()}"
    rerun = make_stack(["router", "odometry"], hub2, tmp_path / "rerun")
    rerun.start(ready_timeout_s=30)
    session = client_session(hub2)
    try:
        again = Recorder(session, keys.ODOM)
        proc = subprocess.run(
            [sys.executable, "-m", "autochair.cli", "replay", str(rec_path), "--rate", "2",
             "--keys", keys.ENCODERS.key, "--connect", hub2, "--quiet",
             "--namespace", ""],  # onto the keys of the re-run stack (no namespace)
            capture_output=True, text=True, timeout=60)
        assert proc.returncode == 0, proc.stderr
        wait_for(lambda: len(again.messages()) >= n_enc, 10, "re-run odometry outputs")
    finally:
        session.close()
        rerun.stop()
    replayed = {o.source_seq: o for o in again.messages()}
    common = sorted(set(recorded) & set(replayed))
    assert len(common) >= 0.95 * len(recorded)
    moved = 0
    for seq in common:
        a, b = recorded[seq], replayed[seq]
        assert (b.x_m, b.y_m, b.yaw_rad, b.distance_m) == pytest.approx(
            (a.x_m, a.y_m, a.yaw_rad, a.distance_m), abs=1e-9), seq
        assert (b.v_mps, b.omega_radps) == pytest.approx((a.v_mps, a.omega_radps), abs=1e-9)
        moved += a.distance_m > 0
    assert moved > 100  # the comparison covered real motion, not just a chair at rest
