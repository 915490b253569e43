"""Pure differential-drive odometry (after diff_drive_controller's `Odometry`).

Exact arc integration in the ISO/REP-103 frame (x forward, y left, yaw counter-clockwise), yaw
kept in (−π, π], wrap-safe N-bit counters, time from the MCU clock (wrap-safe µs counter).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from autochair.geometry import wrap_angle
from autochair.protocol.arduino import ST_BOOT, wrap_delta


@dataclass(frozen=True)
class OdomState:
    x: float
    y: float
    yaw: float
    v: float
    omega: float
    distance: float
    dt: float  # seconds since the previous sample (0 on the first)


@dataclass
class OdometryCore:
    wheel_radius_m: float = 0.049
    base_m: float = 0.367
    counts_per_rev: int = 10000
    # D_right / D_left of the encoder wheels (their mean is 2·wheel_radius_m): from
    # `python -m bench loc_eval` calibration, 1.0 = equal
    wheel_diameter_ratio: float = 1.0
    counter_bits: int = 32
    clock_bits: int = 32
    velocity_window_s: float = 0.02  # velocities averaged over this window (quantisation noise)
    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0
    distance: float = 0.0
    restarts: int = 0  # MCU restarts seen (counters re-based)
    # No wheel of a chair moves faster: a sample implying it (a corrupt frame that passed the
    # CRC, a counter glitch) is dropped and the counters re-based, so the pose is not poisoned.
    max_wheel_mps: float = 5.0
    implausible: int = 0  # samples dropped for that
    _booting: bool = True  # as if booting: the first frames after our own start are no news
    _prev: tuple[int, int, int] | None = None
    _window: deque[tuple[float, float, float]] = field(default_factory=deque)  # (dt, d, dψ)

    def reset(self, x: float = 0.0, y: float = 0.0, yaw: float = 0.0) -> None:
        self.x, self.y, self.yaw, self.distance = x, y, wrap_angle(yaw), 0.0
        self._prev = None
        self._window.clear()

    def rebase(self) -> None:
        """Forget the previous counters (the MCU restarted) but keep the pose."""
        self._prev = None
        self._window.clear()

    def update(self, left: int, right: int, t_us: int, status: int = 0) -> OdomState:
        """Integrate one encoder sample (raw wrapping counters, raw wrapping µs clock).

        A restarted MCU (its clock went backwards, or its boot flag rose) has reset counters:
        the sample re-bases them instead of being integrated as a huge jump. A forward gap (a
        reconnect without reset) is integrated: absolute counters lose no distance.
        """
        booting = bool(status & ST_BOOT)
        if self._prev is not None and (
                wrap_delta(self._prev[2], t_us, self.clock_bits) <= 0
                or (booting and not self._booting)):
            self.restarts += 1
            self.rebase()
        self._booting = booting
        if self._prev is None:
            self._prev = (left, right, t_us)
            return OdomState(self.x, self.y, self.yaw, 0.0, 0.0, self.distance, 0.0)
        pl, pr, pt = self._prev
        self._prev = (left, right, t_us)
        metres_per_count = 2 * math.pi * self.wheel_radius_m / self.counts_per_rev
        e_d = self.wheel_diameter_ratio
        d_l = wrap_delta(pl, left, self.counter_bits) * metres_per_count * 2 / (1 + e_d)
        d_r = wrap_delta(pr, right, self.counter_bits) * metres_per_count * 2 * e_d / (1 + e_d)
        dt = ((t_us - pt) % (1 << self.clock_bits)) * 1e-6
        if max(abs(d_l), abs(d_r)) > self.max_wheel_mps * dt + 0.01:
            self.implausible += 1  # not integrated; the velocities stay the window's
        else:
            self.integrate(d_l, d_r)
            self._window.append((dt, (d_l + d_r) / 2, (d_r - d_l) / self.base_m))
        span = sum(w[0] for w in self._window)
        while len(self._window) > 1 and span - self._window[0][0] >= self.velocity_window_s:
            span -= self._window.popleft()[0]
        if span > 0:
            v = sum(w[1] for w in self._window) / span
            omega = sum(w[2] for w in self._window) / span
        else:
            v = omega = 0.0
        return OdomState(self.x, self.y, self.yaw, v, omega, self.distance, dt)

    def integrate(self, d_l: float, d_r: float) -> None:
        """Advance the pose by left/right wheel travel along an exact arc."""
        d = (d_l + d_r) / 2
        dpsi = (d_r - d_l) / self.base_m
        yaw0 = self.yaw
        if abs(dpsi) < 1e-6:
            # second-order midpoint: exact for straight lines, error O(dψ²) below the threshold
            self.x += d * math.cos(yaw0 + dpsi / 2)
            self.y += d * math.sin(yaw0 + dpsi / 2)
        else:
            yaw1 = yaw0 + dpsi
            r = d / dpsi
            self.x += r * (math.sin(yaw1) - math.sin(yaw0))
            self.y -= r * (math.cos(yaw1) - math.cos(yaw0))
        self.yaw = wrap_angle(yaw0 + dpsi)
        self.distance += abs(d)
