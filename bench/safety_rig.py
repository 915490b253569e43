"""The safety monitor in a lockstep loop (nav_eval `--monitor`): what the live stack runs beside
navigation. Every scan period the simulated laser sweeps the world from the chair's true pose
and motion (the lidar simulator's `ray_scan`, its noise), the monitor's pure core judges the
scan with the odometry's motion as the safety service does, and its limit goes to the velocity
PID, which requires it, and to the control core, as the control node passes it on (and the
scan's points, placed by odometry, as the control node has them); an imminent
collision latches the e-stop (`estop_on_imminent`), which both hear.
"""

from __future__ import annotations

import math

import numpy as np

from autochair.control.core import ControlCore
from autochair.pid.core import VelocityPidCore
from autochair.runtime.config import ChairGeometry, StaleConfig
from autochair.safety.core import EStopAction, SafetyCore, SafetyParams, Scan
from autochair.safety.monitor import Monitor
from autochair.safety.node import SafetyConfig
from autochair.sim.lidar.node import LidarSimConfig
from autochair.sim.lidar.scanner import UrgParams, beam_rays, ray_scan
from autochair.sim.world import World


class SafetyRig:
    def __init__(self, seed: int = 0) -> None:
        cfg, chair, stale = SafetyConfig(), ChairGeometry(), StaleConfig()
        self.mount = chair.laser_mount
        core = SafetyCore(SafetyParams.of(cfg, chair.front_m, chair.rear_m, chair.half_width_m,
                                          self.mount))
        self.monitor = Monitor(core, stale.scan_s, stale.odometry_s, cfg.clear_hold_s,
                               cfg.frame_id, stale.scan_age_s, stale.clock_skew_s)
        sim = LidarSimConfig(tcp_port=0)  # (an endpoint is required; none is opened here)
        self.urg, self.noise_m = UrgParams(scan_rate_hz=sim.scan_rate_hz), sim.noise_std_m
        self.inc = 2 * math.pi / self.urg.ares
        u = self.urg
        # The monitor's standing |ω| bound: its unseen footprint swings at blind_speed_mps
        # (fov as the monitor reads it off each scan: each beam ±half an increment)
        self.omega_cap = core.fov_swing(((u.amin - u.afrt - 0.5) * self.inc,
                                         (u.amax - u.amin + 1) * self.inc))[1]
        self.rng = np.random.default_rng(seed)
        self.next_t = 0.0
        self.scans = 0
        self.binding = 0  # scans whose limit held the chair under what navigation asked
        self.stops: list[tuple[float, str]] = []  # (t, reason) of scans that stop motion
        self.estops = 0
        self._owed: tuple[float, float, str, float] | None = None  # the limit for the control

    def tick(self, t: float, world: World, pose: tuple[float, float, float],
             twist: tuple[float, float], odom: tuple[float, float],
             pid: VelocityPidCore, control: ControlCore) -> None:
        """One 100 Hz tick: the odometry's motion to the monitor; a scan when one is due, its
        limit to the PID and to the control core (as the control node passes it on)."""
        control.gates.monitor_up = True  # (its liveliness token, seen before any goal)
        if self._owed is not None:
            control.on_limit(*self._owed)
            self._owed = None
        self.monitor.on_odom(*odom, t)
        if t + 1e-9 < self.next_t:
            return
        self.next_t += 1.0 / self.urg.scan_rate_hz
        raw = ray_scan(world.at(t), self.urg, pose, self.mount, self.noise_m, self.rng, twist)
        u = self.urg
        r = np.where((raw < u.dmin_mm) | (raw > u.dmax_mm), np.nan, raw * 1e-3)
        scan = Scan(r, (u.amin - u.afrt) * self.inc, self.inc, u.dmin_mm * 1e-3,
                    u.dmax_mm * 1e-3)
        v = self.monitor.on_scan(scan, t)
        if (o := control.odom) is not None:
            # (each beam placed by odometry at its own time in the sweep, as the control
            # node's ScanPeople places them)
            bx, by, ba = beam_rays(u, (o.x, o.y, o.yaw), self.mount, odom)
            control.on_scan(t, np.column_stack((bx + r * np.cos(ba), by + r * np.sin(ba))))
        lim = v.published
        self.scans += 1
        want_v, want_w = pid._desired if pid.obeying else (0.0, 0.0)
        self.binding += want_v > lim.v_fwd + 1e-3 or abs(want_w) > lim.omega + 1e-3
        if (lim.v_fwd == 0.0 and odom[0] > 0.05) or (lim.omega == 0.0 and abs(odom[1]) > 0.05):
            self.stops.append((round(t, 2), lim.reason))
        pid.set_limit(lim.v_fwd, lim.v_rev, lim.omega, t, lim.v_rev_autonomy)
        # The control node hears the limit as the PID does, but acts on it at its own next
        # tick: the PID's 100 Hz update first applies it to the command it holds (one with
        # v > 0 under a forward bound of 0 latches its stop). Passed on in the same tick, the
        # core's answer reached the PID first, which a live stack cannot count on.
        self._owed = (lim.v_fwd, lim.omega, lim.reason, t)
        if v.estop is EStopAction.ASSERT:
            self.estops += 1
            pid.set_estop(True, t, round(t * 1e9))
            control.on_estop(True, t)
