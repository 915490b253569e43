"""Node: one service's Zenoh session, typed pub/sub, liveliness, health, rate loops, shutdown."""

from __future__ import annotations

import argparse
import collections
import contextlib
import faulthandler
import logging
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from typing import Any, TypeVar

import msgspec
import zenoh

from autochair_msgs import Health, LogEvent, keys

from . import client
from .config import (
    ChairGeometry,
    ConfigError,
    StaleConfig,
    ZenohSettings,
    load_section,
    load_zenoh,
)
from .session import open_session
from .watchdog import CHECK_PERIOD_S, LOOP_PERIODS, Liveness, Notifier

T = TypeVar("T", bound=msgspec.Struct)
C = TypeVar("C")

def encode(msg: msgspec.Struct) -> bytes:
    return client.ENCODER.encode(msg)


class HealthState:
    """Counters and state a node reports; rates are derived from counter deltas."""

    def __init__(self, service: str) -> None:
        self.service = service
        self.state = "starting"
        self.detail = ""
        self.last_fault = ""
        self.last_fault_stamp_ns = 0
        self.thresholds: dict[str, float] = {}
        self.counters: dict[str, int] = {}
        self._lock = threading.Lock()
        self._prev: dict[str, int] = {}
        self._prev_t = time.monotonic()
        self._start = time.monotonic()

    def count(self, name: str, n: int = 1) -> None:
        with self._lock:
            self.counters[name] = self.counters.get(name, 0) + n

    def record_fault(self, message: str) -> None:
        """Remember the last fault for health (the state is left as it is)."""
        self.last_fault = message
        self.last_fault_stamp_ns = time.time_ns()

    def snapshot(self) -> Health:
        now = time.monotonic()
        with self._lock:
            counters = dict(self.counters)
        dt = max(now - self._prev_t, 1e-9)
        rates = {k: round((v - self._prev.get(k, 0)) / dt, 3) for k, v in counters.items()}
        self._prev, self._prev_t = counters, now
        return Health(
            stamp_ns=time.time_ns(),
            service=self.service,
            state=self.state,
            uptime_s=round(now - self._start, 3),
            counters=counters,
            rates_hz=rates,
            thresholds=dict(self.thresholds),
            detail=self.detail,
            last_fault=self.last_fault,
            last_fault_stamp_ns=self.last_fault_stamp_ns,
        )


