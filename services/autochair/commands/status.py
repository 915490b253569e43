"""`autochair status`: the chairs on the network, their live services (Zenoh liveliness) and
their health."""

from __future__ import annotations

import argparse
import os
import threading
import time
from typing import TYPE_CHECKING, Any

from autochair.commands.link import add_link_args

if TYPE_CHECKING:
    from autochair_msgs import Health

NO_NAMESPACE = "(no namespace)"


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "status", help="list the chairs, their live services and their health",
        description="List the services whose liveliness token is up, with their latest health: "
                    "of every chair this hub carries (one without a namespace and each "
                    "NAME/autochair/...), or with --chair NAME of that chair only.")
    add_link_args(p)
    p.add_argument("--wait", type=float, default=1.5, help="seconds to gather health")
    p.add_argument("--json", action="store_true",
                   help="machine-readable output: {SERVICE or CHAIR/SERVICE: {chair, service, "
                   "alive, health}}")
    p.set_defaults(func=run)


def own_chair(args: argparse.Namespace) -> str:
    """The chair whose namespace the session is in ("" for none)."""
    from autochair.commands.link import chair_arg
    from autochair.runtime.config import ENV_CHAIR, ConfigError, load_section
    from autochair.runtime.config import ZenohSettings as Z

    chair = chair_arg(args)
    if chair is not None:
        return chair
    if os.environ.get(ENV_CHAIR):
        return os.environ[ENV_CHAIR]
    if args.zenoh_config:
        return ""
    try:
        return load_section(Z, "zenoh").namespace
    except ConfigError:
        return ""  # tool_session reports it


def run(args: argparse.Namespace) -> int:
    import msgspec

    from autochair.commands.link import tool_session
    from autochair.runtime.client import alive_chairs, subscribe_chairs
    from autochair_msgs import keys

    session = tool_session(args)
    own = own_chair(args)
    health: dict[tuple[str, str], Health] = {}
    lock = threading.Lock()

    def on_health(chair: str, h: Health) -> None:
        with lock:
            health[(chair or own, h.service)] = h

    try:
        subscribe_chairs(session, keys.HEALTH, on_health)
        alive = {(chair or own, name) for chair, names in alive_chairs(session).items()
                 for name in names}
        deadline = time.monotonic() + args.wait
        while time.monotonic() < deadline and not alive <= set(health):
            time.sleep(0.05)
    finally:
        session.close()
    with lock:
        seen = sorted(alive | set(health))
        if args.json:
            out = {(name if chair == own else f"{chair}/{name}"): {
                "chair": chair, "service": name, "alive": (chair, name) in alive,
                "health": health.get((chair, name))} for chair, name in seen}
            print(msgspec.json.encode(out).decode())
            return 0 if alive else 1
        if not seen:
            print("no autochair services are running" + (f" in chair {own}" if own else ""))
            return 1
        chairs = sorted({chair for chair, _ in seen})
        for i, chair in enumerate(chairs):
            if chairs != [""]:
                print(("\n" if i else "") + f"chair {chair or NO_NAMESPACE}: "
                      f"{sum(1 for c, _ in alive if c == chair)} services alive")
            print_table([(n, health.get((c, n)), (c, n) in alive) for c, n in seen
                         if c == chair])
    return 0


def print_table(rows: list[tuple[str, Health | None, bool]]) -> None:
    w = max([len("SERVICE"), *(len(n) for n, _, _ in rows)]) + 2  # e.g. "localization"
    print(f"{'SERVICE':<{w}}{'ALIVE':<7}{'STATE':<10}{'UPTIME':>8}  DETAIL")
    for n, h, alive in rows:
        if h is None:
            print(f"{n:<{w}}{'yes':<7}{'?':<10}{'':>8}  (no health yet)")
            continue
        busiest = sorted(h.rates_hz.items(), key=lambda kv: -kv[1])[:3]
        rates = " ".join(f"{k} {v:.0f}/s" for k, v in busiest if v > 0)
        detail = "; ".join(x for x in (h.detail, rates,
                                       f"last fault: {h.last_fault}" if h.last_fault else "")
                           if x)
        print(f"{n:<{w}}{'yes' if alive else 'NO':<7}{h.state:<10}"
              f"{h.uptime_s:>7.0f}s  {detail}")
