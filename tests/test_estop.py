"""E-stop latch: assert from anywhere, explicit release only, refused while a cause remains."""

from __future__ import annotations

from autochair.estop.core import EStopCore


def test_latch_and_release() -> None:
    core = EStopCore()
    assert not core.latched
    assert core.assert_("cli", "operator", active=False, now_ns=1) is False  # nothing to clear
    assert core.assert_("cli", "operator", active=True, now_ns=1)
    assert core.latched
    assert core.release().startswith("refused: cause remains: cli: operator")
    assert core.latched
    assert core.assert_("cli", "operator", active=False, now_ns=2)
    assert core.latched  # a cleared cause does not release
    assert core.release() == ""
    assert not core.latched and not core.causes


def test_several_causes_all_must_clear() -> None:
    core = EStopCore()
    core.assert_("safety", "obstacle 0.3 m", True, 1)
    core.assert_("laptop-1", "button", True, 2)
    core.assert_("laptop-1", "button", False, 3)
    error = core.release()
    assert "safety: obstacle" in error and "laptop-1" not in error
    core.assert_("safety", "obstacle 0.3 m", False, 4)
    assert core.release() == ""


def test_state_keeps_first_assert_time() -> None:
    core = EStopCore()
    core.assert_("safety", "a", True, 10)
    core.assert_("safety", "a", True, 20)
    (cause,) = core.state(30).causes
    assert cause.since_ns == 10 and cause.active
