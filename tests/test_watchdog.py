"""Hung-process watchdog: the pure decisions, the sd_notify socket pair, a node in process and
the `autochair-watchdog` wrapper around small child processes."""

from __future__ import annotations

import itertools
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from autochair.runtime import Node, ZenohSettings
from autochair.runtime.node import encode
from autochair.runtime.watchdog import (
    CHECK_PERIOD_S,
    Late,
    Liveness,
    Notifier,
    NotifyChannel,
    PingWatch,
    late,
    next_due,
    notify,
    parse,
)
from autochair.watchdog_wrapper import HUNG_EXIT
from autochair_msgs import EStopAssert, LogEvent, keys
from tests.helpers import stop_process, wait_for


# --- which loops are late (pure) ------------------------------------------------------------------
def test_loops_on_time_are_not_late() -> None:
    loops = {"tick": (0.005, 10.0), "health": (1.0, 9.0)}
    assert late(loops, [], now=10.2, watchdog_s=1.5) == []


def test_a_fast_loop_is_late_after_watchdog_s() -> None:
    loops = {"tick": (0.005, 10.0)}
    assert late(loops, [], now=11.5, watchdog_s=1.5) == []
    (x,) = late(loops, [], now=11.51, watchdog_s=1.5)
    assert x.what == "loop tick" and x.bound_s == 1.5
    assert x.age_s == pytest.approx(1.51)
    assert str(x) == "loop tick: no tick for 1.51 s (bound 1.50 s)"


def test_a_slow_loop_gets_three_periods() -> None:
    loops = {"health": (1.0, 10.0)}
    assert late(loops, [], now=12.9, watchdog_s=1.5) == []  # 2.9 s: within 3 × 1 s
    assert [x.what for x in late(loops, [], now=13.1, watchdog_s=1.5)] == ["loop health"]
    # a longer watchdog_s wins over 3 periods
    assert late(loops, [], now=13.1, watchdog_s=4.0) == []


def test_a_callback_running_too_long_is_late_and_a_finished_one_is_not() -> None:
    calls = [("autochair/odom", 10.0), ("autochair/cmd/vel", 11.0)]
    (x,) = late({}, calls, now=11.6, watchdog_s=1.5)
    assert x == Late("callback autochair/odom", pytest.approx(1.6), 1.5)  # type: ignore[arg-type]
    assert str(x).startswith("callback autochair/odom: running for 1.60 s")

    live = Liveness(watchdog_s=1.5)
    token = live.enter("autochair/odom", 10.0)
    assert [y.what for y in live.late(11.6)] == ["callback autochair/odom"]
    live.leave(token)
    assert live.late(11.6) == []


def test_an_ended_thread_is_late_at_once_with_why_and_a_running_one_is_not() -> None:
    loops = {"tick": (0.005, 10.0)}
    assert late(loops, [], now=10.1, watchdog_s=1.5, ended={}) == []  # control: on time
    (x,) = late(loops, [], now=10.1, watchdog_s=1.5, ended={"serial": ("OSError: gone", 10.0)})
    assert str(x) == "thread serial: ended 0.10 s ago (OSError: gone)"
    assert next_due(loops, [], 1.5, {"serial": ("returned", 10.0)}) == 10.0


def test_next_due_is_when_the_first_thing_would_be_late() -> None:
    loops = {"tick": (0.005, 10.0), "health": (1.0, 9.8)}
    assert next_due(loops, [], 1.5) == pytest.approx(11.5)  # tick: 10.0 + 1.5
    assert next_due(loops, [("autochair/odom", 9.9)], 1.5) == pytest.approx(11.4)
    assert next_due({"health": (1.0, 9.8)}, [], 1.5) == pytest.approx(12.8)  # 3 periods
    assert next_due({}, [], 1.5) == float("inf")
    for now in (11.39, 11.41):  # consistent with late(): late exactly after the due time
        assert bool(late(loops, [("autochair/odom", 9.9)], now, 1.5)) == (now > 11.4)


