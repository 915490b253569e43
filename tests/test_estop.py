"""E-stop latch: an assert only latches (never clears a cause), a clear clears one source's
cause, a release is explicit and refused while a cause remains; the state file survives
restarts and a latch that cannot be saved is a fault.

The core tests are pure; the node tests run the real node in-process on an isolated Zenoh peer
(loopback, no hub): a session delivers its own puts to its own subscribers.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from pathlib import Path

import msgspec
import pytest

from autochair.estop.core import EStopCore
from autochair.estop.node import EStopConfig, start
from autochair.runtime import Node
from autochair.runtime.client import request, subscribe
from autochair.runtime.config import ZenohSettings
from autochair_msgs import EStopAssert, EStopRelease, EStopReply, EStopState, LogEvent, keys
from tests.helpers import wait_for

ENC = msgspec.msgpack.Encoder()


# --- core --------------------------------------------------------------------------------------
def test_press_latches_and_release_clears() -> None:
    core = EStopCore()
    assert not core.latched
    assert core.latch("cli", "operator", active=False, now_ns=1)  # a press latches
    assert core.latched
    (cause,) = core.state(2).causes
    assert cause.source == "cli" and not cause.active  # nothing left to clear
    assert core.latch("cli", "operator", active=False, now_ns=2) is False  # repeated press
    assert core.release() == ""
    assert not core.latched and not core.causes


def test_active_cause_refuses_release_until_its_source_clears_it() -> None:
    core = EStopCore()
    assert core.latch("safety", "imminent collision", active=True, now_ns=1)
    assert core.release().startswith("refused: cause remains: safety: imminent collision")
    assert core.latched
    assert core.clear("safety")
    assert core.latched  # a cleared cause does not release
    assert core.release() == ""
    assert not core.latched


def test_an_assert_never_clears_a_cause() -> None:
    """The hazard: `active=False` on ESTOP_ASSERT (allowed to every laptop) used to clear the
    named source's cause. It is now a press: the safety monitor's cause stays active."""
    core = EStopCore()
    core.latch("safety", "imminent collision", True, 1)
    assert core.latch("safety", "spoofed clear", active=False, now_ns=2) is False
    (cause,) = core.state(3).causes
    assert cause.active and cause.reason == "imminent collision" and cause.since_ns == 1
    assert "safety" in core.release()
    assert core.latched
    # Positive control: the source's clear (ESTOP_CLEAR) does clear it.
    assert core.clear("safety") and core.release() == ""


def test_clear_is_per_source_and_only_of_active_causes() -> None:
    core = EStopCore()
    assert not core.clear("safety")  # nothing to clear: no change, no latch
    assert not core.latched
    core.latch("safety", "obstacle 0.3 m", True, 1)
    core.latch("laptop-1", "button", False, 2)
    core.latch("other", "held", True, 3)
    assert core.clear("safety")
    assert not core.clear("safety")  # already cleared
    error = core.release()
    assert "other: held" in error and "safety" not in error and "laptop-1" not in error
    assert core.clear("other") and core.release() == ""


def test_press_then_persistent_cause_of_the_same_source() -> None:
    core = EStopCore()
    core.latch("safety", "press", False, 1)
    assert core.latch("safety", "imminent collision", True, 2)  # now held
    (cause,) = core.state(3).causes
    assert cause.active and cause.since_ns == 2
    assert core.latch("safety", "closer", True, 4)  # a new reason, same since
    (cause,) = core.state(5).causes
    assert cause.reason == "closer" and cause.since_ns == 2


def test_state_keeps_first_assert_time() -> None:
    core = EStopCore()
    core.latch("safety", "a", True, 10)
    assert core.latch("safety", "a", True, 20) is False
    (cause,) = core.state(30).causes
    assert cause.since_ns == 10 and cause.active


def test_restore_saved_state_and_unreadable_reads_as_latched() -> None:
    saved = EStopCore()
    saved.latch("safety", "imminent collision", True, 1)
    raw = msgspec.json.encode(saved.state(2))
    core = EStopCore()
    assert core.restore(raw, "", 3) == "e-stop restored LATCHED"
    assert core.latched and core.active()[0].source == "safety"
    for data, err in ((b"{not json", ""), (None, "PermissionError: denied")):
        core = EStopCore()
        assert core.restore(data, err, 3).startswith("e-stop LATCHED: state file unreadable")
        assert core.latched and not core.active()  # releasable by hand
        assert core.release() == ""
    core = EStopCore()
    assert core.restore(None, "", 3) == "" and not core.latched  # no file: a fresh start


def test_health_reports_a_latch_that_cannot_be_saved() -> None:
    core = EStopCore()
    assert core.health() == ("ok", "released")
    core.latch("cli", "x", False, 1)
    core.persist_error = "/nope/estop.json: NotADirectoryError"
    state, detail = core.health()
    assert state == "fault" and detail.startswith("LATCHED; state file not saved: /nope")


# --- node, in-process -----------------------------------------------------------------------------
class EStopNode:
    """The real e-stop node on an isolated peer; `put` and `release` as another service."""

    def __init__(self, state_file: Path | str) -> None:
        self.node = Node("estop", ZenohSettings(connect=[], listen=["tcp/127.0.0.1:0"]))
        self.states: list[EStopState] = []
        self.events: list[LogEvent] = []
        self._lock = threading.Lock()
        s = self.node.session

        def on_state(m: EStopState) -> None:
            with self._lock:
                self.states.append(m)

        def on_log(m: LogEvent) -> None:
            with self._lock:
                self.events.append(m)

        subscribe(s, keys.ESTOP_STATE, on_state)
        subscribe(s, keys.LOG, on_log)
        start(self.node, EStopConfig(state_file=str(state_file), rate_hz=50.0))

    def put(self, topic: keys.Topic[EStopAssert], source: str, active: bool) -> None:
        self.node.session.put(topic.key, ENC.encode(EStopAssert(
            stamp_ns=1, source=source, reason="test", active=active)))

    def latest(self) -> EStopState | None:
        with self._lock:
            return self.states[-1] if self.states else None

    def cause(self, source: str) -> bool | None:
        """Whether `source`'s cause is active in the latest state (None: no such cause)."""
        st = self.latest()
        return next((c.active for c in st.causes if c.source == source), None) if st else None

    def release(self) -> EStopReply:
        return request(self.node.session, keys.ESTOP_RELEASE, EStopRelease(by="test"),
                       EStopReply)

    def close(self) -> None:
        self.node.close()


