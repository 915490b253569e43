"""The Zenoh hub: a router session that every service connects to for discovery.

Peers then open direct links to each other (gossip), so the hub is not on the data path.
No zenohd binary is needed.
"""

from __future__ import annotations

import argparse
import logging
import sys
import threading

from autochair.runtime.config import ConfigError, ZenohSettings, load_section
from autochair.runtime.node import _install_signal_handlers, setup_logging, wait_for_stop
from autochair.runtime.session import open_session


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="autochair-router", description=__doc__)
    parser.add_argument("--listen", default="tcp/127.0.0.1:7447",
                        help="endpoint(s) to listen on, comma-separated")
    parser.add_argument("--config", help="TOML config file; its [router] section is a Zenoh "
                        "settings table (e.g. config_file for TLS and access control)")
    args = parser.parse_args(argv)
    setup_logging()
    try:
        settings = load_section(ZenohSettings, "router", args.config)
        settings.mode, settings.connect = "router", []
        settings.listen = [e.strip() for e in args.listen.split(",")] + [
            e for e in settings.listen if not e.endswith(":0")
        ]
        session = open_session(settings)
    except ConfigError as e:
        print(f"autochair-router: error: {e}", file=sys.stderr)
        return 2
    stop = threading.Event()
    _install_signal_handlers(stop)
    logging.getLogger("router").info("listening on %s", ", ".join(settings.listen))
    wait_for_stop(stop)
    session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
