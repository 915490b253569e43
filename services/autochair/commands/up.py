"""`autochair up`: start the stack from the one process list, show it, stop it cleanly."""

from __future__ import annotations

import argparse
import dataclasses
import os
import signal
import threading
import time
from pathlib import Path
from typing import Any

from autochair.cli import CliError
from autochair.commands.link import add_chair_arg

DEFAULT_RECORD_DIR = "recordings"


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "up", help="start the stack (--sim: with the simulated chair)",
        description="Start every process of the stack, show their state, and stop them all "
                    "cleanly on Ctrl-C or SIGTERM.")
    p.add_argument("--sim", action="store_true", help="run the simulated chair and lidar")
    p.add_argument("--port", help="serial device of the chair's Arduino (without --sim)")
    p.add_argument("--lidar", help="lidar device or tcp://host:port (without --sim)")
    p.add_argument("--record", metavar="PATH",
                   help=f"record the run to PATH (file or dir; default {DEFAULT_RECORD_DIR}/, "
                   f"with --chair NAME {DEFAULT_RECORD_DIR}/NAME/)")
    p.add_argument("--no-record", action="store_true", help="do not run the logger")
    p.add_argument("--map", metavar="NAME",
                   help="localize on map NAME of the state directory's maps/ (saved by "
                   "`autochair map save NAME`); default: build a map while driving")
    p.add_argument("--keepout", metavar="NAME",
                   help="keep-out zones (stairs down, kerbs, glass: what the laser cannot see) "
                   "from mask map NAME of maps/, drawn over the --map; the safety monitor stops "
                   "the chair at them, and everywhere while localization cannot place them; "
                   "navigation plans round them")
    p.add_argument("--hub", default="tcp/127.0.0.1:7447", help="Zenoh endpoint of the hub")
    add_chair_arg(p, "run the stack as chair NAME (every process gets $AUTOCHAIR_CHAIR)")
    p.add_argument("--join", action="store_true",
                   help="use the hub already running at --hub (e.g. another chair's) instead "
                   "of starting one: with --chair, two chairs share one network")
    p.add_argument("--config", help="TOML config file for every service")
    p.add_argument("--only", help="comma-separated subset of processes to run")
    p.add_argument("--run-dir", help="directory for pty links and logs (default: a temp dir)")
    p.add_argument("--no-restart", action="store_true", help="do not restart exited processes")
    p.add_argument("--state-dir",
                   help=f"state kept across runs, e.g. the e-stop latch (default "
                   f"{default_state_dir()}, with --chair NAME its NAME/)")
    p.set_defaults(func=run)


def default_state_dir() -> str:
    """A fixed place (XDG state dir), not the per-run temp dir: the latch survives restarts."""
    base = os.environ.get("XDG_STATE_HOME") or os.path.expanduser("~/.local/state")
    return os.path.join(base, "autochair")


def chair_env(args: argparse.Namespace) -> tuple[str, dict[str, str]]:
    """The stack's chair ("" for none: --chair, else $AUTOCHAIR_CHAIR, else [zenoh] namespace
    of the config) and the environment that gives it, and the config, to every process."""
    from autochair.runtime.config import ENV_CHAIR, ENV_CONFIG, ConfigError, chair_in, check_chair

    env = {ENV_CONFIG: str(Path(args.config).resolve())} if args.config else {}
    try:
        if args.chair:
            env[ENV_CHAIR] = check_chair(args.chair)
        return chair_in({**os.environ, **env}), env
    except ConfigError as e:
        raise CliError(str(e)) from None


def _is_url(port: str) -> bool:
    return "://" in port


