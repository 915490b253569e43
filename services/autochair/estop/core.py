"""Pure e-stop latch: every decision of the e-stop service, no I/O.

- `latch` (keys.ESTOP_ASSERT, any identity, laptops included) only ever latches. `active=True`
  is a persistent cause held by its source until that source clears it; `active=False` is a
  momentary press (a button, `autochair estop`): latched, its cause recorded as already
  inactive. An assert never clears a cause: a laptop that may stop the chair must not be able
  to clear the safety monitor's "imminent collision" by sending `active=False` in its name.
- `clear` (keys.ESTOP_CLEAR, services only by the hub's ACL) clears one source's cause.
- `release` (keys.ESTOP_RELEASE) clears the latch, refused while any cause is active.
- `restore` reads the saved state; an unreadable one restores as latched.
- `snapshot`/`saved`: the state file's content, and what a save's outcome changes.
- `health` says what the node reports, including a latch that cannot be persisted.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import msgspec

from autochair_msgs import EStopCause, EStopState

# The source name of the e-stop's own causes (an unreadable state file).
SELF = "estop"


@dataclass
class EStopCore:
    latched: bool = False
    causes: dict[str, EStopCause] = field(default_factory=dict)
    # Why the last save of the state file failed ("" = saved, or nothing to save to).
    persist_error: str = ""

    def latch(self, source: str, reason: str, active: bool, now_ns: int) -> bool:
        """Latch. active=True: `source` holds a cause until it clears it (`clear`).
        active=False: a momentary press, recorded as an inactive cause; it never clears an
        active cause of the same source. Returns True when the state changed."""
        prev = self.causes.get(source)
        was_latched, self.latched = self.latched, True
        if prev is not None and prev.active:
            if not active or prev.reason == reason:
                return not was_latched  # still held: a press in its name changes nothing
            self.causes[source] = msgspec.structs.replace(prev, reason=reason)
            return True
        if prev is not None and was_latched and not active and prev.reason == reason:
            return False  # a repeated press (the CLI repeats until it sees the latch)
        self.causes[source] = EStopCause(source=source, reason=reason, since_ns=now_ns,
                                         active=active)
        return True

    def clear(self, source: str) -> bool:
        """`source`'s cause has cleared (the latch stays until a release). True if it was
        active."""
        prev = self.causes.get(source)
        if prev is None or not prev.active:
            return False
        self.causes[source] = msgspec.structs.replace(prev, active=False)
        return True

    def active(self) -> list[EStopCause]:
        return [c for c in self.causes.values() if c.active]

    def release(self) -> str:
        """Clear the latch; returns "" on success or why it was refused."""
        remaining = self.active()
        if remaining:
            return "refused: cause remains: " + "; ".join(
                f"{c.source}: {c.reason}" for c in remaining)
        self.latched = False
        self.causes.clear()
        return ""

    def state(self, now_ns: int) -> EStopState:
        return EStopState(stamp_ns=now_ns, latched=self.latched, causes=list(self.causes.values()))

    def restore(self, saved: bytes | None, read_error: str, now_ns: int) -> str:
        """Take the state saved in the state file (`saved`; None = no file). A file that
        cannot be read (`read_error`) or decoded restores as LATCHED, releasable by hand.
        Returns a warning for the event log, or ""."""
        if saved is None and not read_error:
            return ""
        if saved is not None:
            try:
                state = msgspec.json.decode(saved, type=EStopState)
            except (msgspec.DecodeError, msgspec.ValidationError) as e:
                read_error = str(e)
            else:
                self.latched = state.latched
                self.causes = {c.source: c for c in state.causes}
                return "e-stop restored LATCHED" if self.latched else ""
        why = f"state file unreadable ({read_error})"
        self.latch(SELF, why, False, now_ns)
        return f"e-stop LATCHED: {why}"

    def snapshot(self, now_ns: int) -> bytes:
        """The state file's content."""
        return msgspec.json.encode(self.state(now_ns))

    def saved(self, error: str) -> str:
        """The outcome of a save ("" = written): an event to report when that changed (a
        latch that cannot be persisted is an error, never silent), else ""."""
        before, self.persist_error = self.persist_error, error
        if error and error != before:
            return f"e-stop state cannot be saved ({error}): the latch would not survive a restart"
        if before and not error:
            return "e-stop state saved again"
        return ""

    def health(self) -> tuple[str, str]:
        """(health state, detail). A latch that cannot be persisted is a fault: it would be
        lost on a restart."""
        detail = "LATCHED" if self.latched else "released"
        if self.persist_error:
            return "fault", f"{detail}; state file not saved: {self.persist_error}"
        return "ok", detail
