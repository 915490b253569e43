"""Velocity PID node: runs both loops on every odometry sample (the encoder rate)."""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable

import msgspec

from autochair.runtime import ConfigError, Node, service_main
from autochair_msgs import (
    CommandOwner,
    JoystickCommand,
    Odometry,
    PidStatus,
    SafetyLimit,
    VelocityCommand,
    keys,
)

from .core import VelocityPidCore


class PidConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    # (Kp, Ki 1/s, Kd s): the thesis's Ziegler–Nichols gains (table 5.1)
    v_gains: tuple[float, float, float] = (0.90, 1.03, 0.20)
    omega_gains: tuple[float, float, float] = (0.72, 1.08, 0.12)
    min_v: float = 1.1
    max_v: float = 3.9
    d_filter_n: float = 10.0
    # Drive only within a fresh limit from the safety monitor (stale limit → stop).
    require_safety_limit: bool = False


def start(node: Node, cfg: PidConfig) -> None:
    if any(g < 0 for g in (*cfg.v_gains, *cfg.omega_gains)):
        raise ConfigError("[pid] gains must be ≥ 0")
    stale = node.stale
    core = VelocityPidCore(v_gains=cfg.v_gains, omega_gains=cfg.omega_gains, min_v=cfg.min_v,
                           max_v=cfg.max_v, stale_s=stale.desired_velocity_s,
                           require_limit=cfg.require_safety_limit,
                           limit_stale_s=stale.safety_limit_s)
    core.v_pid.d_filter_n = core.omega_pid.d_filter_n = cfg.d_filter_n
    node.health.thresholds.update(desired_velocity_s=stale.desired_velocity_s,
                                  safety_limit_s=stale.safety_limit_s)
    lock = threading.Lock()
    joy_pub = node.publisher(keys.JOYSTICK)
    status_pub = node.publisher(keys.PID_STATUS)

    def desired_from(source: str) -> Callable[[VelocityCommand], None]:
        def on_desired(cmd: VelocityCommand) -> None:
            with lock:
                result = core.set_desired(cmd.v_mps, cmd.omega_radps, time.monotonic(), source)
            node.health.count(f"desired_{result}")

        return on_desired

    def on_owner(msg: CommandOwner) -> None:
        with lock:
            previous = core.owner
            ok = core.set_owner(msg.owner)
        if not ok:
            node.health.count("rejected_owner")
        elif msg.owner != previous:
            node.event("warning", f"drive handed to {msg.owner} by {msg.by or '?'}")
            node.health.detail = f"owner {msg.owner}"

    def on_limit(msg: SafetyLimit) -> None:
        with lock:
            ok = core.set_limit(msg.v_max_fwd_mps, msg.v_max_rev_mps, msg.omega_max_radps,
                                time.monotonic())
        node.health.count("limits" if ok else "rejected_limits")

    def on_odom(odom: Odometry) -> None:
        now = time.monotonic()
        with lock:
            desired = core.desired(now) or (0.0, 0.0)
            out = core.update(odom.v_mps, odom.omega_radps, odom.sample_dt_s, now)
        stamp = time.time_ns()
        joy_pub.put(JoystickCommand(stamp_ns=stamp, longitudinal_v=out.longitudinal_v,
                                    angular_v=out.angular_v, enable=out.active,
                                    source_seq=odom.source_seq))
        sat = any(abs(v - 2.5) >= min(cfg.max_v - 2.5, 2.5 - cfg.min_v) - 1e-9
                  for v in (out.longitudinal_v, out.angular_v))
        status_pub.put(PidStatus(
            stamp_ns=stamp, v_desired_mps=desired[0], v_measured_mps=odom.v_mps,
            v_effort=out.v_effort, omega_desired_radps=desired[1],
            omega_measured_radps=odom.omega_radps, omega_effort=out.omega_effort,
            active=out.active, saturated=sat))
        node.health.count("updates")

    node.health.detail = "owner autonomy"
    node.subscribe(keys.CMD_VEL, desired_from("autonomy"))
    node.subscribe(keys.TELEOP, desired_from("teleop"))
    node.subscribe(keys.CMD_OWNER, on_owner)
    node.subscribe(keys.SAFETY_LIMIT, on_limit)
    node.subscribe(keys.ODOM, on_odom)


def main(argv: list[str] | None = None) -> int:
    return service_main("pid", PidConfig, start, argv, __doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
