"""`autochair drive V W [--for S]`: command a velocity and watch the chair follow it."""

from __future__ import annotations

import argparse
import threading
import time
from typing import Any

from autochair.cli import CliError
from autochair.commands.link import add_link_args

MAX_V, MAX_W = 2.0, 2.0


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "drive", help="command a velocity (m/s, rad/s)",
        description="Publish a desired velocity to the velocity PID at 20 Hz and show the "
                    "measured one. Stops (v = ω = 0) at the end or on Ctrl-C.")
    p.add_argument("v", type=float, help="forward speed, m/s (negative: backwards)")
    p.add_argument("w", type=float, help="turn rate, rad/s (positive: left)")
    p.add_argument("--for", dest="duration", type=float, default=None, metavar="S",
                   help="seconds to drive (default: until Ctrl-C)")
    p.add_argument("--rate", type=float, default=20.0, help="publish rate, Hz")
    add_link_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from autochair.commands.link import tool_session
    from autochair.runtime.client import (
        Publisher,
        alive_services,
        pid_caps,
        pid_hold,
        subscribe,
    )
    from autochair_msgs import Odometry, PidStatus, VelocityCommand, keys

    if abs(args.v) > MAX_V or abs(args.w) > MAX_W:
        raise CliError(f"|v| must be ≤ {MAX_V} m/s and |w| ≤ {MAX_W} rad/s")
    if args.duration is not None and args.duration <= 0:
        raise CliError("--for must be > 0 seconds")
    if not 1 <= args.rate <= 200:
        raise CliError("--rate must be within 1–200 Hz")
    session = tool_session(args)
    try:
        if "pid" not in alive_services(session):
            print("warning: no velocity PID is running (see `autochair status`)", flush=True)
        else:
            caps = pid_caps(session)
            if caps is not None:
                fwd, rev, w = caps
                if not (-rev <= args.v <= fwd and abs(args.w) <= w):
                    raise CliError(f"beyond the velocity PID's caps: v within [-{rev:g}, "
                                   f"{fwd:g}] m/s and |w| ≤ {w:g} rad/s ([pid] in the config)")
        pub = Publisher(session, keys.CMD_VEL)
        latest: list[Odometry] = []
        lock = threading.Lock()

        def on_odom(msg: Odometry) -> None:
            with lock:
                latest[:] = [msg]

        subscribe(session, keys.ODOM_SLOW, on_odom)
        # This command is the deliberate act: the PID obeys it only if it began after any
        # stop (an e-stop, a restart, ...); an old `drive` that simply goes on is refused.
        stream_start = time.time_ns()
        # Why the PID obeys nothing now (an e-stop, a stop before this drive began, no safety
        # limit, ...): a chair that stands still must say why, not just read v 0.
        held: list[str] = [""]

        def on_pid(msg: PidStatus) -> None:
            held[0] = pid_hold(msg.inhibit, msg.stamp_ns, stream_start)

        subscribe(session, keys.PID_STATUS, on_pid)

        def send(v: float, w: float) -> None:
            pub.put(VelocityCommand(stamp_ns=time.time_ns(), v_mps=v, omega_radps=w,
                                    source="cli", stream_start_ns=stream_start))

        start = time.monotonic()
        next_print = start
        try:
            while args.duration is None or time.monotonic() - start < args.duration:
                send(args.v, args.w)
                now = time.monotonic()
                if now >= next_print:
                    with lock:
                        o = latest[0] if latest else None
                    meas = (f"v {o.v_mps:+.3f} m/s  ω {o.omega_radps:+.3f} rad/s  "
                            f"pose ({o.x_m:+.2f}, {o.y_m:+.2f}, {o.yaw_rad:+.2f})"
                            if o else "no odometry yet")
                    why = f"  | held by the PID: {held[0]}" if held[0] else ""
                    print(f"t {now - start:5.1f} s  want v {args.v:+.3f} ω {args.w:+.3f}  "
                          f"| {meas}{why}", flush=True)
                    next_print += 0.5
                time.sleep(1.0 / args.rate)
        except KeyboardInterrupt:
            pass
        for _ in range(10):  # an explicit stop, not just silence
            send(0.0, 0.0)
            time.sleep(0.05)
        print("stopped", flush=True)
    finally:
        session.close()
    return 0
