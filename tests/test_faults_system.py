"""Fast versions of the fault-injection bench: junk on every key, serial unplug and replug."""

from __future__ import annotations

import time
from collections.abc import Callable

import msgspec
import pytest
from bench.faults import decode_errors, junk_every_key, sim_fault

from autochair.launcher import Launcher
from autochair.runtime.client import subscribe
from autochair_msgs import GroundTruth, Health, keys
from autochair_msgs.sim import SimFault
from tests.helpers import Recorder, Stream, client_session, pid_ready, wait_for

pytestmark = pytest.mark.slow

DRIVE_CHAIN = ["estop", "sim", "gateway", "odometry", "pid"]
ENC = msgspec.msgpack.Encoder()


def test_junk_on_every_key_is_counted_and_kills_nothing(
        stack_factory: Callable[..., Launcher], hub: str) -> None:
    stack = stack_factory(DRIVE_CHAIN)
    pids = {n: stack.pid(n) for n in DRIVE_CHAIN}
    session = client_session(hub)
    try:
        health: dict[str, Health] = {}

        def on_health(h: Health) -> None:  # (our own junk on the health key is skipped)
            health[h.service] = h

        subscribe(session, keys.HEALTH, on_health)
        wait_for(lambda: set(DRIVE_CHAIN) <= set(health), 10, "health of every service")
        used = junk_every_key(session)
        assert len(used) == sum(1 for t in keys.TOPICS if t.kind == "pub")
        must = {keys.JOYSTICK.key, keys.CMD_VEL.key, keys.ODOM.key, keys.ENCODERS.key,
                keys.ESTOP_ASSERT.key, keys.ESTOP_STATE.key}
        counted = wait_for(lambda: (lambda c: c if must <= set(c) else None)(
            decode_errors(health)), 10, "decode errors counted in health")
        assert all(n >= 3 for per in counted.values() for n in per.values())  # 3 junk each
        stack.poll()
        assert {n: stack.pid(n) for n in DRIVE_CHAIN} == pids, "a process died or restarted"
    finally:
        session.close()


def test_serial_unplug_gives_neutral_then_reconnects(
        stack_factory: Callable[..., Launcher], hub: str) -> None:
    stack_factory(DRIVE_CHAIN)
    session = client_session(hub)
    try:
        truth = Recorder(session, keys.SIM_TRUTH)
        out = Recorder(session, keys.JOYSTICK_OUT)
        pid_ready(session)
        old = Stream.on(session, 0.0, 0.5)

        def driving_since(stream: Stream, t_ns: int) -> bool:
            stream.put()
            m = out.latest()
            return m is not None and m.reason == "command" and m.stamp_ns > t_ns

        wait_for(lambda: driving_since(old, 0), 15, "driving", interval=0.05)
        t = time.time_ns()
        assert sim_fault(session, SimFault(kind="unplug", duration_s=1.0))

        def neutral() -> list[GroundTruth]:
            old.put()
            return [m for m in truth.messages() if m.stamp_ns > t
                    and (m.longitudinal_v, m.angular_v) == (2.5, 2.5)]

        first = wait_for(neutral, 3, "neutral at the chair", interval=0.02)[0]
        latency_ms = (first.stamp_ns - t) / 1e6
        # Firmware watchdog 200 ms after the last host frame; generous for a loaded machine.
        assert latency_ms < 400, f"neutral {latency_ms:.0f} ms after the unplug"
        # Replugged, the link is back (frames written again) but the old stream, which simply
        # went on, must not drive: the outage was a stop.
        def written_again() -> bool:
            old.put()
            return any(m.stamp_ns > t + 1.5e9 for m in out.messages())

        wait_for(written_again, 15, "frames written again after replug", interval=0.05)
        replugged = time.monotonic()
        while time.monotonic() - replugged < 1.5:
            old.put()
            time.sleep(0.05)  # the stream's own 20 Hz, not a synchronisation
        enabled = [(m.stamp_ns - t) / 1e6 for m in out.messages()
                   if m.stamp_ns > first.stamp_ns and m.enable]
        assert not enabled, f"the old stream drove again after the replug (at +{enabled} ms)"
        new = Stream(old.pub, 0.0, 0.5)  # positive control: a new command drives
        wait_for(lambda: driving_since(new, t), 15, "driving on a new command", interval=0.05)
    finally:
        session.close()