def test_liveness_counts_from_registration_until_the_first_tick() -> None:
    live = Liveness(watchdog_s=1.5)
    live.add_loop("sim", 0.005, now=100.0)
    assert live.late(101.4) == []
    assert [x.what for x in live.late(101.6)] == ["loop sim"]  # never ticked
    live.tick("sim", 101.6)
    assert live.late(102.0) == []


# --- the supervisor's bookkeeping (pure) -------------------------------------------------------
def test_pings_arm_the_watch_and_their_absence_is_a_hang() -> None:
    w = PingWatch(timeout_s=1.5)
    assert w.hung(1000.0) is None  # never pinged: a slow start is not a hang
    w.on_message(parse(b"READY=1"), 0.0)
    assert w.ready and w.hung(1000.0) is None
    w.on_message(parse(b"WATCHDOG=1"), 10.0)
    assert w.hung(11.5) is None
    assert w.hung(11.6) == "no watchdog ping for 1.60 s"
    w.on_message(parse(b"WATCHDOG=1"), 11.6)
    assert w.hung(11.7) is None and w.pings == 2


def test_a_trigger_is_a_hang_at_once_with_its_reason() -> None:
    w = PingWatch(timeout_s=1.5)
    w.on_message(parse(b"WATCHDOG=1"), 10.0)
    w.on_message(parse(b"WATCHDOG=trigger\nSTATUS=hung: loop tick: no tick for 1.51 s"), 10.1)
    assert w.hung(10.1) == "watchdog trigger: hung: loop tick: no tick for 1.51 s"
    w.reset()  # a new process
    assert w.hung(100.0) is None and w.pings == 0


def test_a_stop_is_not_a_hang_unless_it_takes_too_long() -> None:
    w = PingWatch(timeout_s=1.5, stop_grace_s=5.0)
    w.on_message(parse(b"WATCHDOG=1"), 10.0)
    w.on_message(parse(b"STOPPING=1"), 10.2)
    assert w.hung(15.0) is None
    assert w.hung(15.3) == "still not stopped 5.1 s after stopping"
    v = PingWatch(timeout_s=1.5, stop_grace_s=5.0)
    v.on_message(parse(b"WATCHDOG=1"), 10.0)
    v.stopping(10.1)  # the supervisor's own SIGTERM
    assert v.hung(14.0) is None


def test_parse_skips_junk() -> None:
    assert parse(b"READY=1\nnonsense\n=x\nSTATUS=a=b\n\xff") == {"READY": "1", "STATUS": "a=b"}


# --- sd_notify over real datagram sockets --------------------------------------------------------
def test_notify_sends_one_datagram_to_a_path_socket(tmp_path: Path) -> None:
    path = str(tmp_path / "notify")
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as rx:
        rx.bind(path)
        rx.settimeout(5)
        assert notify("READY=1\nSTATUS=up", {"NOTIFY_SOCKET": path})
        assert rx.recv(4096) == b"READY=1\nSTATUS=up"
        n = Notifier(path)
        assert n.send("WATCHDOG=1") and n.send("WATCHDOG=1")
        assert [rx.recv(4096), rx.recv(4096)] == [b"WATCHDOG=1"] * 2
        n.close()


def test_no_notify_socket_is_a_no_op(tmp_path: Path) -> None:
    assert Notifier.from_env({}) is None
    assert not notify("WATCHDOG=1", {})
    n = Notifier(str(tmp_path / "nobody-listens"))
    assert not n.send("WATCHDOG=1") and n.failures == 1  # never raises
    n.close()


def test_channel_receives_abstract_and_counts_only_the_expected_pid() -> None:
    ch = NotifyChannel.open("test", timeout_s=1.5)
    try:
        assert ch.address.startswith("@autochair/")
        env = {"NOTIFY_SOCKET": ch.address}
        ch.expect(os.getpid() + 1)  # someone else's channel: our datagrams are foreign
        assert notify("WATCHDOG=1", env)
        wait_for(lambda: ch.poll(1.0) is None and ch.foreign == 1, 5, "the foreign datagram")
        assert ch.watch.pings == 0
        ch.expect(os.getpid())
        assert notify("READY=1", env) and notify("WATCHDOG=1", env)
        wait_for(lambda: ch.poll(2.0) is None and ch.watch.pings == 1, 5, "our ping")
        assert ch.watch.ready and ch.watch.last_ping == 2.0
        assert ch.poll(3.6) == "no watchdog ping for 1.60 s"
    finally:
        ch.close()


