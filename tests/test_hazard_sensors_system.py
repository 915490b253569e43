"""Sensors fail closed, end to end: a blinded laser stops the chair from driving forward.

The whole simulated drive chain with the simulated URG-04LX, its ingest and the safety monitor
(the launcher makes the PID require the limit because the stack runs "safety"). The lidar
simulator's test hook BLIND_SIGNAL (SIGRTMIN) blinds it: every beam reports error code 1 ("no
return within DMAX") while the link and the protocol stay healthy, which used to read as a
clear path.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from autochair.launcher import Launcher
from autochair.runtime.client import Publisher
from autochair.sim.lidar.node import BLIND_SIGNAL
from autochair_msgs import Health, LaserScan, Odometry, SafetyLimit, VelocityCommand, keys
from tests.helpers import Recorder, Spawn, client_session, spawned, stop_process, wait_for

pytestmark = pytest.mark.slow

STACK = ["estop", "sim", "gateway", "odometry", "pid", "lidar-sim", "lidar", "safety"]


def drive(pub: Publisher, truth: Recorder, v: float, seconds: float,
          until_moved_m: float = float("inf")) -> tuple[float, float]:
    """Command `v` forward at 20 Hz as ONE new stream (begun now) for up to `seconds` or until
    the chair has moved `until_moved_m`; returns (x at the start, largest x seen)."""
    start_ns = time.time_ns()
    x0 = truth.latest().x_m
    x_max = x0
    t0 = time.monotonic()
    while time.monotonic() - t0 < seconds:
        pub.put(VelocityCommand(stamp_ns=time.time_ns(), v_mps=v, omega_radps=0.0,
                                source="test", stream_start_ns=start_ns))
        latest = truth.latest()
        x_max = max(x_max, latest.x_m)
        if x_max - x0 > until_moved_m:
            break
        time.sleep(0.05)  # the 20 Hz rate of the command stream itself, not a sync
    for _ in range(3):  # and stop it
        pub.put(VelocityCommand(stamp_ns=time.time_ns(), v_mps=0.0, omega_radps=0.0,
                                source="test", stream_start_ns=start_ns))
    return x0, max(x_max, truth.latest().x_m)


def test_blinded_laser_does_not_drive_forward(stack_factory: Callable[..., Launcher],
                                              hub: str) -> None:
    launcher = stack_factory(STACK)
    pid = launcher.pid("lidar-sim")
    assert pid is not None
    session = client_session(hub)
    try:
        truth = Recorder(session, keys.SIM_TRUTH)
        limits = Recorder(session, keys.SAFETY_LIMIT)
        health = Recorder(session, keys.HEALTH)
        pub = Publisher(session, keys.CMD_VEL)

        def safety_detail(text: str) -> Health | None:
            return next((h for h in reversed(health.messages())
                         if h.service == "safety" and text in h.detail), None)

        # The hallway start is clear: forward allowed from the scans.
        wait_for(lambda: truth.latest() and limits.latest()
                 and limits.latest().v_max_fwd_mps > 0.5, 30, "scan-based limits, path clear")
        h = wait_for(lambda: safety_detail("rear unseen"), 5, "safety health on the rear")
        print(f"safety health: {h.detail}")
        assert "rear unseen: autonomy may not reverse" in h.detail
        assert "|ω| ≤ 0.35 rad/s for the unseen footprint (R 0.85 m" in h.detail
        assert limits.latest().v_max_rev_autonomy_mps == 0.0

        os.kill(pid, BLIND_SIGNAL)  # blind the laser
        blind = wait_for(lambda: next((m for m in reversed(limits.messages())
                                       if "blind ahead" in m.reason), None), 5,
                         "a 'blind ahead' limit")
        print(f"blinded: {blind}")
        assert blind.v_max_fwd_mps == 0.0 and blind.v_max_rev_autonomy_mps == 0.0
        assert "blind ahead: 0 % valid beams" in blind.reason
        h = wait_for(lambda: safety_detail("blind ahead"), 5, "safety health: blind")
        assert h.state == "degraded" and h.counters.get("blind:fwd", 0) > 0
        x0, x_max = drive(pub, truth, 0.5, 3.0)
        print(f"blinded: commanded 0.5 m/s for 3 s, moved {x_max - x0:+.3f} m")
        assert x_max - x0 <= 0.02, f"the chair drove {x_max - x0:.3f} m with a blind laser"
        assert all(m.v_max_fwd_mps == 0.0 for t, m in limits.items[-20:])

        # Positive control, same test: sight back, a NEW stream drives the chair forward.
        os.kill(pid, BLIND_SIGNAL)
        wait_for(lambda: (m := limits.latest()) and m.v_max_fwd_mps > 0.5
                 and "blind" not in m.reason, 5, "the limit clear again")
        x1, x_max = drive(pub, truth, 0.5, 8.0, until_moved_m=0.25)
        print(f"un-blinded: moved {x_max - x1:+.3f} m")
        assert x_max - x1 > 0.2, f"with sight back the chair moved only {x_max - x1:.3f} m"
    finally:
        session.close()


@pytest.fixture
def spawn(tmp_path: Path) -> Iterator[tuple[str, Spawn]]:
    with spawned(tmp_path) as (hub, start):
        yield hub, start


def test_laser_mount_mismatch_stops_until_they_agree(spawn: tuple[str, Spawn],
                                                     tmp_path: Path) -> None:
    """The ingest announces the laser 9 cm further forward than the monitor's [chair] says:
    every limit is a stop, and health says why; with the same mount again, limits recover."""
    hub, start = spawn
    link = str(tmp_path / "lidar")
    session = client_session(hub)
    try:
        limits = Recorder(session, keys.SAFETY_LIMIT)
        health = Recorder(session, keys.HEALTH)
        clears = Recorder(session, keys.ESTOP_CLEAR)
        asserts = Recorder(session, keys.ESTOP_ASSERT)
        start("autochair.sim.lidar.node", "--set", f"pty_link={link}")
        start("autochair.safety.node")
        wrong = start("autochair.lidar.node", "--set", f"url={link}",
                      "--set", "chair.laser_x_m=0.95")
        stop = wait_for(lambda: next((m for m in reversed(limits.messages())
                                      if m.reason.startswith("laser mount mismatch")), None),
                        20, "a mount-mismatch stop")
        print(stop)
        assert (stop.v_max_fwd_mps, stop.v_max_rev_mps, stop.omega_max_radps) == (0, 0, 0)
        assert "tf x 0.9500 m vs [chair] laser_x_m 0.8636 m" in stop.reason
        h = wait_for(lambda: next((m for m in reversed(health.messages())
                                   if m.service == "safety" and "mismatch" in m.detail), None),
                     5, "safety health naming the mismatch")
        assert h.state == "degraded" and h.counters.get("mount_mismatch", 0) >= 1
        n = len(limits.messages())
        wait_for(lambda: len(limits.messages()) > n + 10, 5, "ten more limits")
        assert all(m.v_max_fwd_mps == 0.0 for m in limits.messages()[n:])  # held, every scan
        # Positive control: the ingest with the [chair] mount; the monitor drives again.
        stop_process(wrong)
        start("autochair.lidar.node", "--set", f"url={link}")
        wait_for(lambda: (m := limits.latest()) and m.v_max_fwd_mps > 0.5
                 and "mismatch" not in m.reason, 20, "limits from the scan again")
        print(limits.latest())
        # A monitor that starts clears a cause it may have left (on the clear key, never on
        # the assert key, where active=False would latch as a button press).
        assert any(m.source == "safety" and not m.active for m in clears.messages())
        assert asserts.messages() == []
    finally:
        session.close()


def test_a_late_scan_is_a_stop(spawn: tuple[str, Spawn]) -> None:
    """H38: scans that arrive late (a backlog after a stall) show the world as it was; the
    monitor judges them by their own stamp: a stop with the reason, open again when fresh."""
    hub, start = spawn
    session = client_session(hub)
    try:
        limits = Recorder(session, keys.SAFETY_LIMIT)
        start("autochair.safety.node")
        pub = Publisher(session, keys.SCAN)
        n = 682
        inc = math.radians(240) / (n - 1)

        def scan(age_s: float) -> None:
            pub.put(LaserScan(stamp_ns=time.time_ns() - round(age_s * 1e9), frame_id="laser",
                              angle_min_rad=-(n - 1) / 2 * inc, angle_increment_rad=inc,
                              range_min_m=0.02, range_max_m=5.6, ranges_m=[4.0] * n))

        def latest_after(age_s: float) -> SafetyLimit | None:
            scan(age_s)
            return limits.latest()  # type: ignore[no-any-return]

        open_ = wait_for(lambda: (lambda m: m if m is not None and m.v_max_fwd_mps > 0.5
                                  else None)(latest_after(0.1)), 20,
                         "an open limit for fresh scans (positive control)", interval=0.1)
        print(open_)
        stop = wait_for(lambda: (lambda m: m if m is not None and "old" in m.reason
                                 else None)(latest_after(1.0)), 5,
                        "a stop for scans one second old", interval=0.1)
        print(stop)
        assert (stop.v_max_fwd_mps, stop.v_max_rev_mps, stop.omega_max_radps) == (0, 0, 0)
        wait_for(lambda: (lambda m: m is not None and m.v_max_fwd_mps > 0.5)(
            latest_after(0.1)), 5, "open again for fresh scans", interval=0.1)
    finally:
        session.close()


def test_keepout_zones_stop_the_chair_where_the_laser_sees_nothing(
        spawn: tuple[str, Spawn], tmp_path: Path) -> None:
    """H42 through a real monitor process: a keep-out band (stairs down, say) on a mask map,
    invisible to the laser, limits the chair like a wall once localization places it, is a
    stop while no localization is heard, and a stop with the chair's front over it."""
    from autochair.mapping.mapfile import save_map
    from tests.test_nav_frames_system import localization
    from tests.test_safety_keepout import map_grid, mask

    hub, start = spawn
    path = save_map(mask([(2.5, -2.0, 3.0, 3.0)]), tmp_path / "keepout.yaml")
    session = client_session(hub)
    try:
        limits = Recorder(session, keys.SAFETY_LIMIT)
        start("autochair.safety.node", "--set", f"keepout_map={path}")
        scans, odom = Publisher(session, keys.SCAN), Publisher(session, keys.ODOM_SLOW)
        n = 682
        inc = math.radians(240) / (n - 1)

        def at(x_odom: float) -> SafetyLimit | None:
            """A fresh open scan with the chair at rest at odom (x, 0, 0); the newest limit."""
            now = time.time_ns()
            odom.put(Odometry(stamp_ns=now, x_m=x_odom, y_m=0.0, yaw_rad=0.0, v_mps=0.0,
                              omega_radps=0.0))
            scans.put(LaserScan(stamp_ns=now, frame_id="laser", angle_min_rad=-(n - 1) / 2 * inc,
                                angle_increment_rad=inc, range_min_m=0.02, range_max_m=5.6,
                                ranges_m=[4.0] * n))
            return limits.latest()  # type: ignore[no-any-return]

        def reason(x_odom: float, text: str) -> Callable[[], SafetyLimit | None]:
            return lambda: (lambda m: m if m is not None and text in m.reason else None)(
                at(x_odom))

        unplaced = wait_for(reason(-3.0, "keep-out zones cannot be placed"), 20,
                            "a stop while no localization is heard", interval=0.1)
        print(unplaced)
        assert (unplaced.v_max_fwd_mps, unplaced.omega_max_radps) == (0.0, 0.0)
        # map → odom (1, 0.5, 0): odom x −3 is map x −2; the map the mask is drawn over
        with localization(session, grid=map_grid()):
            far = wait_for(reason(-3.0, "clear"), 10, "open with the band 4.5 m ahead",
                           interval=0.1)
            near = wait_for(reason(0.0, "free fwd"), 10, "limited 1.5 m before the band",
                            interval=0.1)
            print(f"band 4.5 m ahead: {far.v_max_fwd_mps:.2f} m/s; 1.5 m ahead: "
                  f"{near.v_max_fwd_mps:.2f} m/s ({near.reason})")
            assert 0.0 < near.v_max_fwd_mps < far.v_max_fwd_mps
            over = wait_for(reason(1.0, "stands over a keep-out zone"), 10,
                            "the front over the band", interval=0.1)
            assert (over.v_max_fwd_mps, over.v_max_rev_mps, over.omega_max_radps) == (0, 0, 0)
    finally:
        session.close()


