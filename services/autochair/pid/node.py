"""Velocity PID node: runs both loops on every odometry sample (the encoder rate).

Every decision (whose command counts, when to stop, the caps and the safety limit, the
feed-forward, saturation, tuning probes) is in `VelocityPidCore`; this node only wires Zenoh
to it.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable

from autochair.runtime import ConfigError, Node, service_main
from autochair.tune.core import Probe, ProbeKind
from autochair_msgs import (
    CommandOwner,
    EStopState,
    JoystickCommand,
    Odometry,
    PidProbeReply,
    PidProbeRequest,
    PidStatus,
    SafetyLimit,
    VelocityCommand,
    keys,
)

from .core import Command, PidConfig, VelocityPidCore, Verdict, make_core, probe_reply

__all__ = ["PidConfig", "main", "start"]


class PidWiring:
    """The callbacks: each takes the lock, asks the core, and publishes or counts."""

    def __init__(self, node: Node, core: VelocityPidCore) -> None:
        self.node, self.core = node, core
        self.lock = threading.Lock()
        self.joy_pub = node.publisher(keys.JOYSTICK)
        self.status_pub = node.publisher(keys.PID_STATUS)

    def stopped(self, ended: bool) -> None:
        """Say once, when a stop ends a stream the PID was obeying."""
        if ended:
            self.node.health.count("stops")
            self.node.event("warning", f"pid: stopped ({self.core.stop_reason}): it drives "
                                       "again on a command begun after the stop")

    def desired_from(self, source: str) -> Callable[[VelocityCommand], None]:
        def on_desired(cmd: VelocityCommand) -> None:
            with self.lock:
                verdict = self.core.set_desired(
                    Command(cmd.v_mps, cmd.omega_radps, source, cmd.stamp_ns,
                            cmd.stream_start_ns), time.monotonic(), time.time_ns())
            self.node.health.count(f"desired_{verdict.value}")
            if verdict is Verdict.TOOK_OVER:
                self.node.event("warning", f"pid: a {source} command stream begun later took "
                                           "over; the earlier one is refused from now on")

        return on_desired

    def on_owner(self, msg: CommandOwner) -> None:
        with self.lock:
            previous = self.core.owner
            ok = self.core.set_owner(msg.owner, time.time_ns())
        if not ok:
            self.node.health.count("rejected_owner")
        elif msg.owner != previous:
            self.node.event("warning", f"drive handed to {msg.owner} by {msg.by or '?'}: a "
                                       "stop; it drives again on a command begun after it")

    def on_limit(self, msg: SafetyLimit) -> None:
        with self.lock:
            ok = self.core.set_limit(msg.v_max_fwd_mps, msg.v_max_rev_mps,
                                     msg.omega_max_radps, time.monotonic(),
                                     msg.v_max_rev_autonomy_mps,
                                     (time.time_ns() - msg.stamp_ns) / 1e9)
        self.node.health.count("limits" if ok else "rejected_limits")

    def on_estop(self, msg: EStopState) -> None:
        with self.lock:
            ended = self.core.set_estop(msg.latched, time.monotonic(), time.time_ns())
        self.stopped(ended)

    def on_token(self, service: str) -> Callable[[bool], None]:
        def on_alive(alive: bool) -> None:
            if alive:
                return
            with self.lock:
                now_ns = time.time_ns()
                if service == "estop":
                    ended = self.core.estop_gone(now_ns)
                elif service == "safety":
                    ended = self.core.limit_gone(now_ns)
                else:
                    ended = self.core.stop(f"{service} lost", now_ns)
            if service == "odometry":  # no measurement will come to publish on: neutral now
                self.joy_pub.put(JoystickCommand(stamp_ns=time.time_ns(), longitudinal_v=2.5,
                                                 angular_v=2.5, enable=False))
            self.stopped(ended)

        return on_alive

    def on_odom(self, odom: Odometry) -> None:
        now, now_ns = time.monotonic(), time.time_ns()
        with self.lock:
            was = self.core.obeying
            out = self.core.update(odom.v_mps, odom.omega_radps, odom.sample_dt_s, now, now_ns,
                                   (odom.mcu_restarts, odom.link_epoch))
            inhibit = self.core.inhibit(now)
            ended = was and not self.core.obeying
            owner, command_age = self.core.owner, self.core.command_age_s
        self.stopped(ended)
        stamp = time.time_ns()
        self.joy_pub.put(JoystickCommand(stamp_ns=stamp, longitudinal_v=out.longitudinal_v,
                                         angular_v=out.angular_v, enable=out.active,
                                         source_seq=odom.source_seq))
        self.status_pub.put(PidStatus(
            stamp_ns=stamp, v_desired_mps=out.desired[0], v_measured_mps=odom.v_mps,
            v_effort=out.v_effort, omega_desired_radps=out.desired[1],
            omega_measured_radps=odom.omega_radps, omega_effort=out.omega_effort,
            active=out.active, saturated=out.saturated, inhibit=inhibit,
            command_age_s=round(command_age, 4)))
        self.node.health.count("updates")
        self.node.health.detail = f"owner {owner}: " + (
            f"tuning probe ({out.probe})" if out.probe else inhibit or "driving")

    def on_probe(self, req: PidProbeRequest) -> PidProbeReply:
        with self.lock:
            if req.action == "get":
                return PidProbeReply(**probe_reply(self.core.probe))  # type: ignore[arg-type]
            if req.action == "stop":
                self.core.stop_probe()
                return PidProbeReply(ok=True)
            if req.action != "start" or req.kind not in ("relay", "step"):
                return PidProbeReply(ok=False, error=f"bad action/kind {req.action}/{req.kind}")
            why = self.core.start_probe(Probe(
                ProbeKind(req.kind), req.axis, req.amplitude, req.hysteresis, req.duration_s,
                req.cycles, req.speed_bound), time.monotonic())
        if not why:
            self.node.event("warning", f"pid: {req.kind} probe on {req.axis} started")
        return PidProbeReply(ok=not why, error=why, state="running" if not why else "")


def start(node: Node, cfg: PidConfig) -> None:
    stale = node.stale
    try:
        core = make_core(cfg, stale_s=stale.desired_velocity_s, skew_s=stale.clock_skew_s,
                         limit_stale_s=stale.safety_limit_s, estop_stale_s=stale.estop_s,
                         odom_gap_s=stale.odometry_s, start_ns=time.time_ns())
    except ValueError as e:
        raise ConfigError(str(e)) from None
    node.health.thresholds.update(
        desired_velocity_s=stale.desired_velocity_s, safety_limit_s=stale.safety_limit_s,
        estop_s=stale.estop_s, odometry_s=stale.odometry_s, clock_skew_s=stale.clock_skew_s,
        v_max_fwd_mps=cfg.v_max_fwd_mps, v_max_rev_mps=cfg.v_max_rev_mps,
        omega_max_radps=cfg.omega_max_radps,
        require_safety_limit=float(cfg.require_safety_limit))
    w = PidWiring(node, core)
    node.health.detail = "owner autonomy: no odometry yet"
    node.subscribe(keys.CMD_VEL, w.desired_from("autonomy"))
    node.subscribe(keys.TELEOP, w.desired_from("teleop"))
    node.subscribe(keys.CMD_OWNER, w.on_owner)
    node.subscribe(keys.SAFETY_LIMIT, w.on_limit)
    node.subscribe(keys.ESTOP_STATE, w.on_estop)
    node.subscribe(keys.ODOM, w.on_odom)
    node.serve(keys.PID_PROBE, w.on_probe)
    # A killed service's token vanishes within milliseconds, sooner than any heartbeat.
    for service in ("estop", "gateway", "odometry", "safety"):
        node.watch_alive(service, w.on_token(service))


def main(argv: list[str] | None = None) -> int:
    return service_main("pid", PidConfig, start, argv, __doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
