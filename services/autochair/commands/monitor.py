"""`autochair monitor`: a live terminal dashboard of the chair (works from a laptop over TLS)."""

from __future__ import annotations

import argparse
import sys
import threading
import time
from typing import Any


def register(sub: Any) -> None:
    from autochair.commands.link import add_link_args

    p: argparse.ArgumentParser = sub.add_parser(
        "monitor", help="live dashboard: services, health, pose, scan, faults",
        description="Services up/down (liveliness), their health, pose and velocities, a scan "
        "summary and recent faults, redrawn in place. Ctrl-C quits.")
    add_link_args(p)
    p.add_argument("--once", action="store_true", help="print one snapshot and exit")
    p.add_argument("--wait", type=float, default=1.5, help="seconds to gather before --once")
    p.add_argument("--period", type=float, default=0.5, help="redraw period, s")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from autochair import deploy
    from autochair.commands.link import tool_session
    from autochair.commands.monitor_core import MonitorState
    from autochair.runtime.client import subscribe, watch_alive
    from autochair_msgs import keys

    session = tool_session(args)
    state = MonitorState([p.name for p in deploy.deployed()])
    lock = threading.Lock()
    bad = [0]

    def locked(apply: Any) -> Any:
        def on(msg: Any) -> None:
            with lock:
                apply(msg)
        return on

    def on_bad() -> None:
        bad[0] += 1  # shown in the footer: a wrong-version peer, not silence

    def on_alive(name: str, alive: bool) -> None:
        with lock:
            state.on_alive(name, alive)

    now = time.monotonic
    watch_alive(session, on_alive)
    for topic, apply in ((keys.HEALTH, lambda m: state.on_health(m, now())),
                         (keys.ODOM_SLOW, lambda m: state.on_odom(m, now())),
                         (keys.SCAN, lambda m: state.on_scan(m, now())),
                         (keys.LOG, state.on_log)):
        subscribe(session, topic, locked(apply), on_error=on_bad)
    try:
        if args.once:
            time.sleep(args.wait)  # gathering window for a snapshot, not synchronisation
            with lock:
                print(state.render(now()))
            return 0
        while True:
            with lock:
                text = state.render(now())
            footer = f"\n\n{time.strftime('%H:%M:%S')}  undecodable samples: {bad[0]}  Ctrl-C quits"
            sys.stdout.write("\x1b[H\x1b[2J" + text + footer + "\n")
            sys.stdout.flush()
            time.sleep(args.period)
    finally:
        session.close()
