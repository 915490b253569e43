"""Pure timing helpers (stamps passed in)."""

from __future__ import annotations


class Decimator:
    """Lets one sample per `period_ns` through, drift-free by sample stamp: due times advance
    by whole periods; a late sample or a clock step re-bases them. period 0: every sample."""

    def __init__(self, period_ns: int) -> None:
        self.period_ns = period_ns
        self.due_ns = 0

    @classmethod
    def at(cls, rate_hz: float) -> Decimator:
        """At most `rate_hz` (0 = every sample)."""
        return cls(int(1e9 / rate_hz) if rate_hz > 0 else 0)

    def __call__(self, stamp_ns: int) -> bool:
        due, period = self.due_ns, self.period_ns
        if due - period <= stamp_ns < due:
            return False
        late = stamp_ns - due >= period or stamp_ns < due - period
        self.due_ns = (stamp_ns if late else due) + period
        return True
