"""Simulated URG-04LX ↔ lidar ingest (↔ mapping) as real processes on a private Zenoh hub."""

from __future__ import annotations

import itertools
import math
import os
import signal
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from autochair.launcher import free_port
from autochair.lidar.core import WRAP
from autochair_msgs import Health, LaserScan, keys
from tests.helpers import Recorder, Spawn, client_session, spawned, wait_for

pytestmark = pytest.mark.slow




@pytest.fixture
def spawn(tmp_path: Path) -> Iterator[tuple[str, Spawn]]:
    with spawned(tmp_path) as (hub, start):
        yield hub, start


def health_of(rec: Recorder, service: str) -> Health | None:
    for h in reversed(rec.messages()):
        if h.service == service:
            return h  # type: ignore[no-any-return]
    return None


def wait_health(rec: Recorder, service: str, ok: Callable[[Health], bool] = lambda h: True,
                timeout: float = 5.0) -> Health:
    def found() -> Health | None:
        h = health_of(rec, service)
        return h if h is not None and ok(h) else None

    h = wait_for(found, timeout, f"health of {service}")
    assert h is not None
    return h


def scans_lost(rec: Recorder, after_ns: int) -> tuple[int, int] | None:
    """(the ingest's dropped_scans, the simulator's skipped_scans) at one moment after
    `after_ns`, or None until there is one. A simulator stalled past a scan's slot skips it
    (a loaded machine): the ingest rightly counts that gap too, but the link lost nothing.
    The moment: the ingest's health between two of the simulator's with the same count, at
    least 0.5 s after the first (time for a scan in flight to be read), so every skip the
    ingest saw is in that count and nothing the ingest lost on its own can be."""
    sims = [(h.stamp_ns, h.counters.get("skipped_scans", 0)) for h in rec.messages()
            if h.service == "lidar-sim" and h.stamp_ns > after_ns]
    ingest = [(h.stamp_ns, h.counters.get("dropped_scans", 0)) for h in rec.messages()
              if h.service == "lidar"]
    for t0, skipped in sims:
        t1 = max(t for t, later in sims if later == skipped)  # (the counts only grow)
        for t, dropped in ingest:
            if t0 + 500_000_000 <= t <= t1:
                return dropped, skipped
    return None


def test_sim_to_ingest_over_pty(spawn: tuple[str, Spawn], tmp_path: Path) -> None:
    hub, start = spawn
    session = client_session(hub)
    try:
        scans = Recorder(session, keys.SCAN)
        tf = Recorder(session, keys.TF_STATIC)
        health = Recorder(session, keys.HEALTH)
        link = tmp_path / "lidar"
        # Boot the device clock 3 s before its 24-bit wrap so the run crosses it.
        start("autochair.sim.lidar.node", "--set", f"pty_link={link}",
              "--set", f"clock_start_ms={WRAP - 3000}")
        start("autochair.lidar.node", "--set", f"url={link}")
        wait_for(lambda: len(scans.messages()) >= 45, 30, "45 scans")
        msgs: list[LaserScan] = scans.messages()
        s = msgs[-1]
        assert len(s.ranges_m) == 682 and s.frame_id == "laser"
        assert s.angle_min_rad == pytest.approx((44 - 384) * 2 * math.pi / 1024)
        a = s.angle_min_rad + s.angle_increment_rad * np.arange(682)
        r = np.array(s.ranges_m)
        assert r[int(np.argmin(abs(a - math.pi / 2)))] == pytest.approx(1.1968, abs=0.05)
        assert r[int(np.argmin(abs(a + math.pi / 2)))] == pytest.approx(1.6032, abs=0.05)
        seqs = [m.scan_seq for m in msgs]
        assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))  # none lost on the way
        assert msgs[-1].device_time_ms > WRAP  # unwrapped across the 24-bit wrap
        stamps = [m.stamp_ns for m in msgs]
        assert all(b > a for a, b in itertools.pairwise(stamps))
        assert abs(stamps[-1] - time.time_ns()) < 1e9
        t = wait_for(tf.latest, 5, "chair→laser transform")
        assert (t.parent_frame_id, t.child_frame_id) == ("chair", "laser")
        assert (t.translation.x, t.translation.y, t.translation.z) == (0.8636, 0.2032, 0.3937)
        h = wait_health(health, "lidar")
        for bad in ("bad_sum", "bad_echo", "format_errors", "timeouts"):
            assert h.counters.get(bad, 0) == 0, (bad, h.counters)
        dropped, skipped = wait_for(lambda: scans_lost(health, stamps[-1]), 10,
                                    "a steady count of the simulator's skipped scans")
        assert dropped == skipped, f"{dropped - skipped} scans lost on the way ({h.counters})"
    finally:
        session.close()


