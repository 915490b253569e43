"""Velocity PID node: runs both loops on every odometry sample (the encoder rate).

Every decision (whose command counts, when to stop, the caps and the safety limit) is in
`VelocityPidCore`; this node only wires Zenoh to it.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable

import msgspec
import zenoh

from autochair.runtime import ConfigError, Node, service_main
from autochair_msgs import (
    CommandOwner,
    EStopState,
    JoystickCommand,
    Odometry,
    PidStatus,
    SafetyLimit,
    VelocityCommand,
    keys,
)

from .core import Caps, Command, VelocityPidCore


class PidConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    # (Kp, Ki 1/s, Kd s): the thesis's Ziegler–Nichols gains (table 5.1)
    v_gains: tuple[float, float, float] = (0.90, 1.03, 0.20)
    omega_gains: tuple[float, float, float] = (0.72, 1.08, 0.12)
    min_v: float = 1.1
    max_v: float = 3.9
    d_filter_n: float = 10.0
    # Drive only within a fresh limit from the safety monitor (stale limit → stop). The process
    # list sets it whenever the stack runs the monitor (processes.stack_values).
    require_safety_limit: bool = True
    # Drive only while the e-stop service says "released" (as the gateway does).
    require_estop: bool = True
    # Absolute caps whatever the source (CLI, teleop, autonomy); tools read them from health.
    v_max_fwd_mps: float = 1.2
    v_max_rev_mps: float = 0.5
    omega_max_radps: float = 1.0


def start(node: Node, cfg: PidConfig) -> None:
    if any(g < 0 for g in (*cfg.v_gains, *cfg.omega_gains)):
        raise ConfigError("[pid] gains must be ≥ 0")
    if not all(0 < c <= 3 for c in (cfg.v_max_fwd_mps, cfg.v_max_rev_mps, cfg.omega_max_radps)):
        raise ConfigError("[pid] v_max_fwd_mps, v_max_rev_mps and omega_max_radps must be "
                          "within (0, 3]")
    stale = node.stale
    core = VelocityPidCore(
        v_gains=cfg.v_gains, omega_gains=cfg.omega_gains, min_v=cfg.min_v, max_v=cfg.max_v,
        stale_s=stale.desired_velocity_s, skew_s=stale.clock_skew_s,
        require_limit=cfg.require_safety_limit, limit_stale_s=stale.safety_limit_s,
        require_estop=cfg.require_estop, estop_stale_s=stale.estop_s,
        odom_gap_s=stale.odometry_s,
        caps=Caps(cfg.v_max_fwd_mps, cfg.v_max_rev_mps, cfg.omega_max_radps),
        start_ns=time.time_ns())
    core.v_pid.d_filter_n = core.omega_pid.d_filter_n = cfg.d_filter_n
    node.health.thresholds.update(
        desired_velocity_s=stale.desired_velocity_s, safety_limit_s=stale.safety_limit_s,
        estop_s=stale.estop_s, odometry_s=stale.odometry_s, clock_skew_s=stale.clock_skew_s,
        v_max_fwd_mps=cfg.v_max_fwd_mps, v_max_rev_mps=cfg.v_max_rev_mps,
        omega_max_radps=cfg.omega_max_radps,
        require_safety_limit=float(cfg.require_safety_limit))
    lock = threading.Lock()
    joy_pub = node.publisher(keys.JOYSTICK)
    status_pub = node.publisher(keys.PID_STATUS)

    def stopped(ended: bool) -> None:
        """Say once, when a stop ends a stream the PID was obeying."""
        if ended:
            node.health.count("stops")
            node.event("warning", f"pid: stopped ({core.stop_reason}): it drives again on "
                                  "a command begun after the stop")

    def desired_from(source: str) -> Callable[[VelocityCommand], None]:
        def on_desired(cmd: VelocityCommand) -> None:
            with lock:
                verdict = core.set_desired(
                    Command(cmd.v_mps, cmd.omega_radps, source, cmd.stamp_ns,
                            cmd.stream_start_ns), time.monotonic(), time.time_ns())
            node.health.count(f"desired_{verdict.value}")

        return on_desired

    def on_owner(msg: CommandOwner) -> None:
        with lock:
            previous = core.owner
            ok = core.set_owner(msg.owner, time.time_ns())
        if not ok:
            node.health.count("rejected_owner")
        elif msg.owner != previous:
            node.event("warning", f"drive handed to {msg.owner} by {msg.by or '?'}: a stop; "
                                  "it drives again on a command begun after it")

    def on_limit(msg: SafetyLimit) -> None:
        with lock:
            ok = core.set_limit(msg.v_max_fwd_mps, msg.v_max_rev_mps, msg.omega_max_radps,
                                time.monotonic(), msg.v_max_rev_autonomy_mps)
        node.health.count("limits" if ok else "rejected_limits")

    def on_estop(msg: EStopState) -> None:
        with lock:
            ended = core.set_estop(msg.latched, time.monotonic(), time.time_ns())
        stopped(ended)

    def on_token(service: str) -> Callable[[zenoh.Sample], None]:
        def on_sample(sample: zenoh.Sample) -> None:
            if sample.kind != zenoh.SampleKind.DELETE:
                return
            with lock:
                now_ns = time.time_ns()
                if service == "estop":
                    ended = core.estop_gone(now_ns)
                elif service == "safety":
                    ended = core.limit_gone(now_ns)
                else:
                    ended = core.stop(f"{service} lost", now_ns)
            if service == "odometry":  # no measurement will come to publish on: neutral now
                joy_pub.put(JoystickCommand(stamp_ns=time.time_ns(), longitudinal_v=2.5,
                                            angular_v=2.5, enable=False))
            stopped(ended)

        return on_sample

    def on_odom(odom: Odometry) -> None:
        now, now_ns = time.monotonic(), time.time_ns()
        with lock:
            was = core.obeying
            out = core.update(odom.v_mps, odom.omega_radps, odom.sample_dt_s, now, now_ns,
                              (odom.mcu_restarts, odom.link_epoch))
            inhibit = core.inhibit(now)
            ended = was and not core.obeying
            owner = core.owner
        stopped(ended)
        stamp = time.time_ns()
        joy_pub.put(JoystickCommand(stamp_ns=stamp, longitudinal_v=out.longitudinal_v,
                                    angular_v=out.angular_v, enable=out.active,
                                    source_seq=odom.source_seq))
        sat = any(abs(v - 2.5) >= min(cfg.max_v - 2.5, 2.5 - cfg.min_v) - 1e-9
                  for v in (out.longitudinal_v, out.angular_v))
        status_pub.put(PidStatus(
            stamp_ns=stamp, v_desired_mps=out.desired[0], v_measured_mps=odom.v_mps,
            v_effort=out.v_effort, omega_desired_radps=out.desired[1],
            omega_measured_radps=odom.omega_radps, omega_effort=out.omega_effort,
            active=out.active, saturated=sat, inhibit=inhibit))
        node.health.count("updates")
        node.health.detail = f"owner {owner}: " + (inhibit or "driving")

    node.health.detail = "owner autonomy: no odometry yet"
    node.subscribe(keys.CMD_VEL, desired_from("autonomy"))
    node.subscribe(keys.TELEOP, desired_from("teleop"))
    node.subscribe(keys.CMD_OWNER, on_owner)
    node.subscribe(keys.SAFETY_LIMIT, on_limit)
    node.subscribe(keys.ESTOP_STATE, on_estop)
    node.subscribe(keys.ODOM, on_odom)
    # A killed service's token vanishes within milliseconds, sooner than any heartbeat.
    for service in ("estop", "gateway", "odometry", "safety"):
        sub = node.session.liveliness().declare_subscriber(
            f"{keys.PREFIX}/alive/{service}", on_token(service))
        node.on_close(sub.undeclare)


def main(argv: list[str] | None = None) -> int:
    return service_main("pid", PidConfig, start, argv, __doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
