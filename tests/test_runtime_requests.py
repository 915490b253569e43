"""One typed request/reply API: `Node.serve` answers a query row of the key table, and
`runtime.client.request` asks it; both take the table's request and reply types."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from autochair.runtime import Node
from autochair.runtime.client import RequestError, request
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