def test_keepout_zones_are_painted_into_the_live_grid_once_placed(
        spawn: tuple[str, Spawn], tmp_path: Path) -> None:
    """H42, navigation's side, through a real mapping process: the live grid in `odom` carries
    the zones as occupied once localization places them (so MPEPC plans round them and a goal
    in one is refused), and not before."""
    import numpy as np

    from autochair.mapping.mapfile import save_map
    from tests.test_nav_frames_system import CORRECTION, localization
    from tests.test_safety_keepout import map_grid, mask

    hub, start = spawn
    path = save_map(mask([(2.5, -1.0, 3.0, 1.0)]), tmp_path / "keepout.yaml")
    session = client_session(hub)
    try:
        grids = Recorder(session, keys.MAP_GRID)
        start("autochair.mapping.node", "--set", f"keepout_map={path}")

        def zone_cells() -> int | None:
            g = grids.latest()
            return None if g is None else int((np.frombuffer(g.data, np.uint8) == 100).sum())

        wait_for(lambda: zone_cells() is not None, 20, "a grid before localization")
        assert zone_cells() == 0  # not placed yet: the monitor stops meanwhile
        with localization(session, grid=map_grid()):
            wait_for(lambda: (zone_cells() or 0) >= 400, 10, "the zone painted (10 × 40 cells)")
            g = grids.latest()
            occ = np.frombuffer(g.data, np.uint8).reshape(g.height, g.width) == 100
            # The zone's centre (2.75, 0) in map, in odom (the correction has no rotation):
            x, y = 2.75 - CORRECTION[0], 0.0 - CORRECTION[1]
            assert occ[int((y - g.origin_y_m) / g.resolution_m),
                       int((x - g.origin_x_m) / g.resolution_m)]
    finally:
        session.close()