# --- a node in process ---------------------------------------------------------------------------
@pytest.fixture
def supervised(monkeypatch: pytest.MonkeyPatch) -> Iterator[NotifyChannel]:
    ch = NotifyChannel.open("node-test", timeout_s=1.5)
    ch.expect(os.getpid())
    monkeypatch.setenv("NOTIFY_SOCKET", ch.address)
    try:
        yield ch
    finally:
        ch.close()


def run_node(node: Node) -> threading.Thread:
    t = threading.Thread(target=node.run, daemon=True)
    t.start()
    return t


def test_node_pings_while_on_time_and_says_stopping(supervised: NotifyChannel) -> None:
    node = Node("wdtest", ZenohSettings(connect=[], listen=["tcp/127.0.0.1:0"]))
    node.every(0.01, lambda: None, "fast")
    t = run_node(node)
    try:
        wait_for(lambda: supervised.poll(time.monotonic()) is None
                 and supervised.watch.pings >= 6, 5, "6 pings")
        assert supervised.watch.ready
    finally:
        node.stop_event.set()
        t.join(10)
    wait_for(lambda: supervised.poll(time.monotonic()) is None
             and supervised.watch.stopping_since is not None, 5, "STOPPING=1")


def test_a_callback_stuck_in_a_lock_stops_the_pings_and_triggers(
        supervised: NotifyChannel) -> None:
    """A real deadlock shape (not the SIGUSR2 hook): a subscription callback waits on a lock
    that is never released. The fast loop keeps ticking: only the callback is stuck."""
    node = Node("wdtest", ZenohSettings(connect=[], listen=["tcp/127.0.0.1:0"]))
    events: list[LogEvent] = []
    node.subscribe(keys.LOG, events.append)
    stuck = threading.Lock()
    stuck.acquire()
    released = threading.Event()

    def deadlocked(_msg: EStopAssert) -> None:
        while not stuck.acquire(timeout=0.1):
            if released.is_set():
                return

    node.subscribe(keys.ESTOP_ASSERT, deadlocked)
    node.every(0.01, lambda: None, "fast")
    t = run_node(node)
    try:
        wait_for(lambda: supervised.poll(time.monotonic()) is None
                 and supervised.watch.pings >= 2, 5, "pings")
        t0 = time.monotonic()
        node.session.put(keys.ESTOP_ASSERT.key, encode(EStopAssert(
            stamp_ns=1, source="test", reason="x", active=True)))
        reason = wait_for(lambda: supervised.poll(time.monotonic()), 5, "hung")
        detect = time.monotonic() - t0
        print(f"callback deadlock detected after {detect:.2f} s: {reason}")
        assert "callback autochair/estop/assert: running for" in reason
        assert 1.5 <= detect < 2.0
        assert node.health.counters["watchdog_late"] == 1
        wait_for(lambda: any("watchdog: hung" in e.message for e in events), 5,
                 "the watchdog's LogEvent")
    finally:
        released.set()
        node.stop_event.set()
        t.join(10)


