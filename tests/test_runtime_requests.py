"""One typed request/reply API: `Node.serve` answers a query row of the key table, and
`runtime.client.request` asks it; both take the table's request and reply types."""

from __future__ import annotations

import re
import time
from collections.abc import Iterator

import pytest

from autochair.runtime import Node
from autochair.runtime.client import ENCODER, RequestError, deadline, request, too_late
from autochair.runtime.config import ZenohSettings
from autochair_msgs import EStopRelease, EStopReply, GoalReply, GoalRequest, keys
from tests.helpers import wait_for


@pytest.fixture
def node() -> Iterator[Node]:
    n = Node("test", ZenohSettings(connect=[], listen=["tcp/127.0.0.1:0"]))
    try:
        yield n
    finally:
        n.close()


def test_a_served_row_answers_typed_requests_and_malformed_ones_with_an_error(
        node: Node) -> None:
    asked: list[str] = []

    def on_release(req: EStopRelease) -> EStopReply:
        asked.append(req.by)
        return EStopReply(ok=req.by == "alice", latched=False, error="" if req.by == "alice"
                          else "refused")

    node.serve(keys.ESTOP_RELEASE, on_release)
    s = node.session
    assert request(s, keys.ESTOP_RELEASE, EStopRelease(by="alice"), EStopReply).ok
    assert request(s, keys.ESTOP_RELEASE, EStopRelease(by="bob"), EStopReply).error == "refused"
    assert asked == ["alice", "bob"]
    # A malformed request: an error reply naming it, counted, the handler not called.
    replies = list(s.get(keys.ESTOP_RELEASE.key, payload=b"\xc1", timeout=3.0))
    assert len(replies) == 1 and replies[0].err is not None
    assert "bad request on autochair/estop/release" in replies[0].err.payload.to_string()
    assert node.health.counters[f"bad_requests:{keys.ESTOP_RELEASE.key}"] == 1
    assert asked == ["alice", "bob"]


def test_a_failing_handler_is_an_error_reply_not_a_silence(node: Node) -> None:
    def broken(req: GoalRequest) -> GoalReply:
        raise ValueError("no map")

    node.serve(keys.GOAL_SET, broken)
    with pytest.raises(RequestError, match="ValueError: no map"):
        request(node.session, keys.GOAL_SET, GoalRequest(waypoints=[]), GoalReply)
    wait_for(lambda: node.health.counters.get("query_errors") == 1, 5, "the error counted")


def test_no_service_is_a_one_line_error_and_types_are_checked(node: Node) -> None:
    with pytest.raises(RequestError, match=r"no reply on autochair/goal/cancel within 0\.2 s"):
        request(node.session, keys.GOAL_CANCEL, GoalRequest(waypoints=[]), GoalReply,
                timeout_s=0.2)
    with pytest.raises(TypeError):
        request(node.session, keys.GOAL_CANCEL, GoalRequest(waypoints=[]), EStopReply)
    with pytest.raises(TypeError):
        request(node.session, keys.GOAL_CANCEL, EStopRelease(by="x"), GoalReply)


def test_a_request_delivered_after_its_asker_gave_up_is_not_acted_on(node: Node) -> None:
    """A goal or a release held up on the way (a stalled link, a busy service) and delivered
    after the CLI said "no reply" must not start motion the person was told had failed."""
    asked: list[str] = []

    def on_release(req: EStopRelease) -> EStopReply:
        asked.append(req.by)
        return EStopReply(ok=True, latched=False)

    node.serve(keys.ESTOP_RELEASE, on_release)
    s, now = node.session, time.time_ns()

    def send(attachment: bytes | None) -> str:
        replies = list(s.get(keys.ESTOP_RELEASE.key, timeout=3.0, attachment=attachment,
                             payload=ENCODER.encode(EStopRelease(by="alice"))))
        assert len(replies) == 1
        err = replies[0].err
        return "" if err is None else err.payload.to_string()

    def seconds(pattern: str, text: str) -> float:  # (the reply's figure: its own clock's)
        m = re.search(pattern, text)
        assert m, text
        return float(m.group(1))

    assert send(deadline(now, 3.0)) == "" and asked == ["alice"]  # positive control: in time
    late = send(deadline(time.time_ns() - 5 * 10**9, 3.0))
    assert abs(seconds(r"arrived ([\d.]+) s after its asker stopped waiting", late) - 2.0) < 0.1
    ahead = send(deadline(time.time_ns() + 10**9, 3.0))
    assert abs(seconds(r"stamped ([\d.]+) s ahead", ahead) - 1.0) < 0.1
    assert "carries no deadline" in send(None)
    assert asked == ["alice"]  # none of the three reached the handler
    assert node.health.counters[f"late_requests:{keys.ESTOP_RELEASE.key}"] == 3


def test_too_late_bounds() -> None:
    sent = 10**18
    assert too_late(deadline(sent, 3.0), sent + 2_999_000_000, 0.1) == ""
    assert too_late(deadline(sent, 3.0), sent + 3_001_000_000, 0.1).startswith("it arrived")
    assert too_late(deadline(sent, 3.0), sent - 90_000_000, 0.1) == ""  # within the skew
    assert "ahead of this clock" in too_late(deadline(sent, 3.0), sent - 110_000_000, 0.1)
    assert "no deadline" in too_late(b"short", sent, 0.1)
