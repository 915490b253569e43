"""A goal in `map` through the real processes: refused while no localization is heard, then,
with localization's `map` → `odom` correction on the bus, driven to the map place in `odom`
(the control service re-expresses it on every step)."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import pytest
import zenoh

from autochair.geometry import yaw_quaternion
from autochair.launcher import Launcher
from autochair.runtime.client import Publisher, request
from autochair_msgs import (
    FrameTransform,
    GoalReply,
    GoalRequest,
    LocalizedPose,
    OccupancyGrid,
    Pose2D,
    Quaternion,
    Vector3,
    keys,
)
from tests.helpers import Recorder, client_session, wait_for
from tests.test_nav_system import ACTIVE, STACK, map_ready, story

pytestmark = pytest.mark.slow

CORRECTION = (1.0, 0.5, 0.0)  # map → odom: odometry's origin sits at (1, 0.5) on the map


@contextmanager
def localization(session: zenoh.Session, state: str = "tracking",
                 grid: OccupancyGrid | None = None) -> Iterator[None]:
    """A stand-in for the localization service: its correction and state at 10 Hz, and its
    map (`grid`) if given (a keep-out mask is checked against it)."""
    tf, pose = Publisher(session, keys.TF), Publisher(session, keys.LOC_POSE)
    maps = Publisher(session, keys.LOC_MAP)
    stop = threading.Event()

    def run() -> None:
        while not stop.wait(0.1):  # the service's own 10 Hz, not a synchronisation
            now = time.time_ns()
            tf.put(FrameTransform(stamp_ns=now, parent_frame_id="map", child_frame_id="odom",
                                  translation=Vector3(CORRECTION[0], CORRECTION[1], 0.0),
                                  rotation=Quaternion(*yaw_quaternion(CORRECTION[2]))))
            pose.put(LocalizedPose(stamp_ns=now, x_m=0.0, y_m=0.0, yaw_rad=0.0,
                                   covariance=[0.0] * 9, quality=1.0, state=state,
                                   mode="localization"))
            if grid is not None:
                maps.put(grid)

    t = threading.Thread(target=run, daemon=True)
    t.start()
    try:
        yield
    finally:
        stop.set()
        t.join(5)


def test_a_goal_in_map_is_driven_to_its_place_in_odom(stack_factory: Callable[..., Launcher],
                                                       hub: str) -> None:
    stack_factory(STACK)
    session = client_session(hub)
    try:
        truth = Recorder(session, keys.SIM_TRUTH)
        map_ready(session)
        goal_map = Pose2D(4.0, 0.5, 0.0)  # = (3, 0, 0) in odom, down the hallway
        refused = request(session, keys.GOAL_SET,
                          GoalRequest(waypoints=[goal_map], frame_id="map"), GoalReply)
        assert not refused.ok and "no localization heard" in refused.error
        status = Recorder(session, keys.GOAL_STATUS)
        with localization(session):
            def accepted() -> GoalReply | None:
                r = request(session, keys.GOAL_SET,
                            GoalRequest(waypoints=[goal_map], frame_id="map"), GoalReply)
                return r if r.ok else None

            reply = wait_for(accepted, 10, "the goal accepted once localization is heard", 0.1)
            wait_for(lambda: any(s.goal_id == reply.goal_id and s.state not in ACTIVE
                                 for s in status.messages()), 60, "goal end")
        states = [s for s in status.messages() if s.goal_id == reply.goal_id]
        assert states[-1].state == "arrived", story(states)
        t = truth.latest()
        assert math.hypot(t.x_m - 3.0, t.y_m - 0.0) < 0.10, t  # the map place, in odom
    finally:
        session.close()
