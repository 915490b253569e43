"""Control law end to end: the simulated drive chain + autochair-control, goal set → arrival."""

from __future__ import annotations

import math
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from autochair.launcher import Launcher
from autochair.runtime.client import request
from autochair_msgs import Empty, GoalReply, GoalRequest, GoalStatus, Pose2D, keys
from tests.helpers import Recorder, client_session, goal_ready, wait_for

pytestmark = pytest.mark.slow

STACK = ["estop", "sim", "gateway", "odometry", "pid", "control"]


def test_goal_set_to_arrival_in_the_simulator(
        stack_factory: Callable[..., Launcher], hub: str, tmp_path: Path) -> None:
    stack_factory(STACK)
    session = client_session(hub)
    try:
        status = Recorder(session, keys.GOAL_STATUS)
        truth = Recorder(session, keys.SIM_TRUTH)
        wait_for(lambda: status.latest() and truth.latest(), 15, "goal status and sim truth")
        # a bad goal is refused with a reason
        bad = request(session, keys.GOAL_SET, GoalRequest(waypoints=[Pose2D(math.nan, 0, 0)]),
                      GoalReply)
        assert not bad.ok and "not finite" in bad.error
        goal = GoalRequest(waypoints=[Pose2D(1.5, 0.5, math.radians(30))])

        def set_goal() -> GoalReply | None:  # odometry may not be flowing yet
            r = request(session, keys.GOAL_SET, goal, GoalReply)
            return r if r.ok else None

        # (sent before the PID has started, a goal's stream begins before the PID's own
        # start-up stop, which it never obeys: "the chair does not follow", the fresh-clone
        # rehearsal's one failure in session 14)
        goal_ready(session)
        reply = wait_for(set_goal, 15, "goal accepted")
        done = wait_for(lambda: next((s for s in status.messages() if s.goal_id == reply.goal_id
                                      and s.state not in ("planning", "driving", "blocked")),
                              None), 60, "goal end")
        assert done.state == "arrived", done
        got = request(session, keys.GOAL_GET, Empty(), GoalStatus)
        assert got.goal_id == reply.goal_id and got.state == "arrived"
        t = truth.latest()
        assert math.hypot(t.x_m - 1.5, t.y_m - 0.5) < 0.10, t  # truth vs odometry: slip-free sim
        assert abs(math.remainder(t.yaw_rad - math.radians(30), math.tau)) < math.radians(6)

        # The people's way: waypoints from a file through the CLI, progress shown to arrival.
        wp = tmp_path / "wp.csv"
        wp.write_text("# x, y, yaw_deg\n2.0, 0.0, 0\n2.5, -0.5, -90\n")
        proc = subprocess.run(
            [sys.executable, "-m", "autochair.cli", "goal", "--waypoints", str(wp),
             "--connect", hub], capture_output=True, text=True, timeout=120,
            stdin=subprocess.DEVNULL)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        assert "arrived" in proc.stdout.lower(), proc.stdout
        assert "left" in proc.stdout.lower(), proc.stdout  # progress: distance left was shown
        t = truth.latest()
        assert math.hypot(t.x_m - 2.5, t.y_m + 0.5) < 0.10, t
    finally:
        session.close()
