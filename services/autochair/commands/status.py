"""`autochair status`: the live services (Zenoh liveliness) with their health."""

from __future__ import annotations

import argparse
import threading
import time
from typing import Any

from autochair.remote import add_link_args


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "status", help="list live services and their health",
        description="List the services whose liveliness token is up, with their latest health.")
    add_link_args(p)
    p.add_argument("--wait", type=float, default=1.5, help="seconds to gather health")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import msgspec

    from autochair.remote import open_session
    from autochair.runtime.client import alive_services, subscribe
    from autochair_msgs import Health, keys

    session = open_session(args)
    health: dict[str, Health] = {}
    lock = threading.Lock()

    def on_health(h: Health) -> None:
        with lock:
            health[h.service] = h

    try:
        subscribe(session, keys.HEALTH, on_health)
        alive = alive_services(session)
        deadline = time.monotonic() + args.wait
        while time.monotonic() < deadline and not alive <= set(health):
            time.sleep(0.05)
    finally:
        session.close()
    with lock:
        names = sorted(alive | set(health))
        if args.json:
            out = {n: {"alive": n in alive, "health": health.get(n)} for n in names}
            print(msgspec.json.encode(out).decode())
            return 0 if alive else 1
        if not names:
            print("no autochair services are running")
            return 1
        print(f"{'SERVICE':<12}{'ALIVE':<7}{'STATE':<10}{'UPTIME':>8}  DETAIL")
        for n in names:
            h = health.get(n)
            if h is None:
                print(f"{n:<12}{'yes':<7}{'?':<10}{'':>8}  (no health yet)")
                continue
            busiest = sorted(h.rates_hz.items(), key=lambda kv: -kv[1])[:3]
            rates = " ".join(f"{k} {v:.0f}/s" for k, v in busiest if v > 0)
            detail = "; ".join(x for x in (h.detail, rates,
                                           f"last fault: {h.last_fault}" if h.last_fault else "")
                               if x)
            print(f"{n:<12}{'yes' if n in alive else 'NO':<7}{h.state:<10}"
                  f"{h.uptime_s:>7.0f}s  {detail}")
    return 0
