"""The logger's intake without a Python wake-up per sample: Zenoh holds each logged key's
samples in a ring (`Node.inbox`), stamped on arrival; the writer drains the rings in batches.
A burst is recorded complete and in order, log_time is the arrival (not the drain), and a
ring that overflows is counted and reported, never silent."""

from __future__ import annotations

import itertools
import statistics
import time
from collections.abc import Iterator
from pathlib import Path

import msgspec
import pytest

from autochair.logger import foxglove
from autochair.logger import node as logger_node
from autochair.logger.reader import Recording, is_indexed
from autochair.logger.writer import Intake, LoggerConfig, Recorder
from autochair.runtime import Node
from autochair.runtime.client import Publisher
from autochair.runtime.config import ZenohSettings
from autochair_msgs import Odometry, keys
from tests.helpers import wait_for

ENC = msgspec.msgpack.Encoder()


def odom(seq: int) -> Odometry:
    return Odometry(stamp_ns=time.time_ns(), x_m=0.0, y_m=0.0, yaw_rad=0.0, v_mps=0.0,
                    omega_radps=0.0, distance_m=0.0, source_seq=seq)


@pytest.fixture
def node() -> Iterator[Node]:
    """An isolated peer, stamping samples on arrival as the logger process does."""
    n = Node("logger", ZenohSettings(connect=[], listen=["tcp/127.0.0.1:0"]), timestamps=True)
    try:
        yield n
    finally:
        n.close()


def recorded_odom(path: Path) -> list[tuple[int, Odometry]]:
    dec = msgspec.json.Decoder(Odometry)
    return [(m.log_ns, dec.decode(m.data)) for m in Recording(path).messages()
            if m.topic == keys.ODOM.key]


def test_a_burst_longer_than_a_drain_is_recorded_complete_and_in_order(
        node: Node, tmp_path: Path) -> None:
    path = tmp_path / "burst.mcap"
    logger_node.start(node, LoggerConfig(path=str(path)))
    pub = Publisher(node.session, keys.ODOM)
    n = 3000  # 30 s of odometry at once: many drain periods' worth
    for i in range(n):
        pub.put(odom(i))
    wait_for(lambda: node.health.counters.get("written", 0) >= n, 20, "the burst written")
    node.close()
    wait_for(lambda: is_indexed(path), 10, "the recording finished")
    got = recorded_odom(path)
    assert [m.source_seq for _, m in got] == list(range(n))  # complete, in publish order
    assert all(a[0] <= b[0] for a, b in itertools.pairwise(got))
    assert node.health.counters.get("dropped", 0) == 0
    assert node.health.counters.get("unstamped", 0) == 0


def test_log_time_is_the_arrival_not_the_drain(node: Node, tmp_path: Path) -> None:
    """Paced at 10 ms, samples wait up to a drain period (≥ 40 ms) in the ring: stamped at
    the drain, their log_time would lag their own stamp by half of it in the median."""
    assert logger_node.DRAIN_PERIOD_S >= 0.04  # else this test could not tell the two apart
    path = tmp_path / "paced.mcap"
    logger_node.start(node, LoggerConfig(path=str(path)))
    pub = Publisher(node.session, keys.ODOM)
    for i in range(40):
        pub.put(odom(i))
        time.sleep(0.01)  # the publisher's pace (the scenario), not a synchronisation
    wait_for(lambda: node.health.counters.get("written", 0) >= 40, 20, "all written")
    node.close()
    wait_for(lambda: is_indexed(path), 10, "the recording finished")
    lags_ms = [(log_ns - m.stamp_ns) / 1e6 for log_ns, m in recorded_odom(path)]
    assert len(lags_ms) == 40
    assert min(lags_ms) >= 0.0  # stamped after the message was made
    assert statistics.median(lags_ms) < 5.0, lags_ms


def test_a_full_ring_is_counted_and_reported(node: Node, tmp_path: Path) -> None:
    """The writer's drain, step by step (no writer thread): a ring of 10."""
    cfg = LoggerConfig(path=str(tmp_path / "small.mcap"), queue_size=10)
    box = node.inbox(keys.ODOM.key, logger_node.ring_size(keys.ODOM.key, cfg))
    recorder = Recorder(cfg, time.time_ns(), time.monotonic())
    reporter = logger_node._Reporter(node, recorder)
    intake = Intake(cfg)
    pub = Publisher(node.session, keys.ODOM)

    def drained_after(seqs: range) -> None:
        for i in seqs:
            pub.put(odom(i))
        logger_node._drain([box], intake, recorder, reporter)

    drained_after(range(9))  # positive control: fewer than the ring holds, nothing lost
    assert recorder.counters["written"] == 9
    assert node.health.counters.get("dropped", 0) == 0
    drained_after(range(100, 125))  # 25 into a ring of 10: the oldest 15 are lost
    assert recorder.counters["written"] == 19  # the newest 10
    assert node.health.counters["dropped"] == 1  # one full ring found (at least 1 lost)
    events: list[str] = []
    node.event = lambda level, message: events.append(f"{level}: {message}")  # type: ignore
    reporter.report(time.monotonic(), force=True)
    assert events and events[0].startswith("warning: queue full") and keys.ODOM.key in events[0]
    recorder.finish()
    seqs = [m.source_seq for _, m in recorded_odom(recorder.path)]
    assert seqs == [*range(9), *range(115, 125)]
    notes = [m for m in Recording(recorder.path).messages() if m.topic == foxglove.TOPIC_LOG]
    assert notes and b"queue full" in notes[0].data
