"""Safety monitor node: laser scan + odometry in, keys.SAFETY_LIMIT out at scan rate.

Fails closed: a stale scan (older than [stale] scan_s), a rejected scan (absurd fields, wrong
frame) or a laser mount in tf_static that disagrees with [chair] publishes a stop limit
(0, 0, 0); a direction whose swept sector the laser does not see (too few valid beams) is
blocked; |ω| is capped by the swing of the footprint the laser cannot see, and autonomy may not
reverse (SafetyLimit.v_max_rev_autonomy_mps = 0) unless [safety] blind_reverse_autonomy_mps
allows it. The footprint and the laser mount are the [chair] geometry (`node.chair`).

With `estop_on_imminent` the monitor asserts the e-stop (keys.ESTOP_ASSERT, reliable, on every
scan while it lasts) when the chair moves faster than it could stop within the free distance
even braking at `estop_decel_mps2`, and clears its cause on keys.ESTOP_CLEAR on every scan for
1 s once it is no longer imminent, and at start (a restarted monitor clears what it left).
"""

from __future__ import annotations

import sys
import threading
import time
from typing import Annotated

import msgspec
import numpy as np

from autochair.geometry import quaternion_yaw
from autochair.runtime import Node, service_main
from autochair_msgs import (
    EStopAssert,
    FrameTransform,
    LaserScan,
    LocalizedPose,
    OccupancyGrid,
    Odometry,
    SafetyLimit,
    keys,
)

from .core import EStopAction, Limit, SafetyCore, SafetyParams, SafetyTuning, Scan
from .keepout import load_keepout
from .monitor import Monitor, ScanVerdict

IMMINENT = "imminent collision"


class SafetyConfig(SafetyTuning, kw_only=True, frozen=True):
    """[safety] section: the core's tuning (SafetyTuning) plus the node's own settings. The
    footprint and the laser mount are the [chair] section."""

    estop_on_imminent: bool = True  # assert the e-stop on a collision it could not prevent
    frame_id: str = "laser"  # scans in any other frame are rejected (a stop)
    clear_hold_s: Annotated[float, msgspec.Meta(ge=0)] = 1.0  # e-stop clear repeated this long
    # A mask map (map_server YAML) whose occupied cells are keep-out zones the laser cannot see
    # (stairs down, kerbs, glass): placed with localization, a stop while they cannot be (H42).
    keepout_map: str = ""


def start(node: Node, cfg: SafetyConfig) -> None:
    chair = node.chair
    core = SafetyCore(SafetyParams.of(cfg, chair.front_m, chair.rear_m, chair.half_width_m,
                                      chair.laser_mount))
    monitor = Monitor(core, node.stale.scan_s, node.stale.odometry_s, cfg.clear_hold_s,
                      cfg.frame_id, node.stale.scan_age_s, node.stale.clock_skew_s,
                      load_keepout("safety", cfg.keepout_map))
    node.health.thresholds.update(
        scan_s=node.stale.scan_s, scan_age_s=node.stale.scan_age_s,
        odometry_s=node.stale.odometry_s, decel_mps2=cfg.decel_mps2,
        reaction_s=cfg.reaction_s, min_valid_fraction=cfg.min_valid_fraction,
        blind_speed_mps=cfg.blind_speed_mps,
        blind_reverse_autonomy_mps=cfg.blind_reverse_autonomy_mps)
    wiring = _Wiring(node, cfg, monitor)
    wiring.estop(EStopAction.CLEAR)  # a restarted monitor clears the cause it left behind
    node.watch_alive("lidar", wiring.on_lidar_alive)
    node.subscribe(keys.ODOM_SLOW, wiring.on_odom)
    node.subscribe(keys.TF_STATIC, wiring.on_tf)
    node.subscribe(keys.SCAN, wiring.on_scan)
    if monitor.keepout is not None:
        node.health.thresholds["keepout_edge_cells"] = len(monitor.keepout.edges)
        node.log.info("keep-out zones from %s: %d edge cells", cfg.keepout_map,
                      len(monitor.keepout.edges))
        node.subscribe(keys.TF, wiring.on_correction)
        node.subscribe(keys.LOC_POSE, wiring.on_loc)
        node.subscribe(keys.LOC_MAP, wiring.on_loc_map)
    node.every(0.1, wiring.tick, "watchdog")


