"""The control node's wiring under a busy core: odometry that arrives while a goal request
holds the core's lock (its route check: 0.1-0.5 s of costs-to-go on a loaded CPU) is not
taken for stale odometry. Two CI runs aborted goals at the start with "stale odometry
(0.30 s > 0.3 s)" while the odometry service was publishing all along."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest

from autochair.control.core import ABORTED, ControlConfig
from autochair.control.node import ControlNode
from autochair.runtime import Node
from autochair.runtime.config import ZenohSettings
from autochair_msgs import GoalRequest, Odometry, Pose2D
from tests.helpers import wait_for


@pytest.fixture
def control() -> Iterator[ControlNode]:
    node = Node("control", ZenohSettings(connect=[], listen=["tcp/127.0.0.1:0"]))
    try:
        yield ControlNode(node, ControlConfig())
    finally:
        node.close()


def at_rest() -> Odometry:
    return Odometry(stamp_ns=time.time_ns(), x_m=0.0, y_m=0.0, yaw_rad=0.0, v_mps=0.0,
                    omega_radps=0.0)


def test_odometry_during_a_slow_goal_check_keeps_the_goal(control: ControlNode,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    core = control.core
    check = core._check_route

    def slow_check(*args: Any) -> Any:  # what a loaded CPU makes of the costs-to-go
        time.sleep(2 * core.odom_timeout_s)
        return check(*args)

    monkeypatch.setattr(core, "_check_route", slow_check)
    feeding = threading.Event()
    feeding.set()
    fed = threading.Event()

    def odometry() -> None:  # the odometry service's 50 Hz stream
        while feeding.is_set():
            control.on_odom(at_rest())
            fed.set()
            time.sleep(0.02)

    feeder = threading.Thread(target=odometry, daemon=True)
    feeder.start()
    try:
        wait_for(fed.is_set, 2.0, "odometry taken in")
        reply = control.on_set(GoalRequest(waypoints=[Pose2D(2.0, 0.0, 0.0)]))
        assert reply.ok, reply.error
        control.tick()  # at once, as the 50 Hz loop waiting on the lock does
        assert core.active, f"{core.state}: {core.reason}"
        assert core.odom is not None and time.monotonic() - core.odom.t < core.odom_timeout_s
    finally:
        feeding.clear()
        feeder.join(2.0)
    # Positive control: odometry that really stops still aborts the goal.
    def aborted() -> bool:
        control.tick()
        return not core.active

    wait_for(aborted, 2.0, "the goal aborted")
    assert core.state == ABORTED and "stale odometry" in core.reason, core.reason