class Node:
    """What every service process has. Callbacks run on Zenoh threads: keep them short.

    Hung-process watchdog: from `run()` on, a watchdog thread checks 4 × a second that every
    rate loop of `every()` completed a tick within max(stale.watchdog_s, 3 × its period), that
    no subscription or query callback has been running longer than stale.watchdog_s and that
    no worker thread of `thread()` has ended.
    Only then does it send `WATCHDOG=1` to $NOTIFY_SOCKET (sd_notify; `READY=1` once at the
    start, `STOPPING=1` at shutdown; no $NOTIFY_SOCKET: nothing is sent). When something is
    late it logs what and the stack of every thread, and sends `WATCHDOG=trigger` with the
    reason in `STATUS=`: systemd, the launcher and `autochair-watchdog` then kill and restart
    the process at once instead of waiting for the missing pings to time out.

    Test hook (fault injection, not for production use): SIGUSR2 makes the node hang as a
    real deadlock would. Its rate loops and its subscription and query callbacks block (until
    shutdown) while the process, its Zenoh session and its liveliness token stay up, so its
    outputs go stale. `Node.hang()` does the same from code.
    """

    def __init__(self, name: str, settings: ZenohSettings | None = None,
                 stale: StaleConfig | None = None, chair: ChairGeometry | None = None,
                 *, timestamps: bool = False) -> None:
        self.name = name
        self.stale = stale or StaleConfig()  # the watchdog chain's thresholds ([stale])
        self.chair = chair or ChairGeometry()  # footprint and laser mount ([chair])
        self.config_path: str | None = None  # the file read (None: $AUTOCHAIR_CONFIG)
        self.log = logging.getLogger(name)
        self.stop_event = threading.Event()
        self.health = HealthState(name)
        self.liveness = Liveness(self.stale.watchdog_s)
        # Per `every` loop: when its running tick was due (time.monotonic()), its schedule
        # without the thread's wake-up latency.
        self.due: dict[str, float] = {}
        self._hung = threading.Event()  # the SIGUSR2 test hook
        self._asked = threading.local()  # the request `serve` is handling on this thread
        self._threads: list[threading.Thread] = []
        self._closers: list[Callable[[], Any]] = []
        settings = settings or ZenohSettings()
        self.session = open_session(_timestamped(settings) if timestamps else settings)
        try:
            self._token = self._declare_alone(name, settings)
        except ConfigError:
            self.session.close()
            raise
        self._health_pub = self.publisher(keys.HEALTH, keys.HEALTH.for_service(name))
        self._log_pub = self.publisher(keys.LOG)
        self.every(1.0, self.publish_health, "health")

    def _declare_alone(self, name: str, settings: ZenohSettings, grace_s: float = 3.0) -> Any:
        """Declare this service's token, refusing to run next to a twin in this chair (H39):
        two PIDs or gateways would both drive the chair, two e-stops disagree, and a twin's
        token hides the other's death from every watcher. A predecessor's token may linger a
        moment after it was stopped: wait `grace_s` for it to go.

        Asked through the hub as a client: a client's query is answered at once from the
        hub's whole table, where a fresh peer's own query finds nothing while its routes
        settle (measured: 9 of 20 fresh peers saw no token at first, 50 ms later all did;
        under load, seconds; 20 of 20 clients at once). Without a hub (none within 1 s): this
        session, every query for 0.3 s empty."""
        ask = self.session
        if settings.mode == "peer" and settings.connect:
            # (a hub not up yet: within 1 s, else this session's own queries)
            with contextlib.suppress(ConfigError):
                ask = open_session(msgspec.structs.replace(settings, mode="client", listen=[]),
                                   client_timeout_ms=1000)
        settle_s = 0.0 if ask is not self.session or settings.mode == "client" else 0.3
        start = time.monotonic()
        try:
            while True:
                alive = name in client.alive_services(ask)
                waited = time.monotonic() - start
                if alive and waited > grace_s:
                    raise ConfigError(f"another {name} is already running for this chair; "
                                      "two would both act on it: stop that one first")
                if not alive and waited >= settle_s:
                    break
                time.sleep(0.05)  # (polling a remote fact; nothing to wait on)
        finally:
            if ask is not self.session:
                ask.close()
        # (Two started within the same few milliseconds would both pass: a residual risk;
        # once declared, zenoh cannot tell a twin's token on the same key from one's own.)
        return client.declare_alive(self.session, name)

    # --- messaging -----------------------------------------------------------------------------
    def publisher(self, topic: keys.Topic[Any], key: str | None = None, *,
                  express: bool = True, reliable: bool = False) -> client.Publisher:
        """express: send at once instead of batching (the drive chain is latency-bound).
        reliable: block instead of dropping under congestion (e.g. an e-stop assert, which
        must never be lost), where the default drops: a stale control sample is worse than
        none. Publishers are undeclared by session.close(), not one by one: a callback may
        be using one."""
        return client.Publisher(self.session, topic, key, express=express, reliable=reliable,
                                stopping=self.stop_event)

    def watch_alive(self, service: str, on_change: Callable[[bool], None]) -> None:
        """`on_change(alive)` when `service`'s liveliness token appears or vanishes. A killed
        process's token vanishes within milliseconds, far sooner than any heartbeat."""
        def on_token(_service: str, alive: bool) -> None:
            token = self.liveness.enter(f"token {service}", time.monotonic())
            try:
                on_change(alive)
            finally:
                self.liveness.leave(token)

        self._closers.append(client.watch_alive(self.session, on_token, service).undeclare)

    def inbox(self, key_expr: str, capacity: int) -> Inbox:
        """Undecoded samples of `key_expr` held by Zenoh until drained (the logger's intake):
        no Python thread wakes per sample, unlike `subscribe` (profiled: a 100 Hz subscription
        wakes its callback thread 100 × a second). See `Inbox`."""
        return Inbox(self._ring(key_expr, capacity), key_expr, capacity, self.health)

    def _ring(self, key_expr: str, capacity: int) -> Any:
        """A subscriber whose samples Zenoh holds in a ring of `capacity` (the oldest dropped
        when full) until taken with `try_recv`: no Python thread wakes per sample."""
        sub = self.session.declare_subscriber(key_expr, zenoh.handlers.RingChannel(capacity))
        self._closers.append(sub.undeclare)
        return sub

    def subscribe(self, topic: keys.Topic[T], callback: Callable[[T], None],
                  key: str | None = None) -> None:
        """Subscribe with decoding; a malformed payload is counted and reported, never raised."""
        decoder = msgspec.msgpack.Decoder(topic.type)
        counter = f"decode_errors:{topic.key}"
        what = key or topic.key

        def on_sample(sample: zenoh.Sample) -> None:
            token = self.liveness.enter(what, time.monotonic())
            try:
                if self._hung.is_set():
                    self.stop_event.wait()  # the SIGUSR2 test hook: a deadlocked callback
                    return
                handle(sample)
            finally:
                self.liveness.leave(token)

        def handle(sample: zenoh.Sample) -> None:
            try:
                msg = decoder.decode(sample.payload.to_bytes())
            except (msgspec.DecodeError, msgspec.ValidationError) as e:
                self._malformed(counter, sample, e)
                return
            try:
                callback(msg)
            except Exception as e:  # a bug in one callback must not kill the Zenoh thread
                if self.stop_event.is_set():
                    return  # racing shutdown (e.g. a publisher already closed): not a fault
                self.health.count("callback_errors")
                self.health.record_fault(f"{type(e).__name__}: {e}")
                self.log.exception("callback for %s failed", sample.key_expr)

        sub = self.session.declare_subscriber(key or topic.key, on_sample)
        self._closers.append(sub.undeclare)

    def latest(self, topic: keys.Topic[T], key: str | None = None) -> Callable[[], T | None]:
        """The newest message of `topic` when asked, for a loop that needs only the current
        value at its own rate (the lidar simulator's pose per scan). Returns `get()`: the
        newest message received so far (None before the first). Zenoh's network thread keeps
        only the newest sample (a ring of one) and no Python thread wakes per message, unlike
        `subscribe` (profiled: each 100 Hz subscription wakes its callback thread 100 × a
        second). A malformed payload is counted and reported as in `subscribe`; the last good
        message stays."""
        decoder = msgspec.msgpack.Decoder(topic.type)
        counter = f"decode_errors:{topic.key}"
        sub = self.session.declare_subscriber(key or topic.key, zenoh.handlers.RingChannel(1))
        self._closers.append(sub.undeclare)
        lock = threading.Lock()  # several threads may ask (the lidar sim's pty and TCP ends)
        last: list[T | None] = [None]

        def get() -> T | None:
            with lock:
                sample = newest = sub.try_recv()
                while sample is not None:
                    newest, sample = sample, sub.try_recv()
                if newest is not None:
                    try:
                        last[0] = decoder.decode(newest.payload.to_bytes())
                    except (msgspec.DecodeError, msgspec.ValidationError) as e:
                        self._malformed(counter, newest, e)
                return last[0]

        return get

    def queued(self, topic: keys.Topic[T], capacity: int) -> Callable[[], list[T]]:
        """The messages of `topic` received since the last call, oldest first, for a worker
        that needs them only when it runs (mapping and localization place each scan by the
        odometry received before it): a ring of `capacity` (`_ring`), unlike `subscribe`.
        Returns `take()`; a malformed payload is counted and reported as in `subscribe`."""
        decoder = msgspec.msgpack.Decoder(topic.type)
        counter = f"decode_errors:{topic.key}"
        sub = self._ring(topic.key, capacity)

        def take() -> list[T]:
            out: list[T] = []
            while (sample := sub.try_recv()) is not None:
                try:
                    out.append(decoder.decode(sample.payload.to_bytes()))
                except (msgspec.DecodeError, msgspec.ValidationError) as e:
                    self._malformed(counter, sample, e)
            return out

        return take

    def _malformed(self, counter: str, sample: zenoh.Sample, e: Exception) -> None:
        """Count a payload that does not decode; report the 1st, 10th, 100th, 1000th."""
        self.health.count(counter)
        if self.health.counters.get(counter, 0) in (1, 10, 100, 1000):
            self.event("warning", f"malformed payload on {sample.key_expr}: {e}")

    def serve(self, topic: keys.Topic[T], handler: Callable[[T], msgspec.Struct]) -> None:
        """Answer queries on a `kind="query"` row of the key table: the request decoded as the
        row's type, the handler's reply (the row's reply type) encoded. A malformed request is
        counted and answered with an error reply naming it; so is a handler that fails."""
        assert topic.kind == "query" and topic.reply is not None, topic.key
        decoder = msgspec.msgpack.Decoder(topic.type)
        reply_type = topic.reply

        def on_query(query: zenoh.Query) -> None:
            payload = query.payload.to_bytes() if query.payload is not None else b""
            try:
                request = decoder.decode(payload)
            except (msgspec.DecodeError, msgspec.ValidationError) as e:
                self.health.count(f"bad_requests:{topic.key}")
                query.reply_err(f"bad request on {topic.key}: {e}".encode())
                return
            attachment = None if query.attachment is None else query.attachment.to_bytes()
            late = client.too_late(attachment, time.time_ns(), self.stale.clock_skew_s)
            if late:
                self.health.count(f"late_requests:{topic.key}")
                self.event("warning", f"{topic.key}: request not acted on: {late}")
                query.reply_err(f"{topic.key}: not acted on: {late}".encode())
                return
            self._asked.attachment, self._asked.key = attachment, topic.key
            try:
                reply = handler(request)
                if not isinstance(reply, reply_type):
                    raise TypeError(f"{topic.key} handler returned {type(reply).__name__}, "
                                    f"not {reply_type.__name__}")
            except Exception as e:
                query.reply_err(f"{topic.key}: {type(e).__name__}: {e}".encode())
                raise  # counted and logged by `queryable`
            query.reply(query.key_expr, client.ENCODER.encode(reply))

        self.queryable(topic, on_query)

    def too_late(self) -> str:
        """In a `serve` handler: why its request may no longer be acted on ('' if it may).
        A handler that works long before it acts (a goal's route check) asks again just
        before acting: its asker may have given up meanwhile (hazards H43)."""
        late = client.too_late(getattr(self._asked, "attachment", None), time.time_ns(),
                               self.stale.clock_skew_s)
        if late:
            key = getattr(self._asked, "key", "?")
            self.health.count(f"late_requests:{key}")
            self.event("warning", f"{key}: request not acted on: {late}")
        return late

    def queryable(self, topic: keys.Topic[Any], handler: Callable[[zenoh.Query], None]) -> None:
        """Serve raw queries on a `kind="query"` row (prefer `serve`); the handler must reply
        and return quickly."""

        def guarded(query: zenoh.Query) -> None:
            token = self.liveness.enter(f"query {topic.key}", time.monotonic())
            try:
                if self._hung.is_set():
                    self.stop_event.wait()  # the SIGUSR2 test hook
                    return
                handler(query)
            except Exception as e:
                self.health.count("query_errors")
                self.health.record_fault(f"{type(e).__name__}: {e}")
                self.log.exception("query on %s failed", topic.key)
            finally:
                self.liveness.leave(token)

        q = self.session.declare_queryable(topic.key, guarded)
        self._closers.append(q.undeclare)

    def on_close(self, fn: Callable[[], Any]) -> None:
        """Run `fn` at shutdown, after the loops have stopped (last registered, first run)."""
        self._closers.append(fn)

    def event(self, level: str, message: str) -> None:
        """Log locally and publish a LogEvent (warnings and worse also become `last_fault`)."""
        self.log.log(getattr(logging, level.upper(), logging.INFO), message)
        if level in ("warning", "error", "fatal"):
            self.health.record_fault(message)
        with contextlib.suppress(zenoh.ZError):  # the session may be closing
            self._log_pub.put(LogEvent(stamp_ns=time.time_ns(), service=self.name,
                                       level=level, message=message))

    def publish_health(self) -> None:
        self._health_pub.put(self.health.snapshot())

    # --- time ----------------------------------------------------------------------------------
    def every(self, period_s: float, fn: Callable[[], None], name: str,
              slow_s: float = 0.0) -> None:
        """Call `fn` every `period_s` on its own thread, drift-free on the monotonic clock.

        Missed ticks are skipped (not bunched) and counted as `overruns:<name>`; `due[name]` is
        when the running tick was due (a loop that steps a plan steps it by that, not by when
        its thread woke: the wake-up latency is jitter, not time). Each completed
        tick is reported to the watchdog: a loop stuck for max(stale.watchdog_s, 3 × period_s)
        gets the process restarted (see the class docstring). A tick that raises is counted and
        reported but not completed, so a loop that fails on every tick is restarted like a stuck
        one instead of counting as alive; one failure among good ticks is not. `slow_s`: a
        loop whose ticks may take this long under load (and whose lateness stops nothing that
        moves the chair) is not declared stuck before it.
        """
        # (the watchdog's bound is LOOP_PERIODS × the period it is given: slow_s at least)
        self.liveness.add_loop(name, max(period_s, slow_s / LOOP_PERIODS), time.monotonic())

        def loop() -> None:
            next_t = time.monotonic()
            while not self.stop_event.is_set():
                if self._hung.is_set():
                    self.stop_event.wait()  # the SIGUSR2 test hook: a deadlocked loop
                    break
                done = False
                self.due[name] = next_t
                try:
                    fn()
                    done = True
                except Exception as e:
                    self.health.count(f"errors:{name}")
                    self.health.record_fault(f"{name}: {type(e).__name__}: {e}")
                    self.log.exception("periodic %s failed", name)
                next_t += period_s
                now = time.monotonic()
                if done:
                    self.liveness.tick(name, now)
                if now > next_t:
                    skipped = int((now - next_t) / period_s) + 1
                    self.health.count(f"overruns:{name}", skipped)
                    next_t += skipped * period_s
                self.stop_event.wait(next_t - now)

        self.thread(loop, name)

    def beat(self, name: str, period_s: float) -> Beat:
        """The watchdog's view of a loop that runs on a thread of its own (`thread`) instead
        of `every`, e.g. the gateway's tick done by its serial reader after each read, which
        saves a thread waking at the frame rate. Call the returned `beat()` after each
        completed iteration (at least every `period_s`); a loop with no beat for
        max(stale.watchdog_s, 3 × period_s) gets the process restarted, as for `every`.
        `beat.pause()`: not expected to beat until the next `beat()` (around a blocking call
        that has its own bound, e.g. opening a serial URL). Under the SIGUSR2 test hook
        `beat()` blocks until shutdown, as a deadlocked loop would."""
        self.liveness.add_loop(name, period_s, time.monotonic())
        return Beat(self, name)

    def thread(self, target: Callable[[], None], name: str, daemon: bool = True) -> None:
        """Run `target` on its own thread until shutdown. If it ends before (an exception, or
        a return), the node reports a fault and the watchdog has the process restarted: a
        dead serial reader or map worker must not hide behind a live liveliness token.
        `daemon=False`: the process waits for it at exit (the logger's writer finishes its file)."""

        def run() -> None:
            try:
                target()
                why = "returned"
            except Exception as e:
                self.log.exception("thread %s failed", name)
                why = f"{type(e).__name__}: {e}"
            if self.stop_event.is_set():
                return
            self.health.state = "fault"
            self.health.record_fault(f"thread {name} ended: {why}")
            self.liveness.ended(name, why, time.monotonic())

        t = threading.Thread(target=run, name=f"{self.name}-{name}", daemon=daemon)
        self._threads.append(t)
        t.start()

    def worker(self, name: str, handle: Callable[[T], None], maxlen: int,
               dropped: str) -> Callable[[T], None]:
        """A thread of its own for slow work on received messages (scan matching, ray
        updates), so no Zenoh callback waits on it. Returns `put`, for the callback: never
        blocks; when the worker is `maxlen` behind, the oldest waiting item is dropped and
        counted as `dropped`. Items are handled in order; an exception ends the thread, which
        the watchdog reports (see `thread`)."""
        pending: collections.deque[T] = collections.deque(maxlen=maxlen)
        wake = threading.Event()

        def put(item: T) -> None:
            if len(pending) == maxlen:
                self.health.count(dropped)
            pending.append(item)
            wake.set()

        def run() -> None:
            while not self.stop_event.is_set():
                wake.wait(0.2)
                wake.clear()
                while pending:
                    handle(pending.popleft())

        self.thread(run, name)
        return put

    # --- watchdog ------------------------------------------------------------------------------
    def hang(self) -> None:
        """Test hook (SIGUSR2): block every rate loop and callback until shutdown, as a
        deadlock would, leaving the process, session and liveliness token up.
        Signal-safe: only sets an event and writes one line to stderr."""
        self._hung.set()
        with contextlib.suppress(OSError):
            os.write(2, f"{self.name}: test hook: hanging (loops and callbacks block)\n".encode())

    def _watchdog(self) -> None:
        """Ping the supervisor while every loop and callback is on time (see the class doc)."""
        notifier = Notifier.from_env()
        send = notifier.send if notifier is not None else (lambda _msg: False)
        send("READY=1")
        reported = False
        next_ping = time.monotonic() + CHECK_PERIOD_S
        while True:
            # Wake for the next ping, or when the first loop or callback would become late.
            wake = next_ping if reported else min(next_ping, self.liveness.next_due() + 0.002)
            if self.stop_event.wait(max(0.0, wake - time.monotonic())):
                break
            now = time.monotonic()
            ping_due = now >= next_ping
            if ping_due:
                next_ping = now + CHECK_PERIOD_S
            late = self.liveness.late(now)
            if not late:
                if reported:
                    self.event("info", "watchdog: loops and callbacks on time again")
                    reported = False
                if ping_due:
                    send("WATCHDOG=1")
                continue
            if reported:
                continue
            reported = True
            why = "; ".join(str(x) for x in late)
            self.health.count("watchdog_late")
            self.event("error", f"watchdog: hung: {why}")
            with contextlib.suppress(Exception):  # where it is stuck, for the log
                sys.stderr.flush()
                faulthandler.dump_traceback(file=sys.stderr, all_threads=True)
            send(f"WATCHDOG=trigger\nSTATUS=hung: {why}")
        send("STOPPING=1")
        if notifier is not None:
            notifier.close()

    # --- life ----------------------------------------------------------------------------------
    def run(self) -> None:
        """Block until SIGTERM/SIGINT (or `stop_event`), then shut down cleanly."""
        if self.health.state == "starting":
            self.health.state = "ok"
        self.publish_health()
        self.thread(self._watchdog, "watchdog")
        wait_for_stop(self.stop_event)
        # A shutdown that hangs leaves its stacks in the log before the supervisor kills it.
        faulthandler.dump_traceback_later(3.0, exit=False)
        self.close()
        faulthandler.cancel_dump_traceback_later()

    def close(self) -> None:
        """Stop loops, stop inflow (subscribers, queryables), then close the session."""
        self.stop_event.set()
        for t in self._threads:
            if t is not threading.current_thread():
                t.join(timeout=2.0)
        for closer in reversed(self._closers):
            # RuntimeError: pyo3's "Already borrowed" if a callback holds it at this moment
            with contextlib.suppress(zenoh.ZError, RuntimeError):
                closer()
        with contextlib.suppress(zenoh.ZError, RuntimeError):
            self._token.undeclare()
        self.session.close()


