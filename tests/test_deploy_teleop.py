"""Teleop: the deadman publishes one zero then nothing; speed limits; explicit takeover.

(More of the core, with synthetic pad, keyboard and panel streams: tests/test_teleop_core.py.)
"""

from __future__ import annotations

import math
import queue
import threading
import time

from autochair.commands.teleop import TeleopLink, loop
from autochair.commands.teleop_core import Teleop, TeleopLimits
from autochair.launcher import free_port
from autochair.runtime.client import declare_alive, subscribe
from autochair_msgs import CommandOwner, VelocityCommand, keys
from tests.test_deploy_tls import open_json, wait_for

# Without the ramp, so the commands below are exactly the limits.
NO_RAMP = {"accel_mps2": math.inf, "decel_mps2": math.inf, "omega_accel_radps2": math.inf,
           "omega_decel_radps2": math.inf}


def test_core_deadman_one_zero_then_silence() -> None:
    core = Teleop(TeleopLimits(max_v_mps=1.0, max_omega_radps=1.0, deadman_s=0.3, **NO_RAMP))
    core.scale = 1.0
    core.tick(-0.05, link_ok=True)  # the loop ticks from its start, idle: nothing
    core.request(1.0, 0.0, now=0.0)  # a key press ...
    core.request(1.0, 0.0, now=0.1)  # ... and its auto-repeat: then silence (released)
    out = [core.tick(t / 100, link_ok=True) for t in range(0, 100, 5)]  # 0 .. 0.95 s
    assert out[:8] == [(1.0, 0.0)] * 8  # through 0.35 s
    assert out[8] == (0.0, 0.0)  # 0.40 s: 0.3 s after the last repeat -> one zero
    assert out[9:] == [None] * (len(out) - 9)
    assert core.deadman_stops == 1


def test_each_fresh_deadman_press_begins_a_new_stream() -> None:
    """The PID obeys teleop after a stop only on a stream begun after it: a fresh press."""
    core = Teleop(TeleopLimits(deadman_s=0.3))
    core.request(1.0, 0.0, now=0.0)
    core.tick(0.0, True)
    core.request(1.0, 0.0, now=0.2)  # held (auto-repeat): the same press
    core.tick(0.2, True)
    assert core.presses == 1
    assert core.tick(0.6, True) == (0.0, 0.0)  # released
    core.request(1.0, 0.0, now=1.0)
    core.tick(1.0, True)
    assert core.presses == 2


def test_core_link_loss_stops_and_limits_hold() -> None:
    core = Teleop(TeleopLimits(max_v_mps=0.6, max_omega_radps=0.8, deadman_s=0.3, **NO_RAMP))
    core.scale = 1.0
    core.request(5.0, -5.0, now=0.0)  # out-of-range input is clamped to the limits
    assert core.tick(0.0, True) == (0.6, -0.8)
    core.request(-1.0, 0.0, now=0.1)
    assert core.tick(0.1, True) == (-0.3, 0.0)  # reverse at half speed
    assert core.tick(0.15, False) == (0.0, 0.0)  # link lost while pressing
    assert core.tick(0.2, False) is None
    for _ in range(20):
        core.faster(False)
    assert core.scale == 0.1


def test_teleop_over_zenoh_takes_over_and_deadman_stops() -> None:
    hub = f"tcp/127.0.0.1:{free_port()}"
    router = open_json({"mode": "router", "listen": {"endpoints": [hub]},
                        "scouting": {"multicast": {"enabled": False}}})
    client = {"mode": "client", "connect": {"endpoints": [hub]},
              "scouting": {"multicast": {"enabled": False}}}
    chair, laptop = open_json(client), open_json(client)
    got: list[tuple[float, VelocityCommand]] = []
    owners: list[str] = []
    def on_teleop(m: VelocityCommand) -> None:
        got.append((time.monotonic(), m))

    def on_owner(m: CommandOwner) -> None:
        owners.append(m.owner)

    subscribe(chair, keys.TELEOP, on_teleop)
    subscribe(chair, keys.CMD_OWNER, on_owner)
    token = declare_alive(chair, "pid")
    events: queue.Queue[str] = queue.Queue()
    stop = threading.Event()
    link = TeleopLink(laptop, Teleop(TeleopLimits(deadman_s=0.3, **NO_RAMP)))
    t = threading.Thread(target=loop, args=(link, events, stop, 50.0), daemon=True)
    try:
        assert wait_for(lambda: link.link_ok)
        t.start()
        events.put("t")
        assert wait_for(lambda: owners == ["teleop"])
        # Hold "w" (auto-repeat every 50 ms) for a while, then release.
        for _ in range(10):
            events.put("w")
            time.sleep(0.05)  # pacing the simulated key repeat, not synchronisation
        released = time.monotonic()
        assert wait_for(lambda: any(c.v_mps == 0.0 for _, c in got), 3.0)
        moving = [c for _, c in got if c.v_mps != 0.0]
        assert moving and all(c.v_mps == 0.3 and c.source == "teleop" for c in moving)
        first_press = {c.stream_start_ns for c in moving}
        assert len(first_press) == 1 and min(first_press) > 0  # one press, one stream
        last_t, last = got[-1]
        assert last.v_mps == 0.0 and last.omega_radps == 0.0
        assert 0.2 < last_t - released < 1.5
        n = len(got)
        time.sleep(0.5)  # silence must hold: nothing more is published without input
        assert len(got) == n
        # Press again, then the link drops (the PID's token goes): zero, then silence.
        events.put("a")
        assert wait_for(lambda: len(got) > n and got[-1][1].omega_radps > 0)
        assert got[-1][1].stream_start_ns > max(first_press)  # a fresh press: a new stream
        token.undeclare()
        # Keep pressing: only the lost link can stop it now.
        deadline = time.monotonic() + 3.0
        while link.link_ok and time.monotonic() < deadline:
            events.put("a")
            time.sleep(0.05)
        for _ in range(6):
            events.put("a")
            time.sleep(0.05)
        assert not link.link_ok
        m = len(got)
        assert got[-1][1].omega_radps == 0.0
        for _ in range(6):
            events.put("a")
            time.sleep(0.05)
        assert len(got) == m  # still pressing, link still lost: silence
        events.put("h")
        assert wait_for(lambda: owners[-1] == "autonomy")
    finally:
        stop.set()
        t.join(timeout=5)
        for s in (laptop, chair, router):
            s.close()
