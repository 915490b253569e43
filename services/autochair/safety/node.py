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

import math
import sys
import threading
import time

import msgspec
import numpy as np
import zenoh

from autochair.runtime import ConfigError, Node, service_main
from autochair.runtime.node import Publisher
from autochair_msgs import EStopAssert, FrameTransform, LaserScan, Odometry, SafetyLimit, keys

from .core import (
    DIRECTIONS,
    EStopAction,
    Limit,
    MonitorState,
    SafetyCore,
    SafetyParams,
    Scan,
    stop_limit,
)

IMMINENT = "imminent collision"


class SafetyConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """[safety] section. SI units. The footprint and the laser mount are the [chair] section."""

    padding_m: float = 0.05  # grown on every side
    decel_mps2: float = 1.0  # planned braking deceleration
    reaction_s: float = 1.0  # latency margin (scan age, PID, chair controller lag ~1 s)
    stop_margin_m: float = 0.10  # stop this short of the obstacle
    alpha_radps2: float = 1.5  # planned angular deceleration
    v_max_fwd_mps: float = 1.2  # published bound with nothing in view
    v_max_rev_mps: float = 0.5  # attended (teleop) reverse: the laser cannot see behind
    omega_max_radps: float = 1.0
    estop_on_imminent: bool = True  # assert the e-stop on a collision it could not prevent
    estop_decel_mps2: float = 2.0
    # Fewer valid beams than this in a direction's swept sector: that direction is blocked.
    min_valid_fraction: float = 0.3
    # The footprint the laser cannot see swings at most this fast: |ω| ≤ this / R_max.
    blind_speed_mps: float = 0.3
    # Autonomy may reverse this fast with nothing sensing behind the chair (0 = never).
    blind_reverse_autonomy_mps: float = 0.0
    frame_id: str = "laser"  # scans in any other frame are rejected (a stop)
    clear_hold_s: float = 1.0  # e-stop clear repeated on every scan this long


def params_from(cfg: SafetyConfig, node: Node) -> SafetyParams:
    chair = node.chair
    names = ("padding_m", "decel_mps2", "reaction_s", "stop_margin_m", "alpha_radps2",
             "v_max_fwd_mps", "v_max_rev_mps", "omega_max_radps", "estop_decel_mps2",
             "min_valid_fraction", "blind_speed_mps", "blind_reverse_autonomy_mps")
    return SafetyParams(front_m=chair.front_m, rear_m=chair.rear_m,
                        half_width_m=chair.half_width_m, mount=chair.laser_mount,
                        **{n: getattr(cfg, n) for n in names})


def reliable_publisher(node: Node, topic: keys.Topic[EStopAssert]) -> Publisher:
    """Congestion control BLOCK (reliable, never dropped under load), unlike Node.publisher's
    DROP: one lost e-stop sample must change nothing."""
    pub = node.session.declare_publisher(
        topic.key, express=True, congestion_control=zenoh.CongestionControl.BLOCK,
        reliability=zenoh.Reliability.RELIABLE)
    return Publisher(pub, node.stop_event)