class Beat:
    """A loop's beat for the node's watchdog (see `Node.beat`)."""

    def __init__(self, node: Node, name: str) -> None:
        self._node, self._name = node, name

    def __call__(self) -> None:
        node = self._node
        if node._hung.is_set():  # the SIGUSR2 test hook: a deadlocked loop
            node.stop_event.wait()
            return
        node.liveness.tick(self._name, time.monotonic())

    def pause(self) -> None:
        self._node.liveness.tick(self._name, math.inf)  # never late until the next beat


class Inbox:
    """Samples of one key expression queued on Zenoh's side (`Node.inbox`): a ring of
    `capacity`, drained by the caller's thread in batches. Zenoh's ring drops its oldest sample
    when full, without a count: a drain that finds `capacity` samples reports the ring full
    (samples were, or may have been, lost; how many is unknown), so a loss is never silent.

    Each sample's time is its Zenoh timestamp: with `Node(timestamps=True)` the session stamps
    every sample that has none as it arrives (the hub stamps what it relays from clients), so
    the time is the arrival in Zenoh, within a millisecond of the publish, not the drain. A
    sample without one (a session without timestamps) gets the drain time, counted as
    `unstamped`."""

    def __init__(self, sub: Any, key_expr: str, capacity: int, health: HealthState) -> None:
        self._sub, self.key_expr, self.capacity, self._health = sub, key_expr, capacity, health
        self._fixed = None if "*" in key_expr else key_expr  # a concrete key: no str() per sample

    def drain(self, out: list[tuple[int, str, bytes]]) -> int:
        """Append `(time ns, key, payload)` of the waiting samples (at most `capacity`, in
        arrival order) to `out`; returns how many (== capacity: the ring was full)."""
        n, recv, fixed = 0, self._sub.try_recv, self._fixed
        while n < self.capacity and (sample := recv()) is not None:
            ts = sample.timestamp
            if ts is not None:
                t = ts.get_time_as_ntp64().as_nanos()
            else:
                t = time.time_ns()
                self._health.count("unstamped")
            out.append((t, fixed or str(sample.key_expr), sample.payload.to_bytes()))
            n += 1
        return n