class _Wiring:
    """Monitor verdicts to publications, counters and events."""

    def __init__(self, node: Node, cfg: SafetyConfig, monitor: Monitor) -> None:
        self.node, self.cfg, self.monitor = node, cfg, monitor
        self.health = node.health
        self.lock = threading.Lock()
        self.limit_pub = node.publisher(keys.SAFETY_LIMIT)
        self.assert_pub = node.publisher(keys.ESTOP_ASSERT, reliable=True)
        self.clear_pub = node.publisher(keys.ESTOP_CLEAR, reliable=True)

    def publish(self, lim: Limit) -> None:
        self.limit_pub.put(SafetyLimit(
            stamp_ns=time.time_ns(), v_max_fwd_mps=lim.v_fwd, v_max_rev_mps=lim.v_rev,
            omega_max_radps=lim.omega, reason=lim.reason,
            v_max_rev_autonomy_mps=lim.v_rev_autonomy))

    def estop(self, action: EStopAction) -> None:
        if action is EStopAction.NONE:
            return
        pub = self.assert_pub if action is EStopAction.ASSERT else self.clear_pub
        pub.put(EStopAssert(stamp_ns=time.time_ns(), source=self.node.name, reason=IMMINENT,
                            active=action is EStopAction.ASSERT))
        self.health.count("estop_asserts" if action is EStopAction.ASSERT else "estop_clears")

    def on_odom(self, o: Odometry) -> None:
        with self.lock:
            self.monitor.on_odom(o.v_mps, o.omega_radps, time.monotonic(),
                                 (o.x_m, o.y_m, o.yaw_rad))

    def on_correction(self, msg: FrameTransform) -> None:
        if msg.parent_frame_id == "map" and msg.child_frame_id == "odom":
            t, r = msg.translation, msg.rotation
            with self.lock:
                self.monitor.on_correction((t.x, t.y, quaternion_yaw(r.x, r.y, r.z, r.w)))

    def on_loc(self, msg: LocalizedPose) -> None:
        with self.lock:
            self.monitor.on_loc_state(msg.state, msg.mode, time.monotonic())

    def on_loc_map(self, grid: OccupancyGrid) -> None:
        with self.lock:
            self.monitor.on_loc_map(grid)

    def on_tf(self, tf: FrameTransform) -> None:
        if tf.child_frame_id != self.cfg.frame_id:
            return
        err = self.node.chair.laser_tf_error(tf)
        with self.lock:
            stop, changed = self.monitor.on_mount(err)
        if stop is not None:
            self.health.count("mount_mismatch")
            self.publish(stop)  # at once, not at the next scan
        if changed and err:
            self.node.event("error", f"safety: laser mount mismatch: {err}: stop until "
                                     "tf_static and [chair] agree")
        elif changed:
            self.node.event("info", "safety: laser mount in tf_static agrees with [chair]")

    def on_scan(self, msg: LaserScan) -> None:
        scan = Scan(np.asarray(msg.ranges_m, dtype=np.float64), msg.angle_min_rad,
                    msg.angle_increment_rad, msg.range_min_m, msg.range_max_m, msg.frame_id)
        with self.lock:
            verdict = self.monitor.on_scan(scan, time.monotonic(),
                                           (time.time_ns() - msg.stamp_ns) / 1e9)
        self.publish(verdict.published)
        if self.cfg.estop_on_imminent:
            self.estop(verdict.estop)
            if verdict.imminent_changed:
                self.node.event(*(("error", f"safety: {IMMINENT} at {verdict.v:.2f} m/s "
                                            f"({verdict.assessed.reason}): e-stop")
                                  if verdict.imminent
                                  else ("info", f"safety: {IMMINENT} no more: cause cleared")))
        self._count(verdict)
        if verdict.blind_changed:
            self.node.event(*(("warning", f"safety: {'; '.join(verdict.assessed.blind)}: stop "
                                          "those directions") if verdict.blind
                              else ("info", "safety: the laser sees every direction's sector "
                                            "again")))
        self.health.state = "degraded" if verdict.degraded else "ok"
        self.health.detail = verdict.detail

    def _count(self, verdict: ScanVerdict) -> None:
        count, lim = self.health.count, verdict.assessed
        count("limits")
        if verdict.odometry_stale:
            count("odometry_stale")
        if lim.rejected:
            count("rejected_scans")
            count(f"rejected:{lim.rejected}")
        for name in verdict.blind:
            count(f"blind:{name}")
        if verdict.published.v_fwd < self.cfg.v_max_fwd_mps:
            count("limited_fwd")
        if verdict.published.v_fwd == 0.0:
            count("stopped_fwd")

    def tick(self) -> None:
        with self.lock:
            t = self.monitor.tick(time.monotonic())
        if t.stop is not None:
            self.publish(t.stop)
            self.health.count("stale_stops")
            self.health.state, self.health.detail = "degraded", f"stop: {t.reason}"
        if t.changed:
            self.node.event(*(("warning", f"safety: {t.reason}: stop") if t.faults
                              else ("info", "safety: scans fresh, limits from the scan")))

    def on_lidar_alive(self, alive: bool) -> None:
        if not alive:  # the ingest died: stop now, not in 0.5 s
            with self.lock:
                self.monitor.source_lost()
            self.tick()


def main(argv: list[str] | None = None) -> int:
    return service_main("safety", SafetyConfig, start, argv, __doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
