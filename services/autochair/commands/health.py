"""`autochair health --service NAME`: one service's own health, as a check command.

Exit 0 only when the service's liveliness token is up AND a fresh Health of its own says
`ok` or `degraded`; otherwise 1. One line of output either way. docker-compose's healthchecks
run it (deploy/docker-compose.yml); anyone may run it by hand. The router is not a Node (no
token, no Health): for it, the hub accepting a session is the health.
"""

from __future__ import annotations

import argparse
import threading
import time
from typing import Any

from autochair.commands.link import add_link_args

HEALTHY = ("ok", "degraded")


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "health", help="check one service's health (exit 0 if ok/degraded and alive)",
        description="Exit 0 only if SERVICE's liveliness token is up and a fresh Health from "
                    "it says ok or degraded; print one line. For container healthchecks.")
    p.add_argument("--service", required=True, metavar="NAME",
                   help="service name as in the process list (router: the hub answers)")
    p.add_argument("--timeout", type=float, default=3.0,
                   help="seconds to wait for a fresh Health (it comes once a second)")
    p.add_argument("--max-age", type=float, default=3.0,
                   help="a Health older than this (s, by its stamp) is not fresh")
    add_link_args(p)
    p.set_defaults(func=run)


def check(session: Any, service: str, timeout_s: float, max_age_s: float) -> tuple[bool, str]:
    """(healthy, one line) for `service` over an open session."""
    from autochair.runtime.client import alive_services, subscribe
    from autochair_msgs import Health, keys

    got: list[Health] = []
    fresh = threading.Event()

    def on_health(h: Health) -> None:
        if h.service == service and time.time_ns() - h.stamp_ns <= max_age_s * 1e9:
            got[:] = [h]
            fresh.set()

    sub = subscribe(session, keys.HEALTH, on_health, keys.HEALTH.for_service(service))
    try:
        alive = service in alive_services(session, timeout_s=min(1.0, timeout_s))
        fresh.wait(timeout_s)
    finally:
        sub.undeclare()
    if not alive:
        return False, f"{service}: not alive (no liveliness token)"
    if not got:
        return False, f"{service}: alive but no fresh health within {timeout_s:g} s"
    h = got[0]
    detail = h.detail or h.last_fault
    line = f"{service}: {h.state}, up {h.uptime_s:.0f} s" + (f"; {detail}" if detail else "")
    return h.state in HEALTHY, line


def run(args: argparse.Namespace) -> int:
    from autochair.cli import CliError
    from autochair.commands.link import tool_session

    try:
        session = tool_session(args, timeout_ms=int(min(args.timeout, 5.0) * 1000))
    except CliError as e:
        print(f"{args.service}: {e}", flush=True)
        return 1
    try:
        if args.service == "router":
            print("router: the hub accepts sessions", flush=True)
            return 0
        ok, line = check(session, args.service, args.timeout, args.max_age)
    finally:
        session.close()
    print(line, flush=True)
    return 0 if ok else 1