def _timestamped(settings: ZenohSettings) -> zenoh.Config:
    """`settings` with Zenoh timestamping on: the session stamps each sample on arrival."""
    cfg = settings.to_zenoh()
    cfg.insert_json5("timestamping/enabled", "true")
    return cfg


def wait_for_stop(stop: threading.Event) -> None:
    """Block the main thread until `stop` is set, waking often.

    Python runs signal handlers in the main thread, but the kernel may deliver SIGTERM to any
    thread (Zenoh runs many): a main thread in an untimed wait then never runs the handler, and
    the process ignored SIGTERM until SIGKILL (seen: 1 in 3 `autochair up` shutdowns).
    """
    while not stop.wait(0.2):
        pass


def _install_signal_handlers(stop: threading.Event,
                             hang: Callable[[], None] | None = None) -> None:
    def handler(signum: int, _frame: object) -> None:
        stop.set()

    signal.signal(signal.SIGTERM, handler)
    signal.signal(signal.SIGINT, handler)
    if hang is not None:  # the SIGUSR2 test hook (Node.hang)
        signal.signal(signal.SIGUSR2, lambda _s, _f: hang())


def setup_logging(level: str = "INFO") -> None:
    logging.basicConfig(
        level=level.upper(),
        format="%(asctime)s %(name)s %(levelname)s %(message)s",
        stream=sys.stderr,
    )


