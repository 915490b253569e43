"""No unexpected start-up across processes: an e-stop under an active goal, then a release;
two command streams; the hub killed under a goal."""

from __future__ import annotations

import math
import os
import signal
import time
from collections.abc import Callable

import msgspec
import numpy as np
import pytest

from autochair.launcher import Launcher
from autochair.runtime.client import request
from autochair_msgs import (
    EStopAssert,
    EStopRelease,
    EStopReply,
    GoalReply,
    GoalRequest,
    GroundTruth,
    Pose2D,
    keys,
)
from tests.helpers import Recorder, Stream, client_session, goal_ready, pid_ready, wait_for

pytestmark = pytest.mark.slow

STACK = ["estop", "sim", "gateway", "odometry", "pid", "control"]
A_MAX = 1.0  # the comfort limit (ControlConfig.a_max_mps2)


def peak_accel(truth: list[GroundTruth]) -> float:
    """Peak |a| of the true speed, averaged over 0.1 s (as the control bench measures)."""
    t = np.array([m.sim_time_s for m in truth])
    v = np.array([m.v_mps for m in truth])
    grid = np.arange(t[0], t[-1], 0.01)
    vs = np.convolve(np.interp(grid, t, v), np.ones(10) / 10, mode="valid")
    return float(np.abs(np.diff(vs[::5]) / 0.05).max())


def test_estop_under_a_goal_then_release_does_not_resume_or_lunge(
        stack_factory: Callable[..., Launcher], hub: str) -> None:
    stack_factory(STACK)
    session = client_session(hub)
    try:
        truth = Recorder(session, keys.SIM_TRUTH)
        out = Recorder(session, keys.JOYSTICK_OUT)
        status = Recorder(session, keys.GOAL_STATUS)
        goal_ready(session)
        wait_for(truth.latest, 10, "ground truth")  # (10 Hz while the chair is parked)
        goal = GoalRequest(waypoints=[Pose2D(8.0, 0.0, 0.0)])
        assert request(session, keys.GOAL_SET, goal, GoalReply).ok
        wait_for(lambda: truth.latest().v_mps > 0.6, 20, "the chair cruising to the goal")
        # A momentary press (a button): latched, nothing left to clear.
        session.put(keys.ESTOP_ASSERT.key, msgspec.msgpack.encode(EStopAssert(
            stamp_ns=time.time_ns(), source="test", reason="hazard test", active=False)))
        wait_for(lambda: (lambda s: s is not None and s.state == "aborted")(status.latest()),
                 5, "the goal aborted by the e-stop")
        assert "e-stop" in status.latest().reason
        wait_for(lambda: abs(truth.latest().v_mps) < 0.005, 10, "the chair at rest")
        released = request(session, keys.ESTOP_RELEASE, EStopRelease(by="test"), EStopReply)
        assert released.ok, released.error
        release_ns = time.time_ns()
        x0, t_rel = truth.latest().x_m, time.monotonic()
        wait_for(lambda: time.monotonic() - t_rel > 2.0, 3, "two seconds after the release")
        after = [m for m in out.messages() if m.stamp_ns > release_ns]
        assert after and not any(m.enable for m in after), "the old goal resumed"
        assert abs(truth.latest().x_m - x0) < 0.01, "the chair moved after the release"
        # A new goal (a deliberate act after the stop) starts smoothly from rest.
        start_ns = time.time_ns()
        assert request(session, keys.GOAL_SET, GoalRequest(
            waypoints=[Pose2D(x0 + 3.0, 0.0, 0.0)]), GoalReply).ok
        wait_for(lambda: truth.latest().v_mps > 0.6, 20, "the chair driving the new goal")
        frames = [m for m in out.messages() if m.stamp_ns > start_ns and m.enable]
        first = frames[0]
        lunge = max(abs(first.longitudinal_v - 2.5), abs(first.angular_v - 2.5))
        run = [m for m in truth.messages() if m.stamp_ns > start_ns]
        a = peak_accel(run)
        print(f"first joystick frame after the new goal {first.longitudinal_v:.3f} V; "
              f"peak |a| {a:.2f} m/s² (limit {A_MAX})")
        assert lunge < 0.1, f"first frame {lunge:.2f} V off neutral: a lunge"
        assert a <= A_MAX, f"peak |a| {a:.2f} m/s² beyond the comfort limit"
    finally:
        session.close()


