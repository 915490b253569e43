"""Control-law node: goals in (Zenoh queries), smooth (v, ω) out while a goal is active.

Publishes keys.CMD_VEL at `rate_hz` only while a goal is active and while braking after it (then
`stop_burst_s` of zeros); when idle it publishes nothing, so the CLI or teleop can drive.
"""

from __future__ import annotations

import sys
import threading
import time

from autochair.runtime import ConfigError, Node, service_main
from autochair_msgs import (
    CommandOwner,
    Empty,
    EStopState,
    GoalReply,
    GoalRequest,
    GoalStatus,
    Odometry,
    SafetyLimit,
    VelocityCommand,
    keys,
)

from .core import ControlConfig, ControlCore, OdomSample


def start(node: Node, cfg: ControlConfig) -> None:
    try:  # the odometry watchdog is one of the chain's thresholds, set in [stale] only
        core = ControlCore(cfg, odom_timeout_s=node.stale.odometry_s)
    except ValueError as e:
        raise ConfigError(f"[control] {e}") from None
    node.health.thresholds.update(odometry_s=node.stale.odometry_s, rate_hz=cfg.rate_hz)
    lock = threading.Lock()
    cmd_pub = node.publisher(keys.CMD_VEL)
    status_pub = node.publisher(keys.GOAL_STATUS)

    def on_odom(o: Odometry) -> None:
        sample = OdomSample(o.x_m, o.y_m, o.yaw_rad, o.v_mps, o.omega_radps, time.monotonic())
        with lock:
            core.on_odom(sample)
        node.health.count("odom")

    # When the current goal was accepted (Unix ns): its commands carry it as their stream
    # start, so the velocity PID obeys them only if the goal came after its last stop.
    stream = {"start_ns": 0, "announced": 0}

    def tick() -> None:
        with lock:
            out = core.step(time.monotonic())
            ended = core.state != "active" and stream["announced"] != core.goal_id
            if ended:
                stream["announced"] = core.goal_id
        if ended and core.goal_id and core.state != "cancelled":  # (cancel says so itself)
            why = f": {core.reason}" if core.reason else ""
            node.event("warning" if core.state == "aborted" else "info",
                       f"goal {core.goal_id} {core.state}{why}")
        if out is not None:
            cmd_pub.put(VelocityCommand(stamp_ns=time.time_ns(), v_mps=out[0],
                                        omega_radps=out[1], source="control",
                                        stream_start_ns=stream["start_ns"]))
            node.health.count("commands")

    def status_msg() -> GoalStatus:
        with lock:
            s = core.status()
        return GoalStatus(stamp_ns=time.time_ns(), goal_id=s.goal_id, state=s.state,
                          waypoint_index=s.waypoint_index, waypoint_count=s.waypoint_count,
                          distance_left_m=round(s.distance_left_m, 4), eta_s=round(s.eta_s, 2),
                          reason=s.reason)

    def publish_status() -> None:
        status_pub.put(status_msg())

    def on_set(req: GoalRequest) -> GoalReply:
        with lock:
            result = core.set_goal(req, time.monotonic())
            if result.ok:
                stream["start_ns"] = time.time_ns()
        if result.ok:
            last = req.waypoints[-1]
            node.event("info", f"goal {result.goal_id}: {len(req.waypoints)} waypoint(s) to "
                               f"({last.x_m:.2f}, {last.y_m:.2f}, {last.yaw_rad:.3f} rad)")
        else:
            node.health.count("rejected_goals")
            node.event("warning", f"goal rejected: {result.error}")
        return result

    def on_cancel(_: GoalRequest) -> GoalReply:
        with lock:
            result = core.cancel(time.monotonic())
        if result.goal_id:
            node.event("info", f"goal {result.goal_id} cancelled")
        return result

    def on_get(_: Empty) -> GoalStatus:
        return status_msg()

    def on_estop(msg: EStopState) -> None:
        with lock:
            core.on_estop(msg.latched, time.monotonic())

    def on_owner(msg: CommandOwner) -> None:
        with lock:
            core.on_owner(msg.owner, time.monotonic())

    def on_limit(msg: SafetyLimit) -> None:
        with lock:  # plan within the monitor's bounds instead of being clamped by the PID
            core.on_limit(msg.v_max_rev_autonomy_mps, msg.omega_max_radps)

    node.subscribe(keys.ODOM, on_odom)
    node.subscribe(keys.ESTOP_STATE, on_estop)
    node.subscribe(keys.CMD_OWNER, on_owner)
    node.subscribe(keys.SAFETY_LIMIT, on_limit)
    node.serve(keys.GOAL_SET, on_set)
    node.serve(keys.GOAL_CANCEL, on_cancel)
    node.serve(keys.GOAL_GET, on_get)
    node.every(1.0 / cfg.rate_hz, tick, "control")
    node.every(1.0 / cfg.status_rate_hz, publish_status, "status")


def main(argv: list[str] | None = None) -> int:
    return service_main("control", ControlConfig, start, argv, __doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
