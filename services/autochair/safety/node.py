"""Safety monitor node: laser scan + odometry in, keys.SAFETY_LIMIT out at scan rate.

A stale scan (older than [stale] scan_s) publishes a stop limit (0, 0, 0). With
`estop_on_imminent` the monitor latches the e-stop when the chair moves faster than it could
stop within the free distance even braking at `estop_decel_mps2` (something appeared too close
to be handled by slowing down), and reports the cause cleared once it is no longer imminent.
"""

from __future__ import annotations

import math
import sys
import threading
import time

import msgspec
import numpy as np

from autochair.runtime import ConfigError, Node, service_main
from autochair_msgs import EStopAssert, LaserScan, Odometry, SafetyLimit, keys

from .core import SafetyCore, SafetyParams, scan_points


class SafetyConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """[safety] section. SI units; footprint in the chair frame around the drive axle."""

    front_m: float = 0.95  # footprint ahead of the drive axle
    rear_m: float = 0.25  # footprint behind the axle (1.2 m long in all)
    half_width_m: float = 0.35  # 0.7 m wide
    padding_m: float = 0.05  # grown on every side
    decel_mps2: float = 1.0  # planned braking deceleration
    reaction_s: float = 1.0  # latency margin (scan age, PID, chair controller lag ~1 s)
    stop_margin_m: float = 0.10  # stop this short of the obstacle
    alpha_radps2: float = 1.5  # planned angular deceleration
    v_max_fwd_mps: float = 1.2  # published bound with nothing in view
    v_max_rev_mps: float = 0.5  # the laser cannot see behind: back up slowly
    omega_max_radps: float = 1.0
    estop_on_imminent: bool = True  # latch the e-stop on a collision it could not prevent
    estop_decel_mps2: float = 2.0
    # The laser's pose in the chair frame (must match the lidar ingest's mount).
    mount_x_m: float = 0.8636
    mount_y_m: float = 0.2032
    mount_yaw_rad: float = 0.0
    frame_id: str = "laser"  # scans in any other frame are rejected (counted)


def _params(cfg: SafetyConfig) -> SafetyParams:
    names = ("front_m", "rear_m", "half_width_m", "padding_m", "decel_mps2", "reaction_s",
             "stop_margin_m", "alpha_radps2", "v_max_fwd_mps", "v_max_rev_mps",
             "omega_max_radps", "estop_decel_mps2")
    return SafetyParams(**{n: getattr(cfg, n) for n in names})


def start(node: Node, cfg: SafetyConfig) -> None:
    try:
        core = SafetyCore(_params(cfg))
    except ValueError as e:
        raise ConfigError(f"[safety] {e}") from None
    mount = (cfg.mount_x_m, cfg.mount_y_m, cfg.mount_yaw_rad)
    health = node.health
    health.thresholds.update(scan_s=node.stale.scan_s, odometry_s=node.stale.odometry_s,
                             decel_mps2=cfg.decel_mps2, reaction_s=cfg.reaction_s)
    limit_pub = node.publisher(keys.SAFETY_LIMIT)
    estop_pub = node.publisher(keys.ESTOP_ASSERT)
    lock = threading.Lock()
    motion = {"v": 0.0, "w": 0.0, "t": -math.inf}
    state = {"scan_t": -math.inf, "stale": True, "imminent": False}

    def publish(v_fwd: float, v_rev: float, omega: float, reason: str) -> None:
        limit_pub.put(SafetyLimit(stamp_ns=time.time_ns(), v_max_fwd_mps=v_fwd,
                                  v_max_rev_mps=v_rev, omega_max_radps=omega, reason=reason))

    def on_odom(o: Odometry) -> None:
        with lock:
            motion.update(v=o.v_mps, w=o.omega_radps, t=time.monotonic())

    def on_scan(scan: LaserScan) -> None:
        if scan.frame_id != cfg.frame_id:
            health.count("rejected_frame")
            return
        now = time.monotonic()
        with lock:
            fresh = now - motion["t"] <= node.stale.odometry_s
            v, w = (motion["v"], motion["w"]) if fresh else (0.0, 0.0)
        if not fresh:
            health.count("odometry_stale")
        pts = scan_points(np.asarray(scan.ranges_m, dtype=np.float64), scan.angle_min_rad,
                          scan.angle_increment_rad, scan.range_min_m, scan.range_max_m, mount)
        lim = core.limit(pts, v, w)
        publish(lim.v_fwd, lim.v_rev, lim.omega, lim.reason)
        with lock:
            state["scan_t"], was_stale = now, state["stale"]
            state["stale"] = False
            was_imminent, state["imminent"] = state["imminent"], lim.imminent
        if was_stale:
            node.event("info", "safety: scans fresh, limits from the scan")
        health.count("limits")
        if lim.v_fwd < cfg.v_max_fwd_mps:
            health.count("limited_fwd")
        if lim.v_fwd == 0.0:
            health.count("stopped_fwd")
        health.detail = (f"nearest {lim.nearest_m:.2f} m; fwd ≤ {lim.v_fwd:.2f} "
                         f"rev ≤ {lim.v_rev:.2f} m/s |ω| ≤ {lim.omega:.2f} rad/s")
        if cfg.estop_on_imminent and lim.imminent != was_imminent:
            reason = "imminent collision"
            estop_pub.put(EStopAssert(stamp_ns=time.time_ns(), source=node.name,
                                      reason=reason, active=lim.imminent))
            if lim.imminent:
                health.count("estop_asserts")
                node.event("error", f"safety: {reason} at {v:.2f} m/s ({lim.reason}): e-stop")
            else:
                node.event("info", "safety: collision no longer imminent (cause cleared)")

    def watchdog() -> None:
        with lock:
            stale = time.monotonic() - state["scan_t"] > node.stale.scan_s
            newly = stale and not state["stale"]
            if stale:
                state["stale"] = True
        if stale:
            publish(0.0, 0.0, 0.0, "scan stale")
            health.count("stale_stops")
            health.detail = "scan stale: stop"
        if newly:
            node.event("warning", f"safety: no laser scan for {node.stale.scan_s} s: stop")

    node.subscribe(keys.ODOM, on_odom)
    node.subscribe(keys.SCAN, on_scan)
    node.every(0.1, watchdog, "watchdog")


def main(argv: list[str] | None = None) -> int:
    return service_main("safety", SafetyConfig, start, argv, __doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