def test_a_worker_thread_that_dies_is_a_fault_and_triggers_the_watchdog(
        supervised: NotifyChannel) -> None:
    """A serial reader or map worker killed by an uncaught exception: the process, its session
    and its liveliness token stay up, so only the runtime can tell; it must, at once."""
    node = Node("wdtest", ZenohSettings(connect=[], listen=["tcp/127.0.0.1:0"]))
    go = threading.Event()

    def worker() -> None:
        while not node.stop_event.wait(0.01):
            if go.is_set():
                raise OSError("device vanished")

    node.thread(worker, "serial")
    t = run_node(node)
    try:
        wait_for(lambda: supervised.poll(time.monotonic()) is None
                 and supervised.watch.pings >= 2, 5, "pings while the worker runs")
        assert node.health.state == "ok"  # positive control: a running worker is no fault
        t0 = time.monotonic()
        go.set()
        reason = wait_for(lambda: supervised.poll(time.monotonic()), 5, "hung")
        detect = time.monotonic() - t0
        print(f"dead worker detected after {detect:.2f} s: {reason}")
        assert "thread serial: ended" in reason and "OSError: device vanished" in reason
        assert detect < CHECK_PERIOD_S + 0.2
        assert node.health.state == "fault"
        assert "thread serial" in node.health.last_fault  # what ended, and why
        assert "device vanished" in node.health.last_fault
    finally:
        node.stop_event.set()
        t.join(10)


def test_a_loop_that_fails_on_every_tick_triggers_the_watchdog(
        supervised: NotifyChannel) -> None:
    """A periodic step that raises on every tick (e.g. on a bad value it keeps) does nothing,
    yet its thread runs on: it must count as stuck, not alive. Positive control: the same loop
    failing on every other tick (a transient error among good ticks) keeps the pings going."""
    node = Node("wdtest", ZenohSettings(connect=[], listen=["tcp/127.0.0.1:0"]))
    ticks, always = [0], threading.Event()

    def step() -> None:
        ticks[0] += 1
        if always.is_set() or ticks[0] % 2:
            raise ValueError("bad waypoint")

    node.every(0.05, step, "plan")
    t = run_node(node)
    try:
        wait_for(lambda: ticks[0] >= 60, 10, "3 s of half-failing ticks")
        assert supervised.poll(time.monotonic()) is None  # positive control: still alive
        assert node.health.counters["errors:plan"] >= 25
        t0 = time.monotonic()
        always.set()
        reason = wait_for(lambda: supervised.poll(time.monotonic()), 10, "a trigger")
        detect = time.monotonic() - t0
        print(f"failing loop detected after {detect:.2f} s: {reason}")
        assert "plan" in reason
        assert detect < node.stale.watchdog_s + CHECK_PERIOD_S + 0.5
    finally:
        node.stop_event.set()
        t.join(10)


def test_a_loop_allowed_to_be_slow_gets_its_own_bound_and_the_others_keep_theirs() -> None:
    """H58: the control service's plan and map loops (a blocked cycle took 2.2 s under load)
    are not declared stuck before `slow_s`; the 50 Hz loop beside them still is after 1.5 s
    (positive control), and the slow one too once past its bound."""
    node = Node("wdtest", ZenohSettings(connect=[], listen=["tcp/127.0.0.1:0"]))
    try:
        t0 = time.monotonic()
        node.every(0.25, lambda: None, "plan", slow_s=5.0)
        node.every(0.02, lambda: None, "control")
        mine = ("loop control", "loop plan")  # (the node's own health loop aside)
        late = [x.what for x in node.liveness.late(t0 + 2.2) if x.what in mine]
        assert late == ["loop control"]
        late = [x.what for x in node.liveness.late(t0 + 5.2) if x.what in mine]
        assert late == ["loop control", "loop plan"]
    finally:
        node.close()


def test_a_worker_that_ends_at_shutdown_is_no_fault(supervised: NotifyChannel) -> None:
    node = Node("wdtest", ZenohSettings(connect=[], listen=["tcp/127.0.0.1:0"]))

    def worker() -> None:
        node.stop_event.wait()

    node.thread(worker, "serial")
    t = run_node(node)
    wait_for(lambda: supervised.poll(time.monotonic()) is None
             and supervised.watch.pings >= 1, 5, "a ping")
    node.stop_event.set()
    t.join(10)
    assert not t.is_alive() and node.health.state == "ok" and not node.health.last_fault
    assert node.liveness.late(time.monotonic()) == []


