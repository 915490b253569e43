"""The simulated chair's clock against the wall clock (pure: the due time is passed in)."""

from __future__ import annotations

import math
from dataclasses import dataclass

# Of a longer stall only this much is caught up, the rest is lost (and counted): the host could
# not feed the firmware's 200 ms watchdog while the sim stood still, and a catch-up past it
# would trip the watchdog, which a real MCU (whose time never stops) would not have.
MAX_CATCH_UP_S = 0.1


@dataclass
class Pacer:
    """How many model steps a loop tick runs so that the simulated clock keeps up with the wall
    clock (× time_scale), as a real chair's does. The node's timer skips the ticks it missed
    under load (Node.every); a simulator that lost them let its chair run slower than the
    processes driving it, so a plan's ramp, stepped by the wall clock, reached the chair
    squeezed into less simulated time (peak |a| up to 1.09 m/s² against the plan's 0.97 in the
    e-stop release test under load). Missed steps run at the next tick, the firmware holding the
    volts it had, as a real MCU holds the host's last command while the host is late."""

    period_s: float  # wall seconds per step
    max_steps: int  # per tick; steps due beyond it are given up
    epoch_s: float | None = None  # when the first step was due
    scheduled: int = 0  # steps scheduled so far (run or given up)

    def steps(self, due_s: float) -> tuple[int, int]:
        """(steps to run, steps given up) at a tick due at `due_s` (monotonic)."""
        if self.epoch_s is None:
            self.epoch_s = due_s
        target = math.floor((due_s - self.epoch_s) / self.period_s + 1e-6) + 1
        n, self.scheduled = max(target - self.scheduled, 0), max(target, self.scheduled)
        return min(n, self.max_steps), max(n - self.max_steps, 0)
