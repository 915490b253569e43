"""System test of autochair-sim: a real process, a real pty, real Zenoh on loopback."""

from __future__ import annotations

import itertools
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import serial
import zenoh

from autochair.launcher import free_port
from autochair.protocol import arduino as proto
from autochair.runtime.client import request
from autochair_msgs import keys
from autochair_msgs.sim import SimFault, SimFaultReply
from tests.helpers import Recorder, session_when_up, stop_process, wait_for


@pytest.fixture
def sim(tmp_path: Path) -> Iterator[tuple[zenoh.Session, Path, subprocess.Popen[bytes]]]:
    hub = f"tcp/127.0.0.1:{free_port()}"
    link = tmp_path / "arduino"
    procs: list[subprocess.Popen[bytes]] = []
    session: zenoh.Session | None = None
    try:
        procs.append(subprocess.Popen([sys.executable, "-m", "autochair.router.node",
                                       "--listen", hub]))
        session = session_when_up(hub)  # the hub is up before the sim joins it
        procs.append(subprocess.Popen([sys.executable, "-m", "autochair.sim.chair.node",
                                       "--connect", hub, "--set", f"pty_link={link}"]))
        yield session, link, procs[-1]
    finally:
        if session is not None:
            session.close()
        for p in reversed(procs):
            stop_process(p)


def _read_frames(port: serial.Serial, seconds: float) -> list[proto.Frame]:
    dec = proto.FrameDecoder()
    frames: list[proto.Frame] = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        frames += dec.feed(port.read(4096))
    assert dec.stats.bad_frames == 0
    return frames


@pytest.mark.slow
def test_sim_node_telemetry_truth_and_unplug(
        sim: tuple[zenoh.Session, Path, subprocess.Popen[bytes]]) -> None:
    session, link, proc = sim
    truth = Recorder(session, keys.SIM_TRUTH)
    wait_for(link.exists, 20, "pty link")
    with serial.Serial(str(link), timeout=0.05) as port:
        port.reset_input_buffer()
        frames = _read_frames(port, 2.0)
        tel = [f for f in frames if isinstance(f, proto.Telemetry)]
        # 2 s at the key table's rate; generous bounds for a busy 2-core machine.
        n = 2.0 * keys.DRIVE_RATE_HZ
        assert 0.625 * n <= len(tel) <= 1.125 * n, len(tel)
        assert all(proto.seq_gap(a.seq, b.seq) == 0 for a, b in itertools.pairwise(tel))
        # Drive: after boot, an enabled forward command moves the chair (ground truth).
        seq = 0
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            seq += 1
            port.write(proto.encode(proto.Command(seq, tel[-1].seq, 3200, 2500,
                                                  proto.FL_ENABLE)))
            time.sleep(0.02)  # the host's own command rate, not synchronisation
            last = truth.latest()
            if last is not None and last.x_m > 0.05:
                break
        last = truth.latest()
        assert last is not None and last.x_m > 0.05 and last.longitudinal_v == 3.2
    # Fault: unplug for 1 s -> the link disappears, then comes back and still talks.
    answer = request(session, keys.SIM_FAULT, SimFault(kind="unplug", duration_s=1.0),
                     SimFaultReply)
    assert answer.ok
    wait_for(lambda: not link.exists(), 5, "link removed")
    wait_for(link.exists, 10, "link recreated")
    with serial.Serial(str(link), timeout=0.05) as port:
        assert len(_read_frames(port, 0.5)) > 20
    assert proc.poll() is None
    n = len(truth.messages())
    wait_for(lambda: len(truth.messages()) > n + 20, 5, "more ground truth")
