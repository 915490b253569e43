"""The walking skeleton end to end: real processes, real Zenoh on loopback, a real pty."""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Callable

import msgspec
import pytest

from autochair.launcher import Launcher
from autochair_msgs import GroundTruth, JoystickOutput, VelocityCommand, keys
from tests.helpers import Recorder, client_session, wait_for

pytestmark = pytest.mark.slow

DRIVE_CHAIN = ["estop", "sim", "gateway", "odometry", "pid"]


def test_velocity_step_settles_and_pid_kill_goes_neutral(
        stack_factory: Callable[..., Launcher], hub: str) -> None:
    stack = stack_factory(DRIVE_CHAIN)
    session = client_session(hub)
    try:
        truth = Recorder(session, keys.SIM_TRUTH.key, GroundTruth)
        out = Recorder(session, keys.JOYSTICK_OUT.key, JoystickOutput)
        wait_for(lambda: truth.latest() and out.latest(), 10, "truth and joystick output")
        assert out.latest().reason.startswith("neutral"), "output must be neutral before a command"
        pub = session.declare_publisher(keys.CMD_VEL.key)
        enc = msgspec.msgpack.Encoder()
        t0 = time.monotonic()
        while time.monotonic() - t0 < 5.0:
            pub.put(enc.encode(VelocityCommand(stamp_ns=time.time_ns(), v_mps=0.5,
                                               omega_radps=0.0, source="test")))
            time.sleep(0.05)  # the 20 Hz publish rate of the command itself, not a sync
        samples = [(t - t0, m.v_mps) for t, m in truth.items if t >= t0]
        outside = [t for t, v in samples if abs(v - 0.5) > 0.05]
        settle = max(outside) if outside else 0.0
        assert samples[-1][0] > 4.5
        assert settle < 3.0, f"true speed still outside ±10 % of 0.5 m/s at t = {settle:.2f} s"

        # Keep commanding, then kill the PID: the gateway must write neutral within 150 ms.
        stop_cmds = time.monotonic() + 10
        pid_pid = stack.pid("pid")
        assert pid_pid is not None
        killed_ns = 0
        while time.monotonic() < stop_cmds:
            pub.put(enc.encode(VelocityCommand(stamp_ns=time.time_ns(), v_mps=0.5,
                                               omega_radps=0.0, source="test")))
            if not killed_ns:
                assert out.latest().reason == "command"
                killed_ns = time.time_ns()
                os.kill(pid_pid, signal.SIGKILL)
            neutral = [m for m in out.messages()
                       if m.stamp_ns > killed_ns and m.reason == "neutral:stale"]
            if neutral:
                break
            time.sleep(0.01)
        assert neutral, "gateway never went neutral after the PID was killed"
        latency_ms = (neutral[0].stamp_ns - killed_ns) / 1e6
        assert latency_ms < 150, f"neutral {latency_ms:.0f} ms after the PID died"
        assert (neutral[0].longitudinal_v, neutral[0].angular_v) == (2.5, 2.5)
    finally:
        session.close()