def test_sim_to_ingest_over_tcp(spawn: tuple[str, Spawn]) -> None:
    hub, start = spawn
    session = client_session(hub)
    try:
        scans = Recorder(session, keys.SCAN)
        port = free_port()
        start("autochair.sim.lidar.node", "--set", f"tcp_port={port}")
        start("autochair.lidar.node", "--set", f"url=tcp://127.0.0.1:{port}")
        wait_for(lambda: len(scans.messages()) >= 10, 30, "10 scans over TCP")
        assert len(scans.latest().ranges_m) == 682
    finally:
        session.close()


def test_reconnect_after_unplug(spawn: tuple[str, Spawn], tmp_path: Path) -> None:
    hub, start = spawn
    session = client_session(hub)
    try:
        scans = Recorder(session, keys.SCAN)
        health = Recorder(session, keys.HEALTH)
        link = tmp_path / "lidar"
        sim = start("autochair.sim.lidar.node", "--set", f"pty_link={link}",
                    "--set", "unplug_s=2.0")
        start("autochair.lidar.node", "--set", f"url={link}")
        wait_for(lambda: len(scans.messages()) >= 5, 30, "first scans")
        os.kill(sim.pid, signal.SIGUSR1)
        wait_for(lambda: not os.path.lexists(link), 5, "the device to vanish")
        wait_for(lambda: os.path.lexists(link), 10, "the device to come back")
        back = time.monotonic()
        wait_for(lambda: scans.items[-1][0] > back, 10, "scans after the device returned")
        first = next(t for t, _ in scans.items if t > back)
        reconnect_s = first - back
        print(f"reconnect: first scan {reconnect_s:.3f} s after the device returned")
        assert reconnect_s < 2.5  # goal 2 s; margin for a loaded 2-core machine
        h = wait_health(health, "lidar", lambda x: x.counters.get("reconnects", 0) >= 1)
        # The unplugged device is retried with backoff, not in a storm (≤ ~2 s × 1/0.075 s).
        assert h.counters.get("connect_failures", 0) < 15, h.counters
    finally:
        session.close()


def test_40_scans_per_second_none_lost_with_mapping(spawn: tuple[str, Spawn],
                                                    tmp_path: Path) -> None:
    hub, start = spawn
    session = client_session(hub)
    try:
        scans = Recorder(session, keys.SCAN)
        grids = Recorder(session, keys.MAP_GRID)
        health = Recorder(session, keys.HEALTH)
        link = tmp_path / "lidar"
        start("autochair.sim.lidar.node", "--set", f"pty_link={link}",
              "--set", "scan_rate_hz=40")
        start("autochair.lidar.node", "--set", f"url={link}")
        start("autochair.mapping.node", "--set", "require_odom=false")
        wait_for(lambda: len(scans.messages()) >= 1, 30, "first scan")
        t0 = time.monotonic()
        wait_for(lambda: len(scans.messages()) >= 200, 30, "200 scans")
        rate = (len(scans.messages()) - 1) / (time.monotonic() - t0)
        msgs: list[LaserScan] = scans.messages()
        seqs = [m.scan_seq for m in msgs]
        assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))
        assert 30 < rate < 50, rate
        g = wait_for(grids.latest, 5, "a map")
        assert np.frombuffer(g.data, np.uint8).max() > 60
        dropped, skipped = wait_for(lambda: scans_lost(health, msgs[-1].stamp_ns), 10,
                                    "a steady count of the simulator's skipped scans")
        print(f"{skipped} scans skipped by the stalled simulator")
        assert dropped == skipped, f"{dropped - skipped} scans lost on the way"
    finally:
        session.close()