@pytest.fixture
def opened() -> Iterator[list[EStopNode]]:
    nodes: list[EStopNode] = []
    try:
        yield nodes
    finally:
        for n in nodes:
            n.close()


def test_node_assert_never_clears_and_clear_key_does(tmp_path: Path,
                                                     opened: list[EStopNode]) -> None:
    n = EStopNode(tmp_path / "estop.json")
    opened.append(n)
    n.put(keys.ESTOP_ASSERT, "safety", True)
    wait_for(lambda: n.cause("safety") is True, 5, "safety cause active")
    n.put(keys.ESTOP_ASSERT, "safety", False)  # the spoof: a "clear" on the assert key
    n.put(keys.ESTOP_ASSERT, "marker", False)  # same session, after it: when this is seen,
    wait_for(lambda: n.cause("marker") is False, 5, "marker press")  # the spoof was handled
    assert n.cause("safety") is True
    reply = n.release()
    assert not reply.ok and reply.latched and "safety" in reply.error
    n.put(keys.ESTOP_CLEAR, "safety", False)  # positive control: the clear key clears it
    wait_for(lambda: n.cause("safety") is False, 5, "safety cause cleared")
    reply = n.release()
    assert reply.ok and not reply.latched
    wait_for(lambda: (st := n.latest()) is not None and not st.latched, 5, "released state")


def test_node_creates_state_dir_and_latch_survives_restart(tmp_path: Path,
                                                           opened: list[EStopNode]) -> None:
    path = tmp_path / "state" / "deeper" / "estop.json"  # the directory does not exist yet
    n = EStopNode(path)
    opened.append(n)
    assert path.exists()  # saved at start: an unwritable directory is found before a latch
    n.put(keys.ESTOP_ASSERT, "safety", True)
    wait_for(lambda: n.cause("safety") is True, 5, "safety cause")
    saved = msgspec.json.decode(path.read_bytes(), type=EStopState)
    assert saved.latched and saved.causes[0].active
    assert n.node.health.state == "ok"
    n.close()
    opened.remove(n)
    again = EStopNode(path)
    opened.append(again)
    wait_for(lambda: again.cause("safety") is True, 5, "restored cause")
    st = again.latest()
    assert st is not None and st.latched
    assert not again.release().ok  # the restored cause still holds the latch


def test_node_unreadable_state_file_restores_latched(tmp_path: Path,
                                                     opened: list[EStopNode]) -> None:
    path = tmp_path / "estop.json"
    path.write_bytes(b"\x00 torn")
    n = EStopNode(path)
    opened.append(n)
    wait_for(lambda: n.cause("estop") is False, 5, "latched by the unreadable file")
    st = n.latest()
    assert st is not None and st.latched
    assert n.release().ok  # releasable by hand, and the file is sound again
    assert not msgspec.json.decode(path.read_bytes(), type=EStopState).latched


def test_node_state_file_that_cannot_be_written_is_a_fault(tmp_path: Path,
                                                          opened: list[EStopNode]) -> None:
    blocker = tmp_path / "not-a-dir"
    blocker.write_text("a file where the state directory should be")  # root cannot write either
    n = EStopNode(blocker / "estop.json")
    opened.append(n)
    assert n.node.health.state == "fault"
    assert "state file not saved" in n.node.health.detail
    assert "cannot be saved" in n.node.health.last_fault
    n.put(keys.ESTOP_ASSERT, "cli", False)
    wait_for(lambda: n.cause("cli") is False, 5, "latched in memory all the same")
    latest = n.latest()
    assert latest is not None and latest.latched
    assert n.node.health.state == "fault" and n.node.health.detail.startswith("LATCHED")
    # Positive control: the same node setup with a writable directory is healthy.
    ok = EStopNode(tmp_path / "fine" / "estop.json")
    opened.append(ok)
    assert ok.node.health.state == "ok" and ok.node.health.detail == "released"
