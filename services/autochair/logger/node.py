"""autochair-logger: records every logged key to MCAP without ever blocking a publisher.

Zenoh holds the samples of each logged key expression in a ring of its own (`Node.inbox`),
stamped on arrival; one writer thread drains the rings every DRAIN_PERIOD_S (at once again
while one is more than half full), decodes, transcodes and writes, so no Python thread wakes
per sample (profiled: ~2 % of a core per 100 Hz stream). A full ring drops its oldest sample
(never blocks a publisher): the drain that finds it full counts `dropped` in health and the
writer reports it as a warning event and a foxglove.Log in the file. The writer thread is not
a daemon: on SIGTERM it drains the rings and finishes the file (summary and indexes) before the
process exits. A restart never truncates a recording: files are created exclusively, a taken
name gets a suffix (see autochair.logger.writer).

log_time in the file = the sample's Zenoh timestamp: when it reached the logger's Zenoh
session (or the hub, for what the hub relays from clients), within a millisecond of the
publish; not when the writer drained it.
"""

from __future__ import annotations

import sys
import time
from operator import itemgetter

from autochair.runtime import ConfigError, Node, service_main
from autochair.runtime.node import Inbox
from autochair_msgs import OccupancyGrid, keys

from .writer import Intake, LoggerConfig, Recorder

# The writer drains the rings this often: 10 wake-ups a second however many samples arrive
# (the old writer's idle poll). A ring holds queue_size samples: at 100 Hz that is 1000 s of a
# stalled writer.
DRAIN_PERIOD_S = 0.1
# Whole maps (~240 kB each, ≤ 1 Hz, recorded every map_period_s): a ring of 256 holds a
# stalled writer's 4 minutes in ≤ 61 MB, where queue_size of them could hold gigabytes.
MAP_RING = 256


def logged_keys() -> list[str]:
    """Key expressions to subscribe: every logged publish row (wildcards for per-service rows)."""
    return [t.key for t in keys.TOPICS if t.logged and t.kind == "pub"]


def ring_size(key: str, cfg: LoggerConfig) -> int:
    """Samples the ring of `key` holds before its oldest is dropped."""
    row = keys.by_key(key) if "*" not in key else None
    return min(MAP_RING, cfg.queue_size) if row is not None and row.type is OccupancyGrid \
        else cfg.queue_size


def start(node: Node, cfg: LoggerConfig) -> None:
    try:
        recorder = Recorder(cfg, time.time_ns(), time.monotonic())
    except (ValueError, OSError) as e:
        raise ConfigError(f"[logger] cannot record to {cfg.path}: {e}") from None
    node.log.info("recording to %s", recorder.path)
    if recorder.path != recorder.requested:
        node.event("info", f"{recorder.requested} (or its parts) exists and is never "
                           f"overwritten: recording to {recorder.path}")
    node.health.detail = f"recording to {recorder.path}"
    node.health.thresholds.update(queue_size=cfg.queue_size, flush_period_s=cfg.flush_period_s,
                                  max_size_mib=cfg.max_size_mib,
                                  max_duration_s=cfg.max_duration_s,
                                  drain_period_s=DRAIN_PERIOD_S)
    inboxes = [node.inbox(k, ring_size(k, cfg)) for k in logged_keys()]
    # Not a daemon: the process waits for the file's summary at exit. A writer that dies is a
    # fault the watchdog restarts (a new file), never a recording silently stopped.
    node.thread(lambda: _write_loop(node, recorder, inboxes, Intake(cfg)), "writer",
                daemon=False)


class _Reporter:
    """Moves the recorder's counters into health once a second; a drop becomes a warning."""

    def __init__(self, node: Node, recorder: Recorder) -> None:
        self.node, self.recorder = node, recorder
        self.reported = dict.fromkeys(recorder.counters, 0)
        self.dropped_reported = 0
        self.last = time.monotonic()
        self.queue_max = 0
        self.full: dict[str, int] = {}  # key expression → its ring size, when found full

    def overflowed(self, box: Inbox) -> None:
        self.node.health.count("dropped")  # at least one sample lost (Zenoh does not count)
        self.full[box.key_expr] = box.capacity

    def report(self, now: float, force: bool) -> None:
        if now - self.last < 1.0 and not force:
            return
        self.last = now
        health, recorder = self.node.health, self.recorder
        for k, v in recorder.counters.items():
            if v != self.reported[k]:
                health.count(k, v - self.reported[k])
                self.reported[k] = v
        health.counters["queue_max"] = self.queue_max
        health.counters["files"] = len(recorder.files)
        if self.reported["decode_errors"] and recorder.last_error:
            health.record_fault(recorder.last_error)
        dropped = health.counters.get("dropped", 0)
        if dropped > self.dropped_reported:
            rings = ", ".join(f"{k} ({n})" for k, n in self.full.items())
            msg = (f"queue full: the ring of {rings} was full, its oldest samples were "
                   f"dropped ({dropped - self.dropped_reported} full rings, {dropped} in all)")
            recorder.note("warning", msg, time.time_ns())
            self.node.event("warning", msg)
            self.dropped_reported = dropped
            self.full.clear()


def _drain(inboxes: list[Inbox], intake: Intake, recorder: Recorder,
           reporter: _Reporter) -> bool:
    """Write what waits in the rings, in time order; True if one was over half full."""
    batch: list[tuple[int, str, bytes]] = []
    busy = False
    for box in inboxes:
        n = box.drain(batch)
        reporter.queue_max = max(reporter.queue_max, n)
        if n >= box.capacity:
            reporter.overflowed(box)
        busy = busy or n > box.capacity // 2
    batch.sort(key=itemgetter(0))  # (stable: one key's samples stay in arrival order)
    for t, key, payload in batch:
        if intake.take(key, t):
            recorder.write(key, payload, t)
    return busy


def _write_loop(node: Node, recorder: Recorder, inboxes: list[Inbox], intake: Intake) -> None:
    reporter = _Reporter(node, recorder)
    try:
        while True:
            stopping = node.stop_event.is_set()
            busy = _drain(inboxes, intake, recorder, reporter)
            now = time.monotonic()
            recorder.tick(now)
            reporter.report(now, stopping)
            if stopping:
                break
            if not busy:
                node.stop_event.wait(DRAIN_PERIOD_S)
    finally:
        recorder.finish()
        node.log.info("recording finished: %s (%d messages)", ", ".join(
            str(p) for p in recorder.files), recorder.counters["written"])


def main(argv: list[str] | None = None) -> int:
    return service_main("logger", LoggerConfig, start, argv, description=__doc__ or "",
                        timestamps=True)


if __name__ == "__main__":
    sys.exit(main())
