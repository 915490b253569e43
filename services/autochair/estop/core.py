"""Pure e-stop latch: assert from anywhere, release only explicitly and only without causes."""

from __future__ import annotations

from dataclasses import dataclass, field

from autochair_msgs import EStopCause, EStopState


@dataclass
class EStopCore:
    latched: bool = False
    causes: dict[str, EStopCause] = field(default_factory=dict)

    def assert_(self, source: str, reason: str, active: bool, now_ns: int) -> bool:
        """Latch (active=True) or report that a source's cause has cleared (active=False).

        Returns True when the state changed.
        """
        prev = self.causes.get(source)
        if not active:
            if prev is None or not prev.active:
                return False
            self.causes[source] = EStopCause(source=source, reason=prev.reason,
                                             since_ns=prev.since_ns, active=False)
            return True
        changed = not self.latched or prev is None or not prev.active or prev.reason != reason
        self.latched = True
        since = prev.since_ns if prev is not None and prev.active else now_ns
        self.causes[source] = EStopCause(source=source, reason=reason, since_ns=since,
                                         active=True)
        return changed

    def release(self) -> str:
        """Clear the latch; returns "" on success or why it was refused."""
        remaining = [c for c in self.causes.values() if c.active]
        if remaining:
            return "refused: cause remains: " + "; ".join(
                f"{c.source}: {c.reason}" for c in remaining)
        self.latched = False
        self.causes.clear()
        return ""

    def state(self, now_ns: int) -> EStopState:
        return EStopState(stamp_ns=now_ns, latched=self.latched, causes=list(self.causes.values()))
