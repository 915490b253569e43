"""The one list of processes. `autochair up`, deploy/ (compose, supervisor, systemd) and the
tests are all made from, or checked against, this list.

`args` may use placeholders filled in by whoever launches: {run_dir} (a per-run directory for
pty links and recordings), {hub} (the hub endpoint) and {hub_port}.
{record_path}: where the logger records (a directory, default `recordings/`, gets one
autochair-<UTC time>.mcap per run; a path ending in .mcap is that file).
{lidar_url}: the lidar the ingest reads: a serial device (e.g. /dev/ttyACM0), a pty path
(with --sim: {run_dir}/lidar, the simulated URG-04LX) or tcp://HOST:PORT (UST/UTM class).
{state_dir}: state that must outlive any run (the e-stop latch): a FIXED directory, so `up`,
supervisord and systemd restarts keep the latch.
{safety_required}: "true" whenever the stack runs the safety monitor (see `stack_values`), so
a dead monitor stops the chair instead of leaving it unlimited.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal


@dataclass(frozen=True)
class Process:
    name: str  # also the service name (liveliness token, health key, config section)
    module: str  # run as `python -m module`
    script: str  # console script of the same
    args: tuple[str, ...] = ()
    sim_only: bool = False  # only with --sim (the simulated hardware)
    hardware: tuple[str, ...] = ()  # devices it owns on a real chair
    doc: str = ""
    after: tuple[str, ...] = field(default=("router",))  # start after these are up
    # How the launcher knows it is up: its liveliness token, or (the hub itself, which every
    # token travels through) its listening port.
    ready: Literal["token", "hub_port"] = "token"


# A Zenoh client: one link, to the hub, instead of one to every peer, each with a keepalive
# every 250 ms (runtime.node.zenoh_settings: measured, 12 idle peers 15 % of a core, as clients
# 2 % plus 1 % for the hub). For services whose traffic is light and not latency-bound (10 Hz
# scans, 20 Hz commands, maps, the simulators); the 100 Hz drive chain (gateway, odometry,
# pid), the logger, the e-stop and the safety monitor stay peers, talking directly.
CLIENT = ("--zenoh-mode", "client")

PROCESSES: tuple[Process, ...] = (
    Process("router", "autochair.router.node", "autochair-router",
            ("--listen", "{hub}"), after=(), ready="hub_port", doc="Zenoh hub for discovery"),
    Process("estop", "autochair.estop.node", "autochair-estop",
            ("--set", "state_file={state_dir}/estop.json"),
            doc="E-stop latch; the gateway holds neutral while latched or silent"),
    Process("sim", "autochair.sim.chair.node", "autochair-sim",
            ("--set", "pty_link={run_dir}/arduino", *CLIENT), sim_only=True,
            doc="Simulated chair + Arduino on a pty"),
    Process("gateway", "autochair.gateway.node", "autochair-gateway",
            ("--set", "port={serial_port}"), hardware=("serial",),
            doc="Serial link to the Arduino: encoders in, joystick out"),
    Process("odometry", "autochair.odometry.node", "autochair-odometry",
            doc="Encoder counts to pose and velocity"),
    Process("pid", "autochair.pid.node", "autochair-pid",
            ("--set", "require_safety_limit={safety_required}"),
            doc="Velocity PID: desired (v, ω) to joystick voltages"),
    Process("control", "autochair.control.node", "autochair-control", CLIENT,
            doc="Smooth control law: goals and waypoints to comfort-limited (v, ω)"),
    Process("logger", "autochair.logger.node", "autochair-logger",
            ("--set", "path={record_path}"), doc="Records every logged key to MCAP"),
    Process("lidar-sim", "autochair.sim.lidar.node", "autochair-lidar-sim",
            ("--set", "pty_link={run_dir}/lidar", *CLIENT), sim_only=True,
            doc="Simulated Hokuyo URG-04LX (SCIP 2.0) on a pty, seeing the hallway world"),
    Process("lidar", "autochair.lidar.node", "autochair-lidar",
            ("--set", "url={lidar_url}", *CLIENT), hardware=("lidar",),
            doc="Hokuyo SCIP 2.0 ingest: checked, stamped scans and the chair→laser transform"),
    Process("mapping", "autochair.mapping.node", "autochair-mapping", CLIENT,
            doc="Occupancy grid and point-cloud map from scans and odometry"),
    Process("localization", "autochair.localization.node", "autochair-localization",
            ("--set", "maps_dir={state_dir}/maps", *CLIENT),
            doc="Scan matching on the map fused with odometry (map → odom); maps with loop "
                "closure when started without --map"),
    Process("safety", "autochair.safety.node", "autochair-safety",
            doc="Safety monitor: slows then stops before obstacles in the laser scan "
                "(SafetyLimit)"),
)


def by_name(name: str) -> Process:
    for p in PROCESSES:
        if p.name == name:
            return p
    raise KeyError(name)


def local_values(run_dir: Path, hub: str, **overrides: str) -> dict[str, str]:
    """Placeholder values for a stack on this machine: the simulators' ptys in `run_dir`,
    recordings and state there too, unless `overrides` (e.g. serial_port=/dev/ttyACM0,
    state_dir=...) say otherwise. `autochair up` passes its fixed state directory."""
    return {"run_dir": str(run_dir), "hub": hub, "hub_port": hub.rsplit(":", 1)[-1],
            "serial_port": str(run_dir / "arduino"), "lidar_url": str(run_dir / "lidar"),
            "record_path": str(run_dir), "state_dir": str(run_dir), **overrides}


def stack_values(procs: list[Process], values: dict[str, str]) -> dict[str, str]:
    """`values` plus what follows from the selection itself: a stack that runs the safety
    monitor always requires its limit (fail closed; not left to a config file)."""
    running = {p.name for p in procs}
    return {**values, "safety_required": "true" if "safety" in running else "false"}


def with_needs(procs: list[Process], names: set[str]) -> list[Process]:
    """The processes of `procs` named in `names` and those they need to start (`after`,
    transitively, e.g. the hub), in list order."""
    by = {p.name: p for p in procs}
    todo, keep = list(names), set()
    while todo:
        name = todo.pop()
        if name in by and name not in keep:
            keep.add(name)
            todo.extend(by[name].after)
    return [p for p in procs if p.name in keep]


def selected(sim: bool) -> list[Process]:
    return [p for p in PROCESSES if sim or not p.sim_only]