def start(node: Node, cfg: SafetyConfig) -> None:
    try:
        core = SafetyCore(params_from(cfg, node))
    except ValueError as e:
        raise ConfigError(f"[safety] {e}") from None
    if cfg.clear_hold_s < 0:
        raise ConfigError("[safety] clear_hold_s must be ≥ 0")
    chair = node.chair
    health = node.health
    health.thresholds.update(scan_s=node.stale.scan_s, odometry_s=node.stale.odometry_s,
                             decel_mps2=cfg.decel_mps2, reaction_s=cfg.reaction_s,
                             min_valid_fraction=cfg.min_valid_fraction,
                             blind_speed_mps=cfg.blind_speed_mps,
                             blind_reverse_autonomy_mps=cfg.blind_reverse_autonomy_mps)
    limit_pub = node.publisher(keys.SAFETY_LIMIT)
    assert_pub = reliable_publisher(node, keys.ESTOP_ASSERT)
    clear_pub = reliable_publisher(node, keys.ESTOP_CLEAR)
    lock = threading.Lock()
    motion = {"v": 0.0, "w": 0.0, "t": -math.inf}
    state = MonitorState(stale_s=node.stale.scan_s, clear_hold_s=cfg.clear_hold_s)

    def publish(lim: Limit) -> None:
        limit_pub.put(SafetyLimit(stamp_ns=time.time_ns(), v_max_fwd_mps=lim.v_fwd,
                                  v_max_rev_mps=lim.v_rev, omega_max_radps=lim.omega,
                                  reason=lim.reason, v_max_rev_autonomy_mps=lim.v_rev_autonomy))

    def estop(action: EStopAction) -> None:
        if action is EStopAction.ASSERT:
            assert_pub.put(EStopAssert(stamp_ns=time.time_ns(), source=node.name,
                                       reason=IMMINENT, active=True))
            health.count("estop_asserts")
        elif action is EStopAction.CLEAR:
            clear_pub.put(EStopAssert(stamp_ns=time.time_ns(), source=node.name,
                                      reason=IMMINENT, active=False))
            health.count("estop_clears")

    def on_odom(o: Odometry) -> None:
        with lock:
            motion.update(v=o.v_mps, w=o.omega_radps, t=time.monotonic())

    def on_tf(tf: FrameTransform) -> None:
        if tf.child_frame_id != cfg.frame_id:
            return
        err = chair.laser_tf_error(tf)
        with lock:
            changed = state.on_mount(err)
        if err:
            health.count("mount_mismatch")
            publish(stop_limit(f"laser mount mismatch: {err}"))  # at once, not at the next scan
        if changed and err:
            node.event("error", f"safety: laser mount mismatch: {err}: stop until tf_static "
                                "and [chair] agree")
        elif changed:
            node.event("info", "safety: laser mount in tf_static agrees with [chair]")

    def on_scan(msg: LaserScan) -> None:
        now = time.monotonic()
        with lock:
            fresh = now - motion["t"] <= node.stale.odometry_s
            v, w = (motion["v"], motion["w"]) if fresh else (0.0, 0.0)
        if not fresh:
            health.count("odometry_stale")
        scan = Scan(np.asarray(msg.ranges_m, dtype=np.float64), msg.angle_min_rad,
                    msg.angle_increment_rad, msg.range_min_m, msg.range_max_m, msg.frame_id)
        lim = core.assess(scan, v, w, cfg.frame_id)
        with lock:
            state.on_scan(now, lim.reason if lim.rejected else "")  # "scan rejected: why"
            mount_err = state.mount_error
            # A rejected scan says nothing new about a collision: the previous verdict stands.
            imminent = state.imminent if lim.rejected else lim.imminent
            action, changed = state.estop(imminent, now)
        published = lim
        if mount_err:
            published = stop_limit(f"laser mount mismatch: {mount_err}")
        publish(published)
        if cfg.estop_on_imminent:
            estop(action)
            if changed and imminent:
                node.event("error", f"safety: {IMMINENT} at {v:.2f} m/s ({lim.reason}): "
                                    "e-stop")
            elif changed:
                node.event("info", f"safety: {IMMINENT} no more: cause cleared")
        health.count("limits")
        if lim.rejected:
            health.count("rejected_scans")
            health.count(f"rejected:{lim.rejected}")
        blind = tuple(name for name, frac in zip(DIRECTIONS, lim.valid_fraction, strict=True)
                      if frac is not None and frac < cfg.min_valid_fraction)
        for name in blind:
            health.count(f"blind:{name}")
        with lock:
            blind_changed = state.on_blind(blind)
        if blind_changed and blind:
            node.event("warning", f"safety: {'; '.join(lim.blind)}: stop those directions")
        elif blind_changed:
            node.event("info", "safety: the laser sees every direction's sector again")
        if published.v_fwd < cfg.v_max_fwd_mps:
            health.count("limited_fwd")
        if published.v_fwd == 0.0:
            health.count("stopped_fwd")
        health.state = ("degraded" if published is not lim or lim.rejected or lim.blind
                        else "ok")
        health.detail = detail(published, lim)

    def detail(published: Limit, lim: Limit) -> str:
        head = (f"fwd ≤ {published.v_fwd:.2f} rev ≤ {published.v_rev:.2f} (autonomy "
                f"{published.v_rev_autonomy:.2f}) m/s |ω| ≤ {published.omega:.2f} rad/s")
        if published.reason != lim.reason or lim.rejected:
            return f"stop: {published.reason}; {head}"
        parts = [f"nearest {lim.nearest_m:.2f} m; {head}", *lim.blind]
        if not lim.rear_seen:
            parts.append("rear unseen: autonomy may not reverse" if lim.v_rev_autonomy == 0
                         else f"rear unseen: autonomy reverses blind ≤ {lim.v_rev_autonomy:.2f}"
                              " m/s")
        if lim.unseen_radius_m > 0:
            parts.append(f"|ω| ≤ {lim.omega_unseen_cap:.2f} rad/s for the unseen footprint "
                         f"(R {lim.unseen_radius_m:.2f} m at {cfg.blind_speed_mps} m/s)")
        return "; ".join(parts)

    def watchdog() -> None:
        now = time.monotonic()
        with lock:
            silent = state.stale(now)
            faults, changed = state.poll(now)
            reason = state.reason(now)
        if silent:
            publish(stop_limit(reason))
            health.count("stale_stops")
            health.state, health.detail = "degraded", f"stop: {reason}"
        if changed and faults:
            node.event("warning", f"safety: {reason}: stop")
        elif changed:
            node.event("info", "safety: scans fresh, limits from the scan")

    def on_lidar_token(sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.DELETE:  # the ingest died: stop now, not in 0.5 s
            with lock:
                state.source_lost()
            watchdog()

    # At start: clear any cause a previous instance of this monitor left behind.
    estop(EStopAction.CLEAR)
    token_sub = node.session.liveliness().declare_subscriber(f"{keys.PREFIX}/alive/lidar",
                                                            on_lidar_token)
    node.on_close(token_sub.undeclare)
    node.subscribe(keys.ODOM, on_odom)
    node.subscribe(keys.TF_STATIC, on_tf)
    node.subscribe(keys.SCAN, on_scan)
    node.every(0.1, watchdog, "watchdog")


def main(argv: list[str] | None = None) -> int:
    return service_main("safety", SafetyConfig, start, argv, __doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