def run(args: argparse.Namespace) -> int:
    from autochair import processes
    from autochair.launcher import Child, Launcher

    if not args.sim and not args.port:
        raise CliError("give --port DEVICE (the chair's Arduino), or --sim for the simulator")
    if args.port and not _is_url(args.port) and not os.path.exists(args.port):
        raise CliError(f"serial port {args.port} not found (is the Arduino plugged in?)")
    if args.config and not os.path.exists(args.config):
        raise CliError(f"config file not found: {args.config}")
    chair, env = chair_env(args)
    procs = processes.selected(sim=args.sim)
    if args.no_record:
        procs = [p for p in procs if p.name != "logger"]
    if not args.sim and not args.lidar:
        procs = [p for p in procs if p.name != "lidar"]
    if args.only:
        wanted = {n.strip() for n in args.only.split(",")}
        unknown = wanted - {p.name for p in processes.PROCESSES}
        if unknown:
            raise CliError(f"unknown process(es): {', '.join(sorted(unknown))}; known: "
                           f"{', '.join(p.name for p in processes.PROCESSES)}")
        procs = processes.with_needs(procs, wanted)
    import tempfile

    from autochair.launcher import wait_port

    hub = args.hub
    host, _, port = hub.partition("/")[2].rpartition(":")
    if not (host and port.isdigit()):
        raise CliError(f"--hub must look like tcp/127.0.0.1:7447, not {hub!r}")
    if args.join:
        procs = [p for p in procs if p.ready != "hub_port"]
        if not wait_port(host, int(port), 0.5):
            raise CliError(f"--join: no hub listens on {hub} (start one with `autochair up`)")
    elif wait_port(host, int(port), 0.2):
        raise CliError(f"something already listens on {hub}: is another `autochair up` running? "
                       "(`autochair status`; another chair on it: --join --chair NAME; or "
                       "pick another --hub)")

    run_dir = Path(args.run_dir or tempfile.mkdtemp(prefix="autochair-"))
    devices = {"serial_port": args.port, "lidar_url": args.lidar}
    state_dir = Path(args.state_dir or os.path.join(default_state_dir(), chair)).resolve()
    try:
        state_dir.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise CliError(f"cannot create the state directory {state_dir}: {e}") from None
    if args.keepout and not args.map:
        raise CliError("--keepout needs --map: the zones are placed by localization on that map")
    maps = state_dir / "maps"
    mask = f"keepout_map={maps / f'{args.keepout}.yaml'}"
    for name, what, settings in ((args.map, "map", {"localization": f"map={args.map}"}),
                                 (args.keepout, "mask", {"safety": mask, "mapping": mask})):
        if not name:
            continue
        if not (maps / f"{name}.yaml").exists():
            known = sorted(f.stem for f in maps.glob("*.yaml")) if maps.is_dir() else []
            raise CliError(f"no {what} {name!r} in {maps} (known: {', '.join(known) or 'none'};"
                           " save one with `autochair map save NAME`)")
        procs = [dataclasses.replace(p, args=(*p.args, "--set", settings[p.name]))
                 if p.name in settings else p for p in procs]
    if args.keepout:
        _check_mask(maps / f"{args.keepout}.yaml", maps / f"{args.map}.yaml")
    record = args.record or os.path.join(DEFAULT_RECORD_DIR, chair)
    values = processes.local_values(run_dir, hub, record_path=str(Path(record).resolve()),
                                    state_dir=str(state_dir),
                                    **{k: v for k, v in devices.items() if v})

    def show(child: Child) -> None:
        extra = ""
        if child.state in ("restarting", "exited") and child.exit_code is not None:
            extra = f" (exit {child.exit_code}; log {child.log_path})"
        elif child.state == "stopped" and child.killed:
            extra = f" (killed: did not stop within 5 s; log {child.log_path})"
        elif child.state == "stopped" and child.exit_code not in (0, -signal.SIGTERM, None):
            extra = f" (exit {child.exit_code}; log {child.log_path})"
        pid = f"pid {child.popen.pid}" if child.popen else ""
        print(f"{time.strftime('%H:%M:%S')}  {child.proc.name:<10} {child.state:<10} {pid}{extra}",
              flush=True)

    launcher = Launcher(procs, values, run_dir, restart=not args.no_restart, env=env,
                        on_change=show)
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    print(f"autochair: starting {len(procs)} processes (logs in {run_dir})", flush=True)
    try:
        launcher.start()
    except TimeoutError as e:
        launcher.stop()
        raise CliError(str(e)) from None
    on = f" --chair {chair}" if chair else ""
    print(f"autochair: all up{f' as chair {chair}' if chair else ''}. Hub {hub}. Try "
          f"`autochair drive 0.5 0 --for 3{on}` or `autochair status`. Ctrl-C stops.",
          flush=True)
    while not stop.wait(0.1):
        launcher.poll()
    print("autochair: stopping ...", flush=True)
    clean = launcher.stop()
    print("autochair: stopped" + ("" if clean else " (some processes had to be killed)"),
          flush=True)
    return 0 if clean else 1


def _check_mask(mask_path: Path, map_path: Path) -> None:
    """Refuse at once a mask not drawn over the map (the safety monitor would stop the chair
    for it anyway, H42; this says why before anything starts)."""
    from autochair.mapping.mapfile import MapFileError, load_map
    from autochair.safety.keepout import mask_mismatch

    try:
        why = mask_mismatch(load_map(mask_path), load_map(map_path))
    except MapFileError as e:
        raise CliError(str(e)) from None
    if why:
        raise CliError(f"--keepout {mask_path.stem} does not fit --map {map_path.stem}: {why}")
