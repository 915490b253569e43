"""Odometry calibration from a mapped run, pure: the systematic errors (UMBmark's E_d, E_b)
estimated by comparing encoder counts with the localized (map-corrected) poses.

Over windows of about `window_s`, with nominal travel dl, dr of the wheels (nominal radius),
d = (dl + dr)/2, u = (dr - dl)/b (nominal base), and the localized motion Δψ, d_true:

    Δψ     = α·u + β·(2d/b) − γ·|ω|·u       α = s/E_b, β = s·δ/E_b, γ = k_turn·s/E_b
    d_true = s·d + s·δ·(dr − dl)/2 − s·k_acc·|a|·d

where s is the mean wheel scale, δ the half difference (E_d = (1 + δ)/(1 − δ)), and k_turn,
k_acc the skid in turns and the spin when accelerating (so they do not bias E_b and s). Both
are linear least squares.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from .matching import F64


@dataclass(frozen=True)
class Calibration:
    diameter_ratio: float  # E_d = D_right / D_left
    base_ratio: float  # E_b = effective base / configured base
    scale: float  # mean wheel diameter / configured
    slip_turn_per_radps: float
    slip_accel_per_mps2: float
    windows: int
    wheel_radius_m: float  # corrected values for [odometry]
    base_m: float

    def config_text(self) -> str:
        return ("[odometry]\n"
                f"wheel_radius_m = {self.wheel_radius_m:.6f}\n"
                f"wheel_diameter_ratio = {self.diameter_ratio:.6f}\n"
                f"base_m = {self.base_m:.6f}\n")


def _wrap(a: F64) -> F64:
    return np.arctan2(np.sin(a), np.cos(a))


def calibrate(t_s: F64, left_counts: F64, right_counts: F64, poses: F64, *,
              wheel_radius_m: float, base_m: float, counts_per_rev: int,
              window: int = 10) -> Calibration:
    """`poses` (N, 3) localized at times `t_s` (N,), with the encoder counts there (N,)."""
    mpc = 2 * math.pi * wheel_radius_m / counts_per_rev
    idx = np.arange(0, len(t_s), window)
    wl = np.diff(left_counts[idx]) * mpc
    wr = np.diff(right_counts[idx]) * mpc
    p = poses[idx]
    dt = np.diff(t_s[idx])
    dpsi = _wrap(np.diff(p[:, 2]))
    heading = p[:-1, 2] + dpsi / 2
    # The chord along the mid heading (an arc's chord points that way), signed: its length
    # |Δp| would read pose noise as travel while turning in place and bias the scale, and
    # E_b = s/α with it (1 cm of noise: E_b 11 % of its error off).
    chord = np.cos(heading) * np.diff(p[:, 0]) + np.sin(heading) * np.diff(p[:, 1])
    half = np.where(np.abs(dpsi) > 1e-9, dpsi / 2, 1.0)
    d_true = chord * np.where(np.abs(dpsi) > 1e-9, half / np.sin(half), 1.0)
    # |a| from the nominal speed at each scan (encoder counts between neighbouring scans)
    v = np.diff((left_counts + right_counts) / 2 * mpc) / np.diff(t_s)
    acc = np.abs(np.gradient(v, t_s[1:]))
    acc_w = np.array([acc[a:b].mean() if b > a else 0.0 for a, b in itertools.pairwise(idx)])
    d = (wl + wr) / 2
    u = (wr - wl) / base_m
    # The turn rate from the encoders, not the localized heading: its noise in a regressor
    # biased the skid and through it E_b (hallway: 64 % of the error off).
    omega = np.abs(u / dt)
    rot = np.column_stack((u, 2 * d / base_m, -omega * u))
    alpha, beta, gamma = np.linalg.lstsq(rot, dpsi, rcond=None)[0]
    delta = beta / alpha
    tra = np.column_stack((d + delta * (wr - wl) / 2, -acc_w * d))
    s, s_ka = np.linalg.lstsq(tra, d_true, rcond=None)[0]
    e_b = s / alpha
    return Calibration(
        diameter_ratio=float((1 + delta) / (1 - delta)), base_ratio=float(e_b),
        scale=float(s), slip_turn_per_radps=float(gamma / alpha),
        slip_accel_per_mps2=float(s_ka / s), windows=len(d),
        wheel_radius_m=float(wheel_radius_m * s), base_m=float(base_m * e_b))