def test_the_map_leaves_out_the_returns_of_the_people_tracked(
        spawn: tuple[str, Spawn], tmp_path: Path) -> None:
    """The mapping service takes the control service's people (keys.PEOPLE) who have walked
    as not the map's: a report puts someone (first 0.6 m out from it: a walker,
    mapping.core.Walkers) against the default hallway's right wall 3 m ahead of the parked
    chair, and that stretch of wall stays out of the map while the wall 3 m further on is
    mapped (the positive control). The service maps nothing until odometry places its scans,
    which starts once the walker has been reported there. (Someone pacing left a trail of
    hits that closed a door's exit on the laser's map, H75.)"""
    import threading

    import msgspec

    from autochair.nav.field import GridMap
    from autochair_msgs import Odometry, People, TrackedPerson

    hub, start = spawn
    session = client_session(hub)
    stop, up = threading.Event(), threading.Event()
    try:
        grids = Recorder(session, keys.MAP_GRID)
        health = Recorder(session, keys.HEALTH, keys.HEALTH.for_service("mapping"))
        people, odom = (session.declare_publisher(k.key) for k in (keys.PEOPLE, keys.ODOM_SLOW))

        def feed() -> None:
            # The tracker's reports at 10 Hz: 0.6 m out till half a second after the service
            # is up, then against the wall; odometry at 50 Hz half a second after that.
            k, since_up = 0, 0
            while not stop.wait(0.02):
                now = time.time_ns()
                since_up += up.is_set()
                if k % 5 == 0:
                    people.put(msgspec.msgpack.encode(People(
                        stamp_ns=now, frame_id="odom", people=[TrackedPerson(
                            track_id=1, x_m=3.0, y_m=-1.4 if since_up > 25 else -0.8,
                            vx_mps=0.0, vy_mps=0.0, radius_m=0.25)])))
                if since_up > 50:
                    odom.put(msgspec.msgpack.encode(Odometry(
                        stamp_ns=now, x_m=0.0, y_m=0.0, yaw_rad=0.0, v_mps=0.0,
                        omega_radps=0.0)))
                k += 1

        threading.Thread(target=feed, daemon=True).start()
        link = tmp_path / "lidar"
        start("autochair.sim.lidar.node", "--set", f"pty_link={link}")
        start("autochair.lidar.node", "--set", f"url={link}")
        start("autochair.mapping.node")
        wait_for(health.latest, 30, "the mapping service up (subscribed)")
        up.set()

        def cells_near(x: float) -> int:
            gm = GridMap.from_msg(grids.latest())
            cx, cy = gm.centres()
            return int((gm.occupied & (np.abs(cx - x) < 0.2) & (np.abs(cy + 1.4) < 0.2)).sum())

        wait_for(lambda: (lambda h: h is not None and h.counters.get("scans_mapped", 0) >= 3)(
            health.latest()), 30, "3 scans mapped")
        since = time.time_ns()
        wait_for(lambda: (lambda g: g is not None and g.stamp_ns > since)(grids.latest()), 10,
                 "a map with them")
        assert cells_near(6.0) >= 4  # (the wall, mapped)
        assert cells_near(3.0) == 0, "the tracked walker's returns were mapped"
    finally:
        stop.set()
        session.close()
