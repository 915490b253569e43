"""The simulator's clock keeps up with the wall clock when its loop misses ticks (no process)."""

from __future__ import annotations

from collections import Counter
from typing import Any

import pytest

from autochair.protocol import arduino as proto
from autochair.sim.chair.clock import MAX_CATCH_UP_S, Pacer
from autochair.sim.chair.node import SimConfig, Simulator
from autochair_msgs import keys

DT = 1.0 / keys.DRIVE_RATE_HZ


class FakeNode:
    """What the simulator's loop uses of a Node: the timer's schedule, counters, a publisher."""

    def __init__(self) -> None:
        self.due: dict[str, float] = {}
        self.health = self
        self.counts: Counter[str] = Counter()

    def count(self, name: str, n: int = 1) -> None:
        self.counts[name] += n

    def publisher(self, topic: Any) -> Any:
        return self

    def put(self, msg: Any) -> None:
        pass

    def event(self, level: str, message: str) -> None:
        pass


def run_ticks(node: FakeNode, sim: Simulator, dues: list[float]) -> None:
    for due in dues:
        node.due["sim"] = 100.0 + due  # (a monotonic clock's arbitrary origin)
        sim.tick()


def test_ticks_the_timer_skipped_are_simulated_at_the_next_one() -> None:
    node = FakeNode()
    sim = Simulator(node, SimConfig(pty_link="/nonexistent"))  # type: ignore[arg-type]
    run_ticks(node, sim, [0.0, 0.01, 0.02])
    assert sim.t == pytest.approx(3 * DT)  # positive control: one step per tick on time
    # Under load the node's timer skips the ticks it missed (Node.every): due at 0.07 next.
    run_ticks(node, sim, [0.07, 0.08])
    # The simulated chair lived through the missed 40 ms, as a real one does (it lost it
    # before: its time then ran slower than that of the processes driving it).
    assert sim.t == pytest.approx(9 * DT)
    assert node.counts["steps_caught_up"] == 4 and not node.counts["steps_lost"]
    assert node.counts["frames_unread"] == 9  # a telemetry frame per simulated step


def test_a_stall_beyond_the_catch_up_bound_loses_time_and_counts_it() -> None:
    node = FakeNode()
    sim = Simulator(node, SimConfig(pty_link="/nonexistent"))  # type: ignore[arg-type]
    bound = round(MAX_CATCH_UP_S / DT)
    run_ticks(node, sim, [0.0, 2.0])  # a process frozen for 2 s
    assert sim.t == pytest.approx((1 + bound) * DT)
    assert node.counts["steps_lost"] == 201 - 1 - bound
    run_ticks(node, sim, [2.01])  # and on time again from there
    assert sim.t == pytest.approx((2 + bound) * DT)


def test_a_long_stall_of_the_sim_does_not_trip_the_firmware_watchdog() -> None:
    """The host cannot feed the MCU's 200 ms watchdog while the sim stands still (no telemetry,
    no reply): only 0.1 s is caught up, so the chair keeps the host's command as a real one,
    whose time never stops, would have."""
    node = FakeNode()
    sim = Simulator(node, SimConfig(pty_link="/nonexistent"))  # type: ignore[arg-type]
    drive = proto.encode(proto.Command(1, 0, 3000, 2500, proto.FL_ENABLE))
    for k in range(130):  # past the firmware's 1 s boot, a host command every tick
        sim.fw.receive(drive, sim.t)
        run_ticks(node, sim, [k * DT])
    assert sim.fw.output_volts[0] == pytest.approx(3.0)  # positive control: driving
    run_ticks(node, sim, [130 * DT + 0.5])  # the sim stood still 0.5 s
    assert sim.fw.output_volts[0] == pytest.approx(3.0)
    assert not sim.fw.status & proto.ST_HOST_TIMEOUT
    # Positive control: the host silent for 0.25 s of the chair's own time trips it.
    run_ticks(node, sim, [130 * DT + 0.5 + k * DT for k in range(1, 26)])
    assert sim.fw.output_volts[0] == pytest.approx(2.5)


def test_the_pacer_follows_the_time_scale() -> None:
    pacer = Pacer(period_s=DT / 4, max_steps=50)  # time_scale 4: a step per 2.5 ms of wall
    assert pacer.steps(5.0) == (1, 0)
    assert pacer.steps(5.0 + DT / 4) == (1, 0)
    assert pacer.steps(5.0 + DT) == (3, 0)  # two missed
    assert pacer.steps(5.0 + DT) == (0, 0)  # nothing more due at the same time
