"""Small planar geometry shared by the cores (pure)."""

from __future__ import annotations

import math


def wrap_angle(a: float) -> float:
    """Wrap an angle to (−π, π] (REP-103 heading range)."""
    r = math.remainder(a, math.tau)
    return r + math.tau if r <= -math.pi else r