def _parser(name: str, description: str) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=f"autochair-{name}", description=description)
    parser.add_argument("--config", help="TOML config file (default: $AUTOCHAIR_CONFIG)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help=f"override a [{name}] setting (or stale.KEY, chair.KEY); "
                             "repeatable")
    parser.add_argument("--connect", help="Zenoh endpoint(s) of the hub, comma-separated")
    parser.add_argument("--zenoh-mode", choices=("peer", "client"),
                        help="peer: direct links to every other peer (the drive chain); "
                             "client: one link, to the hub, which relays (default: [zenoh] "
                             "mode)")
    parser.add_argument("--log-level", default="INFO")
    return parser


def _settings(name: str, config_type: type[C], path: str | None, sets: list[str]
              ) -> tuple[C, StaleConfig, ChairGeometry]:
    """The service's section and the shared [stale] and [chair], each with its --set
    overrides (`stale.KEY=...`, `chair.KEY=...`; the rest are the service's)."""
    def overrides(prefix: str) -> list[str]:
        return [o.removeprefix(prefix) for o in sets if o.startswith(prefix)]

    own = [o for o in sets if not o.startswith(("stale.", "chair."))]
    return (load_section(config_type, name, path, own),
            load_section(StaleConfig, "stale", path, overrides("stale.")),
            load_section(ChairGeometry, "chair", path, overrides("chair.")))


