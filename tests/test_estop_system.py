"""The e-stop as a person uses it: `autochair estop` latches, the gateway holds neutral while a
command keeps coming, `autochair release` clears it and driving resumes."""

from __future__ import annotations

import re
import subprocess
import sys
import time
from collections.abc import Callable

import pytest

from autochair.launcher import Launcher
from autochair.runtime.client import Publisher
from autochair_msgs import EStopAssert, JoystickCommand, keys
from tests.helpers import Recorder, client_session, pid_ready, wait_for

pytestmark = pytest.mark.slow


def cli(hub: str, *argv: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "autochair.cli", *argv, "--connect", hub],
                          capture_output=True, text=True, timeout=30, stdin=subprocess.DEVNULL)


def test_estop_latches_holds_neutral_and_releases(stack_factory: Callable[..., Launcher],
                                                  hub: str) -> None:
    stack_factory(["estop", "sim", "gateway"])
    session = client_session(hub)
    try:
        out = Recorder(session, keys.JOYSTICK_OUT)
        pub = Publisher(session, keys.JOYSTICK)

        def reason() -> str:  # a joystick command keeps coming, as from a running PID
            pub.put(JoystickCommand(stamp_ns=time.time_ns(), longitudinal_v=3.0,
                                    angular_v=2.5))
            latest = out.latest()
            return latest.reason if latest else ""

        wait_for(lambda: reason() == "command", 10, "commands applied", interval=0.02)
        latched = cli(hub, "estop", "test")
        assert latched.returncode == 0, latched.stderr
        wait_for(lambda: reason() == "neutral:estop", 2, "neutral while latched", interval=0.02)
        released = cli(hub, "release")
        assert released.returncode == 0, released.stderr
        wait_for(lambda: reason() == "command", 2, "commands again after release", interval=0.02)
    finally:
        session.close()


def test_cli_clear_of_a_held_cause_then_release(stack_factory: Callable[..., Launcher],
                                                hub: str) -> None:
    """A service's persistent cause refuses `autochair release`; `autochair estop --clear
    SOURCE` on the chair (a services identity) clears it, then the release is accepted."""
    stack_factory(["estop"])
    session = client_session(hub)
    try:
        states = Recorder(session, keys.ESTOP_STATE)
        pub = Publisher(session, keys.ESTOP_ASSERT)

        def held() -> bool:
            latest = states.latest()
            return latest is not None and any(c.source == "safety" and c.active
                                              for c in latest.causes)

        def asserted() -> bool:
            pub.put(EStopAssert(stamp_ns=time.time_ns(), source="safety",
                                reason="imminent collision"))
            return held()

        wait_for(asserted, 5, "the safety cause held", interval=0.1)
        refused = cli(hub, "release")
        assert refused.returncode == 2 and "safety: imminent collision" in refused.stderr
        nobody = cli(hub, "estop", "--clear", "nobody")
        assert nobody.returncode == 2 and "nobody holds no active e-stop cause" in nobody.stderr
        assert "active causes: safety" in nobody.stderr
        cleared = cli(hub, "estop", "--clear", "safety")
        assert cleared.returncode == 0, cleared.stderr
        assert "cause of safety cleared" in cleared.stdout and "autochair release" in cleared.stdout
        assert not held() and states.latest().latched  # cleared, still latched
        released = cli(hub, "release")
        assert released.returncode == 0, released.stderr
        wait_for(lambda: not states.latest().latched, 2, "released")
    finally:
        session.close()


def test_drive_says_why_the_pid_holds_the_chair(stack_factory: Callable[..., Launcher],
                                                hub: str) -> None:
    """A chair that stands still under `autochair drive` says why (here the e-stop), instead
    of reading v 0 as if it were driving."""
    stack_factory(["estop", "sim", "gateway", "odometry", "pid"])
    session = client_session(hub)
    try:
        pid_ready(session)
    finally:
        session.close()
    free = cli(hub, "drive", "0.3", "0", "--for", "2")  # positive control: it drives
    assert free.returncode == 0, free.stderr
    assert "held by the PID" not in free.stdout, free.stdout
    measured = [float(v) for v in re.findall(r"\| v ([+-]\d+\.\d+) m/s", free.stdout)]
    assert max(measured, default=0.0) > 0.1, free.stdout
    latched = cli(hub, "estop", "test")
    assert latched.returncode == 0, latched.stderr
    held = cli(hub, "drive", "0.3", "0", "--for", "1.5")
    assert held.returncode == 0, held.stderr
    assert "held by the PID: e-stop latched" in held.stdout, held.stdout