def test_two_command_streams_are_never_mixed_and_the_older_never_resumes(
        stack_factory: Callable[..., Launcher], hub: str) -> None:
    """H37: a goal's stream and `autochair drive` (or two laptops) on one key at once."""
    stack_factory(["estop", "sim", "gateway", "odometry", "pid"])
    session = client_session(hub)
    try:
        truth = Recorder(session, keys.SIM_TRUTH)
        pid_ready(session)
        older = Stream.on(session, 0.3, 0.0)  # straight ahead

        def state(*streams: Stream) -> GroundTruth | None:
            for s in streams:
                s.put()
            return truth.latest()  # type: ignore[no-any-return]

        # Positive control: the older stream alone drives the chair forward.
        wait_for(lambda: (lambda m: m is not None and m.v_mps > 0.25)(state(older)), 15,
                 "the first stream driving", interval=0.05)
        newer = Stream(older.pub, 0.0, 0.5)  # begun later: turn on the spot
        # Interleaved at the same rate: the chair must follow the newer stream alone.
        turning = wait_for(lambda: (lambda m: m if m is not None and m.omega_radps > 0.4
                                    and abs(m.v_mps) < 0.03 else None)(state(older, newer)),
                           10, "the chair turning on the spot (the newer stream alone)",
                           interval=0.05)
        mixed = [m for m in truth.messages() if m.stamp_ns > turning.stamp_ns
                 and abs(m.v_mps) > 0.03]
        t0 = time.monotonic()
        while time.monotonic() - t0 < 1.0:  # a second more of both: no forward creep
            state(older, newer)
            time.sleep(0.05)  # the streams' own 20 Hz, not a synchronisation
        mixed += [m for m in truth.messages() if m.stamp_ns > turning.stamp_ns
                  and abs(m.v_mps) > 0.03]
        assert not mixed, f"the streams were mixed: {max(abs(m.v_mps) for m in mixed):.2f} m/s"
        # The newer stream's person lets go; the older stream goes on: the chair stops, stays.
        wait_for(lambda: (lambda m: m is not None and abs(m.omega_radps) < 0.01
                          and abs(m.v_mps) < 0.005)(state(older)), 10, "the chair at rest",
                 interval=0.05)
        rest = truth.latest()
        t0 = time.monotonic()
        while time.monotonic() - t0 < 1.5:
            state(older)
            time.sleep(0.05)
        moved = math.hypot(truth.latest().x_m - rest.x_m, truth.latest().y_m - rest.y_m)
        assert moved < 0.01, f"the older stream drove again ({moved:.3f} m)"
    finally:
        session.close()


def test_the_hub_dies_under_a_goal_the_chair_stops_and_does_not_resume_when_it_is_back(
        stack_factory: Callable[..., Launcher], hub: str) -> None:
    """The hub relays the control service's commands (a Zenoh client): killed mid-goal (or by
    its own watchdog) and restarted, the chair stops, and once every service is back it stays
    at rest: the goal's old stream began before the stop. Positive control: it was cruising."""
    stack = stack_factory(STACK)
    stack.restart = True
    session = client_session(hub)
    try:
        truth = Recorder(session, keys.SIM_TRUTH)
        status = Recorder(session, keys.GOAL_STATUS)
        goal_ready(session)
        wait_for(truth.latest, 10, "ground truth")
        assert request(session, keys.GOAL_SET, GoalRequest(waypoints=[Pose2D(8.0, 0.0, 0.0)]),
                       GoalReply).ok
        wait_for(lambda: truth.latest().v_mps > 0.6, 20, "the chair cruising to the goal")
        old_hub = stack.pid("router")
        assert old_hub is not None
        killed_ns = time.time_ns()
        os.kill(old_hub, signal.SIGKILL)

        def back() -> bool:
            stack.poll()
            return (stack.pid("router") not in (None, old_hub)
                    and all(c.state == "up" for c in stack.children.values()))

        wait_for(back, 30, "the hub restarted and every service up through it")
        fresh = wait_for(lambda: (lambda m: m if m is not None and m.stamp_ns > killed_ns
                                  else None)(truth.latest()), 10, "ground truth again")
        wait_for(lambda: abs(truth.latest().v_mps) < 0.005, 10, "the chair at rest")
        rest, t0 = truth.latest(), time.monotonic()
        print(f"\nhub back; chair at rest {rest.x_m - fresh.x_m:+.2f} m after the first "
              f"fresh truth; goal: {status.latest().state if status.latest() else None}: "
              f"{status.latest().reason if status.latest() else None}")
        def three_seconds() -> bool:
            stack.poll()
            return time.monotonic() - t0 > 3.0

        wait_for(three_seconds, 5, "three seconds with the hub back")
        moved = math.hypot(truth.latest().x_m - rest.x_m, truth.latest().y_m - rest.y_m)
        assert moved < 0.01, f"the chair drove again by itself ({moved:.3f} m)"
        s = status.latest()
        assert s is not None and s.state != "driving", "the goal drives on after the stop"
    finally:
        session.close()
