"""Messages of the simulator only (never used on a real chair)."""

from __future__ import annotations

import msgspec


class SimFault(msgspec.Struct, kw_only=True, frozen=True):
    """Fault injected into the simulated Arduino link (query request on keys.SIM_FAULT).

    kind: "unplug" (close the pty and remove its link for `duration_s`, then recreate both,
    like a USB cable pulled and plugged back), "replug" (end an unplug now), "garbage" (write
    `count` random bytes into the telemetry stream).
    """

    kind: str
    duration_s: float = 1.0
    count: int = 16


class SimFaultReply(msgspec.Struct, kw_only=True, frozen=True):
    ok: bool
    detail: str = ""
