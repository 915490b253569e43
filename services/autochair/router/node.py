"""The Zenoh hub: a router session that every service connects to.

Peers (the drive chain, the recorder, the e-stop, the safety monitor) find each other through it
and then talk directly; clients (the simulators, the lidar, mapping, localization, control) have
one link, to the hub, which relays their data. No zenohd binary is needed.

Watched like every service: under a supervisor ($NOTIFY_SOCKET) a client session of this process
asks the hub's own queryable through the hub 4 × a second, and the hub pings the hung-process
watchdog only while that answers. A frozen hub, or one whose routing is stuck while the process
runs, cuts every client off (a stop, fail closed) and is restarted instead of staying so.
"""

from __future__ import annotations

import argparse
import logging
import sys
import threading

import zenoh

from autochair.runtime.client import answer_hub_probe, hub_answers
from autochair.runtime.config import ConfigError, ZenohSettings, load_section
from autochair.runtime.node import _install_signal_handlers, setup_logging, wait_for_stop
from autochair.runtime.session import client_settings, open_session
from autochair.runtime.watchdog import Notifier

PROBE_PERIOD_S = 0.25
# One lost probe leaves a gap of period + timeout + period = 1 s between pings, inside the
# supervisors' 1.5 s; two in a row is a restart.
PROBE_TIMEOUT_S = 0.5
log = logging.getLogger("router")


def probe_endpoint(listen: list[str]) -> str | None:
    """Where the hub's probe connects: its first TCP listener, on loopback (the ACL trusts TCP,
    which only the chair's own services reach)."""
    for endpoint in listen:
        proto, _, address = endpoint.partition("/")
        host, _, port = address.rpartition(":")
        if proto == "tcp" and port:
            return f"tcp/{'127.0.0.1' if host in ('0.0.0.0', '[::]', '') else host}:{port}"
    return None


def probe_loop(client: zenoh.Session, notifier: Notifier, stop: threading.Event) -> None:
    """READY=1 at the first answer, then WATCHDOG=1 after every answer, until `stop`."""
    ready = False
    while not stop.wait(PROBE_PERIOD_S):
        if hub_answers(client, PROBE_TIMEOUT_S):
            notifier.send("WATCHDOG=1" if ready else "READY=1\nWATCHDOG=1")
            ready = True


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="autochair-router", description=__doc__)
    parser.add_argument("--listen", default="tcp/127.0.0.1:7447",
                        help="endpoint(s) to listen on, comma-separated")
    parser.add_argument("--config", help="TOML config file; its [router] section is a Zenoh "
                        "settings table (e.g. config_file for TLS and access control)")
    args = parser.parse_args(argv)
    setup_logging()
    notifier = Notifier.from_env()
    try:
        settings = load_section(ZenohSettings, "router", args.config)
        settings.mode, settings.connect = "router", []
        settings.listen = [e.strip() for e in args.listen.split(",")] + [
            e for e in settings.listen if not e.endswith(":0")
        ]
        probe_at = probe_endpoint(settings.listen)
        if notifier is not None and probe_at is None:
            raise ConfigError("[router] a supervised hub needs a TCP listener for its "
                              f"watchdog probe; listening on {', '.join(settings.listen)}")
        session = open_session(settings)
    except ConfigError as e:
        print(f"autochair-router: error: {e}", file=sys.stderr)
        return 2
    stop = threading.Event()
    _install_signal_handlers(stop)
    log.info("listening on %s", ", ".join(settings.listen))
    answer_hub_probe(session)
    if notifier is not None and probe_at is not None:
        client = open_session(client_settings(probe_at, settings.namespace))
        threading.Thread(target=probe_loop, args=(client, notifier, stop), name="probe",
                         daemon=True).start()
    wait_for_stop(stop)
    session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