def test_the_hang_hook_blocks_loops_and_callbacks_until_shutdown(
        supervised: NotifyChannel) -> None:
    node = Node("wdtest", ZenohSettings(connect=[], listen=["tcp/127.0.0.1:0"]))
    ticks: list[float] = []
    node.every(0.01, lambda: ticks.append(time.monotonic()), "fast")
    t = run_node(node)
    try:
        wait_for(lambda: supervised.poll(time.monotonic()) is None
                 and supervised.watch.pings >= 2, 5, "pings")
        t0 = time.monotonic()
        node.hang()
        reason = wait_for(lambda: supervised.poll(time.monotonic()), 5, "hung")
        detect = time.monotonic() - t0
        print(f"hang hook detected after {detect:.2f} s: {reason}")
        # the loop's last tick came up to one period (0.01 s) before the hook
        assert "loop fast: no tick for" in reason and 1.5 - 0.02 <= detect < 2.0
        assert max(ticks) - t0 < 0.1  # the loop stopped at the hook
    finally:
        node.stop_event.set()
        t.join(10)
    assert not t.is_alive(), "a hung node must still shut down on stop"


def test_an_idle_node_is_caught_by_its_health_loop_after_three_periods(
        supervised: NotifyChannel) -> None:
    """No inputs and no loops of its own: only the 1 Hz health loop shows the hang, after
    3 × 1 s (the known slow case; in a running stack callbacks catch it after 1.5 s)."""
    node = Node("wdtest", ZenohSettings(connect=[], listen=["tcp/127.0.0.1:0"]))
    t = run_node(node)
    try:
        wait_for(lambda: supervised.poll(time.monotonic()) is None
                 and supervised.watch.pings >= 1, 5, "a ping")
        t0 = time.monotonic()
        node.hang()
        reason = wait_for(lambda: supervised.poll(time.monotonic()), 6, "hung")
        detect = time.monotonic() - t0
        print(f"idle node detected after {detect:.2f} s: {reason}")
        assert "loop health: no tick for" in reason and 2.0 <= detect < 3.3
    finally:
        node.stop_event.set()
        t.join(10)


# --- the wrapper around real child processes --------------------------------------------------
CHILD = """
import sys, time
from autochair.runtime.watchdog import notify
notify("READY=1")
for _ in range({pings}):
    notify("WATCHDOG=1")
    time.sleep(0.1)  # the child's ping rate
{then}
"""