def zenoh_settings(path: str | None, connect: str | None, mode: str | None) -> ZenohSettings:
    """[zenoh] with the command line's hub and mode. A client listens nowhere: its one link is
    to the hub. Why clients at all: every link of a peer carries a keepalive each lease / 4
    (250 ms at lease_ms = 1000), so a full mesh of n peers wakes every process ~8 (n - 1)
    times a second doing nothing; measured, 12 idle peers cost 15 % of a core, as clients 2 %
    (plus 1 % for the hub). A process whose traffic is light and not latency-bound (10 Hz
    scans, maps, the simulators) is a client (processes.py); the drive chain stays peers."""
    settings = load_zenoh(path, connect)
    if mode is not None:
        settings.mode = mode
        if mode == "client":
            settings.listen = []
    return settings


def service_main(
    name: str,
    config_type: type[C],
    start: Callable[[Node, C], None],
    argv: list[str] | None = None,
    description: str = "",
    *,
    timestamps: bool = False,
) -> int:
    """The `main` of every service: parse common flags, load config, start, run until signal.

    `start(node, config)` declares subscriptions and loops and returns; errors there that are
    the user's (bad config, missing device) are ConfigError and print as one line.
    `timestamps`: Zenoh stamps each sample on arrival (`Inbox`; the logger).
    """
    args = _parser(name, description).parse_args(argv)
    setup_logging(args.log_level)
    try:
        config, stale, chair = _settings(name, config_type, args.config, args.set)
        node = Node(name, zenoh_settings(args.config, args.connect, args.zenoh_mode), stale,
                    chair, timestamps=timestamps)
    except ConfigError as e:
        print(f"autochair-{name}: error: {e}", file=sys.stderr)
        return 2
    node.config_path = args.config
    _install_signal_handlers(node.stop_event, node.hang)
    try:
        start(node, config)
    except ConfigError as e:
        print(f"autochair-{name}: error: {e}", file=sys.stderr)
        node.close()
        return 2
    node.event("info", f"{name} started")
    node.run()
    return 0
