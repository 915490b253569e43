"""A raw Zenoh relay for the baseline: republish every sample of KEY_IN on KEY_OUT unchanged."""

from __future__ import annotations

import sys
import threading

from autochair.runtime.config import load_zenoh
from autochair.runtime.node import _install_signal_handlers, wait_for_stop
from autochair.runtime.session import open_session


def main(argv: list[str]) -> int:
    key_in, key_out = argv
    session = open_session(load_zenoh())
    pub = session.declare_publisher(key_out, express=True)
    session.declare_subscriber(key_in, lambda s: pub.put(s.payload))
    stop = threading.Event()
    _install_signal_handlers(stop)
    print("relay ready", flush=True)
    wait_for_stop(stop)
    session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