def wrapped(tmp_path: Path, pings: int, then: str, *extra: str) -> subprocess.Popen[str]:
    script = tmp_path / "child.py"
    script.write_text(CHILD.format(pings=pings, then=then))
    return subprocess.Popen([sys.executable, "-m", "autochair.watchdog_wrapper", *extra,
                             "--", sys.executable, str(script)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_wrapper_kills_a_child_whose_pings_stop(tmp_path: Path) -> None:
    p = wrapped(tmp_path, 5, "time.sleep(60)", "--timeout", "0.5")
    try:
        t0 = time.monotonic()
        assert p.wait(timeout=20) == HUNG_EXIT
        took = time.monotonic() - t0
        err = p.stderr.read() if p.stderr else ""
        assert "hung: no watchdog ping for" in err and "SIGKILL" in err
        assert took < 10
    finally:
        stop_process(p)


def test_wrapper_leaves_a_child_that_never_pings_and_passes_its_status(tmp_path: Path) -> None:
    script = tmp_path / "quiet.py"
    script.write_text("import time, sys\ntime.sleep(1.5)\nsys.exit(3)\n")
    p = subprocess.Popen([sys.executable, "-m", "autochair.watchdog_wrapper", "--timeout", "0.3",
                          "--", sys.executable, str(script)])
    try:
        assert p.wait(timeout=20) == 3
    finally:
        stop_process(p)


SLOW_STOP = """
import pathlib, signal, sys, threading, time
from autochair.runtime.watchdog import notify
stopping = threading.Event()
signal.signal(signal.SIGTERM, lambda *a: stopping.set())
notify("WATCHDOG=1")
pathlib.Path({ready!r}).touch()
while not stopping.is_set():
    notify("WATCHDOG=1")
    time.sleep(0.1)  # the child's ping rate
time.sleep(1.0)  # a slow shutdown without pings, longer than --timeout
sys.exit(0)
"""


def test_wrapper_forwards_sigterm_and_a_stop_is_not_a_hang(tmp_path: Path) -> None:
    ready = tmp_path / "ready"
    script = tmp_path / "slow_stop.py"
    script.write_text(SLOW_STOP.format(ready=str(ready)))
    p = subprocess.Popen([sys.executable, "-m", "autochair.watchdog_wrapper", "--timeout", "0.5",
                          "--", sys.executable, str(script)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        wait_for(ready.exists, 10, "the child up")
        p.send_signal(signal.SIGTERM)
        code = p.wait(timeout=20)
        assert code == 0, p.stderr.read() if p.stderr else ""  # the child's own status
    finally:
        stop_process(p)


def test_sigkill_of_the_wrapper_kills_the_service_too(tmp_path: Path) -> None:
    """supervisorctl shows the wrapper's pid: `kill -9` of it must still kill the service."""
    pidfile = tmp_path / "child.pid"
    script = tmp_path / "forever.py"
    script.write_text(f"import os, pathlib, time\npathlib.Path({str(pidfile)!r}).write_text("
                      "str(os.getpid()))\nwhile True:\n    time.sleep(1)\n")
    p = subprocess.Popen([sys.executable, "-m", "autochair.watchdog_wrapper", "--",
                          sys.executable, str(script)])
    try:
        text: str = wait_for(lambda: pidfile.read_text() if pidfile.exists() else "", 10,
                             "child pid")
        child = int(text)
        p.kill()
        p.wait(timeout=10)

        def gone() -> bool:
            try:
                os.kill(child, 0)
            except ProcessLookupError:
                return True
            return False

        wait_for(gone, 5, "the service killed with its wrapper")
    finally:
        stop_process(p)


def test_a_worker_handles_in_order_and_drops_the_oldest_when_behind() -> None:
    node = Node("wdtest", ZenohSettings(connect=[], listen=["tcp/127.0.0.1:0"]))
    gate, busy, seen = threading.Event(), threading.Event(), []

    def handle(msg: LogEvent) -> None:
        busy.set()
        gate.wait(5)
        seen.append(msg.message)

    put = node.worker("work", handle, maxlen=3, dropped="dropped_busy")
    try:
        msgs = [LogEvent(stamp_ns=i, level="info", service="t", message=str(i))
                for i in range(6)]
        put(msgs[0])
        wait_for(busy.is_set, 5, "the first item taken")
        for m in msgs[1:]:  # the worker is busy with "0": 1..5 wait in a queue of 3
            put(m)
        assert node.health.counters["dropped_busy"] == 2  # "1" and "2", the oldest
        gate.set()
        wait_for(lambda: len(seen) == 4, 5, "the rest handled")
        assert seen == ["0", "3", "4", "5"]
    finally:
        node.stop_event.set()
        node.close()


def test_a_loop_tick_knows_when_it_was_due() -> None:
    """`Node.due[name]`: the running tick's schedule (drift-free, whole periods apart, never
    after it ran), not its wake-up time, which jitters (positive control)."""
    node = Node("duetest", ZenohSettings(connect=[], listen=["tcp/127.0.0.1:0"]))
    seen: list[tuple[float, float]] = []  # (woke, due)
    node.every(0.02, lambda: seen.append((time.monotonic(), node.due["plan"])), "plan")
    t = run_node(node)
    try:
        wait_for(lambda: len(seen) >= 15, 5, "15 ticks")
    finally:
        node.stop_event.set()
        t.join(10)
    assert not t.is_alive()
    due = [d for _, d in seen]
    periods = [(b - a) / 0.02 for a, b in itertools.pairwise(due)]
    assert all(p >= 1 - 1e-6 and abs(p - round(p)) < 1e-6 for p in periods)
    assert all(d <= w for w, d in seen)
    woke = [w for w, _ in seen]
    assert any(abs((b - a) / 0.02 - 1) > 1e-6 for a, b in itertools.pairwise(woke))
