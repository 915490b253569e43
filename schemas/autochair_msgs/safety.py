"""E-stop and the safety monitor's speed limit."""

from __future__ import annotations

import msgspec


class EStopAssert(msgspec.Struct, kw_only=True, frozen=True):
    """On keys.ESTOP_ASSERT: latch the e-stop. `active` says the cause persists (a service's
    condition, held until that service clears it on keys.ESTOP_CLEAR); active=False is a
    momentary press (a button, the CLI): latched, with nothing left to clear. On keys.ESTOP_CLEAR
    (services only): `source`'s cause has cleared; the latch stays until an explicit release."""

    stamp_ns: int
    source: str  # who asserts: a service name, "cli", a laptop's name
    reason: str
    active: bool = True


class EStopCause(msgspec.Struct, kw_only=True, frozen=True):
    source: str
    reason: str
    since_ns: int
    active: bool


class EStopState(msgspec.Struct, kw_only=True, frozen=True):
    """The latch, repeated at 10 Hz: the gateway holds neutral while latched or when silent."""

    stamp_ns: int
    latched: bool
    causes: list[EStopCause] = []


class EStopRelease(msgspec.Struct, kw_only=True, frozen=True):
    by: str


class EStopReply(msgspec.Struct, kw_only=True, frozen=True):
    ok: bool
    latched: bool
    error: str = ""


def says_stop(v_max_fwd_mps: float, omega_max_radps: float) -> bool:
    """A SafetyLimit's bounds that allow neither forward motion nor turning: the monitor's
    stop (the velocity PID and the control service's goal gate judge it alike)."""
    return v_max_fwd_mps == 0.0 and omega_max_radps == 0.0


class SafetyLimit(msgspec.Struct, kw_only=True, frozen=True):
    """Speed bounds from the safety monitor; the velocity PID clamps any desired velocity."""

    stamp_ns: int
    v_max_fwd_mps: float
    v_max_rev_mps: float  # a positive number: the bound on backward speed (attended: teleop)
    omega_max_radps: float
    reason: str = ""
    # Bound on backward speed for autonomy: 0 while nothing senses behind the chair, unless
    # [safety] allows blind reversing.
    v_max_rev_autonomy_mps: float = 0.0
