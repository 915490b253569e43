"""autochair-logger: records every logged key to MCAP without ever blocking a publisher.

Zenoh callbacks only append (key, payload, receive time) to a bounded queue; one writer thread
decodes, transcodes and writes. A full queue drops the sample, counts it (`dropped` in health)
and the writer reports it as a warning event and a foxglove.Log in the file. The writer thread
is not a daemon: on SIGTERM it drains the queue and finishes the file (summary and indexes)
before the process exits. A restart never truncates a recording: files are created
exclusively, a taken name gets a suffix (see autochair.logger.writer).
"""

from __future__ import annotations

import sys
import time
from collections import deque

from autochair.runtime import ConfigError, Node, service_main
from autochair_msgs import keys

from .writer import Intake, LoggerConfig, Recorder

IDLE_WAIT_S = 0.1  # writer poll period when the queue is empty (10 wakeups/s)


def logged_keys() -> list[str]:
    """Key expressions to subscribe: every logged publish row (wildcards for per-service rows)."""
    return [t.key for t in keys.TOPICS if t.logged and t.kind == "pub"]


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
                                  max_duration_s=cfg.max_duration_s)
    queue: deque[tuple[str, bytes, int]] = deque()
    limit = cfg.queue_size
    health = node.health
    intake = Intake(cfg)

    def on_sample(key: str, payload: bytes) -> None:
        # Runs on a Zenoh thread: append and return, nothing else (never block a publisher).
        now = time.time_ns()
        if not intake.take(key, now):
            return
        if len(queue) >= limit:
            health.count("dropped")
            return
        queue.append((key, payload, now))

    node.record_raw(logged_keys(), on_sample)
    # Not a daemon: the process waits for the file's summary at exit. A writer that dies is a
    # fault the watchdog restarts (a new file), never a recording silently stopped.
    node.thread(lambda: _write_loop(node, recorder, queue), "writer", daemon=False)


class _Reporter:
    """Moves the recorder's counters into health once a second; a drop becomes a warning."""

    def __init__(self, node: Node, recorder: Recorder) -> None:
        self.node, self.recorder = node, recorder
        self.reported = dict.fromkeys(recorder.counters, 0)
        self.dropped_reported = 0
        self.last = time.monotonic()
        self.queue_max = 0

    def report(self, now: float, queued: int, force: bool) -> None:
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
            msg = (f"queue full ({queued}/{recorder.cfg.queue_size}): dropped "
                   f"{dropped - self.dropped_reported} samples ({dropped} in all)")
            recorder.note("warning", msg, time.time_ns())
            self.node.event("warning", msg)
            self.dropped_reported = dropped


def _write_loop(node: Node, recorder: Recorder, queue: deque[tuple[str, bytes, int]]) -> None:
    reporter = _Reporter(node, recorder)
    try:
        while True:
            stopping = node.stop_event.is_set()
            reporter.queue_max = max(reporter.queue_max, len(queue))
            n = 0
            while queue:
                recorder.write(*queue.popleft())
                n += 1
            now = time.monotonic()
            recorder.tick(now)
            reporter.report(now, len(queue), stopping)
            if stopping:
                break
            if n == 0:
                node.stop_event.wait(IDLE_WAIT_S)
    finally:
        recorder.finish()
        node.log.info("recording finished: %s (%d messages)", ", ".join(
            str(p) for p in recorder.files), recorder.counters["written"])


def main(argv: list[str] | None = None) -> int:
    return service_main("logger", LoggerConfig, start, argv, description=__doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
