"""Safety monitor in the simulator: drive at the dead end at 1.2 m/s, stop without touching."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from autochair.launcher import Launcher
from autochair.runtime import ChairGeometry
from autochair.sim.world import DEFAULT_WORLD, World, parse_world
from autochair_msgs import keys
from tests.helpers import Recorder, Stream, client_session, make_stack, pid_ready, wait_for

pytestmark = pytest.mark.slow

STACK = ["estop", "sim", "gateway", "odometry", "pid", "lidar-sim", "lidar", "safety"]
P = ChairGeometry()


def footprint_outline(step: float = 0.01) -> np.ndarray:
    """The unpadded footprint's boundary as chair-frame points."""
    f, r, w = P.front_m, P.rear_m, P.half_width_m
    xs = np.arange(-r, f + step, step)
    ys = np.arange(-w, w + step, step)
    return np.concatenate([np.column_stack((xs, np.full_like(xs, w))),
                           np.column_stack((xs, np.full_like(xs, -w))),
                           np.column_stack((np.full_like(ys, f), ys)),
                           np.column_stack((np.full_like(ys, -r), ys))])


def clearance(world: World, x: float, y: float, yaw: float) -> float:
    """Distance from the chair's footprint outline at a pose to the nearest world shape."""
    pts = footprint_outline()
    c, s = math.cos(yaw), math.sin(yaw)
    wp = np.column_stack((x + c * pts[:, 0] - s * pts[:, 1], y + s * pts[:, 0] + c * pts[:, 1]))
    return float(world.distance_to(wp).min())


def test_clearance_helper_sees_a_touch() -> None:
    world = parse_world(DEFAULT_WORLD.read_text())
    assert clearance(world, 0.0, 0.0, 0.0) == pytest.approx(1.4 - P.half_width_m, abs=0.01)
    assert clearance(world, 22.0 - P.front_m, 0.0, 0.0) < 0.01


@pytest.fixture
def safe_stack(tmp_path: Path, hub: str) -> Iterator[Launcher]:
    """The drive chain, the simulated lidar and the monitor (so the PID requires its limit)."""
    launcher = make_stack(["router", *STACK], hub, tmp_path / "run")
    assert launcher.values["safety_required"] == "true"
    try:
        launcher.start(ready_timeout_s=40)
        yield launcher
    finally:
        launcher.stop()


def test_drive_at_the_dead_end_stops_without_touching(safe_stack: Launcher, hub: str) -> None:
    world = parse_world(DEFAULT_WORLD.read_text())
    session = client_session(hub)
    try:
        truth = Recorder(session, keys.SIM_TRUTH)
        limits = Recorder(session, keys.SAFETY_LIMIT)
        estop = Recorder(session, keys.ESTOP_STATE)
        wait_for(lambda: truth.latest() and limits.latest()
                 and limits.latest().reason != "scan stale", 30, "truth and scan-based limits")
        pid_ready(session)
        stream = Stream.on(session, 1.2)
        t0 = time.monotonic()
        stopped_since = math.inf
        while time.monotonic() - t0 < 45:
            stream.put()
            now, latest = time.monotonic(), truth.latest()
            if latest.x_m > 15 and abs(latest.v_mps) < 0.01:
                stopped_since = min(stopped_since, now)
                if now - stopped_since > 1.5:
                    break
            else:
                stopped_since = math.inf
            time.sleep(0.05)  # the 20 Hz rate of the command stream itself, not a sync
        run = [m for t, m in truth.items if t >= t0]
        v_peak = max(m.v_mps for m in run)
        final = run[-1]
        gaps = [clearance(world, m.x_m, m.y_m, m.yaw_rad) for m in run[::5]]
        gap_end = clearance(world, final.x_m, final.y_m, final.yaw_rad)
        # A safety stop brakes to rest without reversing (nothing senses behind the chair).
        reverse = max(m.x_m for m in run) - final.x_m
        print(f"peak {v_peak:.2f} m/s, stopped at x = {final.x_m:.2f} m, {gap_end:.3f} m from "
              f"the nearest obstacle, min clearance {min(gaps):.3f} m, reverse travel "
              f"{reverse * 100:.2f} cm; {limits.latest()}")
        assert reverse <= 0.01, f"reversed {reverse * 100:.1f} cm while stopping"
        assert v_peak > 1.1, f"never reached vmax (peak {v_peak:.2f} m/s)"
        assert final.x_m > 15 and abs(final.v_mps) < 0.01, "the chair did not stop at the end"
        assert min(gaps) > 0.0, f"footprint touched the world (clearance {min(gaps):.3f} m)"
        assert gap_end < 0.6, f"stopped {gap_end:.2f} m short of the obstacle"
        # Stopped by slowing down. The last-resort e-stop (moving faster than 2 m/s² could stop
        # within the free extent) may latch in the final braking, as the chair's own neutral
        # braking takes over (seen in ~1 run in 4): never earlier, while cruising.
        assert estop.latest() is not None
        latched = [m.stamp_ns for m in estop.messages() if m.latched]
        if latched:
            at = min((m for m in run if m.stamp_ns >= latched[0]), key=lambda m: m.stamp_ns,
                     default=final)
            print(f"e-stop latched at x = {at.x_m:.2f} m, {at.v_mps:.2f} m/s")
            assert final.x_m - at.x_m < 1.5 and at.v_mps < 0.9, "latched before the final brake"
        assert limits.latest().v_max_fwd_mps == 0.0  # still on a collision course: held at 0
        assert limits.latest().v_max_rev_mps > 0.0  # but it may back away
    finally:
        session.close()
