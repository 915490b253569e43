"""Run analysis for `autochair report` (pure numpy): step responses (rise time, overshoot) and
smoothed acceleration, jerk and turn rate from odometry."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Step:
    t_s: float  # time of the step in the desired value
    before: float
    after: float
    rise_s: float | None  # 10 % → 90 % of the step; None if 90 % is never reached
    overshoot_pct: float  # peak beyond `after`, in % of the step size (0 if none)


def steps(t: Array, desired: Array, measured: Array, min_step: float = 0.05) -> list[Step]:
    """Steps in `desired` (jumps ≥ min_step between samples) and how `measured` followed each
    until the next step (or the end)."""
    jumps = np.flatnonzero(np.abs(np.diff(desired)) >= min_step) + 1
    out: list[Step] = []
    for n, i in enumerate(jumps):
        end = jumps[n + 1] if n + 1 < len(jumps) else len(t)
        before, after = float(desired[i - 1]), float(desired[i])
        size = after - before
        # Progress toward the new value, in units of the step (0 = old value, 1 = new).
        progress = (measured[i:end] - before) / size
        tt = t[i:end]
        r10 = np.flatnonzero(progress >= 0.1)
        r90 = np.flatnonzero(progress >= 0.9)
        rise = float(tt[r90[0]] - tt[r10[0]]) if len(r90) and len(r10) else None
        peak = float(np.max(progress)) if len(progress) else 0.0
        out.append(Step(float(t[i]), before, after, rise, max(0.0, (peak - 1.0) * 100.0)))
    return out


def resample(t: Array, x: Array, period_s: float) -> tuple[Array, Array]:
    """Bin means (of time and value) on a regular grid: smooths 200 Hz odometry before
    differentiating."""
    if len(t) == 0:
        return t, x
    idx = np.floor((t - t[0]) / period_s + 1e-6).astype(np.int64)  # 1e-6: float edges
    counts = np.bincount(idx)
    ok = counts > 0
    tm = np.bincount(idx, weights=t)[ok] / counts[ok]
    return tm, np.bincount(idx, weights=x)[ok] / counts[ok]


def motion(t: Array, v: Array, period_s: float = 0.05) -> tuple[Array, Array, Array, Array]:
    """(t, v, a, jerk) on a regular grid: a = dv/dt, jerk = da/dt."""
    tr, vr = resample(t, v, period_s)
    if len(tr) < 3:
        z = np.zeros_like(tr)
        return tr, vr, z, z
    a = np.gradient(vr, tr)
    return tr, vr, a, np.gradient(a, tr)
