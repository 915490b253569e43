"""The control node's wiring under a busy core. A goal's route check (costs-to-go and the
forward lattice: 0.1-0.2 s quiet, up to 1.6 s on a loaded CPU, measured on the navigation suite's
office) runs without the core's lock: the 50 Hz loop and odometry go on meanwhile, odometry is
not taken for stale (a CI run aborted a goal at the start with "stale odometry (0.30 s >
0.3 s)" while the odometry service was publishing all along), and a goal whose asker gave up
during the check is not taken (hazards H43)."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from autochair.control.core import ABORTED, ControlConfig, GoalCheck
from autochair.control.node import ControlNode
from autochair.runtime import Node
from autochair.runtime.client import RequestError, request
from autochair.runtime.config import ZenohSettings
from autochair_msgs import EStopState, GoalReply, GoalRequest, Odometry, Pose2D, keys
from tests.helpers import wait_for

GOAL = GoalRequest(waypoints=[Pose2D(2.0, 0.0, 0.0)])


@pytest.fixture
def control() -> Iterator[ControlNode]:
    node = Node("control", ZenohSettings(connect=[], listen=["tcp/127.0.0.1:0"]))
    try:
        c = ControlNode(node, ControlConfig())
        node.serve(keys.GOAL_SET, c.on_set)
        yield c
    finally:
        node.close()


@pytest.fixture
def odometry(control: ControlNode) -> Iterator[threading.Event]:
    """The odometry service's 50 Hz stream (at rest), and the e-stop's heartbeat without which
    no goal is taken, while the event is set."""
    feeding, fed = threading.Event(), threading.Event()
    feeding.set()

    def feed() -> None:
        while feeding.is_set():
            control.on_odom(Odometry(stamp_ns=time.time_ns(), x_m=0.0, y_m=0.0, yaw_rad=0.0,
                                     v_mps=0.0, omega_radps=0.0))
            control.on_estop(EStopState(stamp_ns=time.time_ns(), latched=False))
            fed.set()
            time.sleep(0.02)

    feeder = threading.Thread(target=feed, daemon=True)
    feeder.start()
    wait_for(fed.is_set, 2.0, "odometry taken in")
    yield feeding
    feeding.clear()
    feeder.join(2.0)


class HeldRoute:
    """GoalCheck.routed held until released, as a slow route check on a loaded CPU is."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.entered, self.release = threading.Event(), threading.Event()
        routed = GoalCheck.routed

        def held(check: GoalCheck) -> GoalCheck:
            self.entered.set()
            assert self.release.wait(10.0), "never released"
            return routed(check)

        monkeypatch.setattr(GoalCheck, "routed", held)


def in_thread(fn: Callable[[], Any]) -> tuple[threading.Thread, list[Any]]:
    out: list[Any] = []

    def run() -> None:
        try:
            out.append(fn())
        except Exception as e:  # (kept for the assertion)
            out.append(e)

    t = threading.Thread(target=run, daemon=True)
    t.start()
    return t, out


def aborted(control: ControlNode) -> Callable[[], bool]:
    def check() -> bool:
        control.tick()
        return not control.core.active
    return check


def test_the_loop_and_odometry_go_on_during_a_slow_route_check(
        control: ControlNode, odometry: threading.Event,
        monkeypatch: pytest.MonkeyPatch) -> None:
    core, route = control.core, HeldRoute(monkeypatch)
    asking, reply = in_thread(lambda: request(control.node.session, keys.GOAL_SET, GOAL,
                                              GoalReply, timeout_s=5.0))
    try:
        assert route.entered.wait(5.0)
        # The 50 Hz loop runs while the route is checked (it used to wait for the lock).
        ticking, ticked = in_thread(control.tick)
        ticking.join(5.0)
        assert not ticking.is_alive() and ticked == [None], ticked
        t_release = time.monotonic()
        time.sleep(2 * core.odom_timeout_s)  # the check's duration (not a synchronisation)
    finally:
        route.release.set()
        asking.join(5.0)
    assert reply and isinstance(reply[0], GoalReply) and reply[0].ok, reply
    control.tick()  # at once, as the loop waiting on the lock did
    assert core.active, f"{core.state}: {core.reason}"
    assert core.odom is not None and core.odom.t > t_release
    # Positive control: odometry that really stops still aborts the goal.
    odometry.clear()
    wait_for(aborted(control), 2.0, "the goal aborted")
    assert core.state == ABORTED and "stale odometry" in core.reason, core.reason


@pytest.mark.parametrize("gives_up", [True, False])
def test_a_goal_whose_asker_gave_up_during_the_route_check_is_not_taken(
        control: ControlNode, odometry: threading.Event, monkeypatch: pytest.MonkeyPatch,
        gives_up: bool) -> None:
    core, route = control.core, HeldRoute(monkeypatch)
    asking, reply = in_thread(lambda: request(control.node.session, keys.GOAL_SET, GOAL,
                                              GoalReply, timeout_s=1.0))
    try:
        assert route.entered.wait(5.0)
        if gives_up:
            asking.join(5.0)  # the asker's timeout: "no reply … is the service running?"
            assert reply and isinstance(reply[0], RequestError), reply
    finally:
        route.release.set()
        asking.join(5.0)
    if gives_up:
        wait_for(lambda: control.node.health.counters.get(f"late_requests:{keys.GOAL_SET.key}"),
                 5.0, "the late goal counted")
        assert not core.active and core.goal_id == 0, core.state
    else:  # positive control: the same goal, its asker still waiting, is taken
        assert reply and isinstance(reply[0], GoalReply) and reply[0].ok, reply
        assert core.active and core.goal_id == 1
