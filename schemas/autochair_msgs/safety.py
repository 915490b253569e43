"""E-stop and the safety monitor's speed limit."""

from __future__ import annotations

import msgspec


class EStopAssert(msgspec.Struct, kw_only=True, frozen=True):
    """Latch the e-stop. `active` says the cause persists; the source sends active=False when
    it has cleared (the latch stays until an explicit release)."""

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


class SafetyLimit(msgspec.Struct, kw_only=True, frozen=True):
    """Speed bounds from the safety monitor; the velocity PID clamps any desired velocity."""

    stamp_ns: int
    v_max_fwd_mps: float
    v_max_rev_mps: float  # a positive number: the bound on backward speed
    omega_max_radps: float
    reason: str = ""
