"""`autochair foxglove`: a live Foxglove WebSocket bridge (foxglove-sdk) of the chair.

Serves on 127.0.0.1:8765 by default (open Foxglove, "Open connection", ws://127.0.0.1:8765).
Channels: the well-known /tf, /pose, /scan, /map, /log (foxglove.* JSON, converted by the
logger's autochair.logger.foxglove.Deriver, so recordings and the live view match) and, for the
Plot panel, the raw autochair messages as JSON on their Zenoh key names (odometry, PID status,
health). The SDK's server speaks the subprotocol `foxglove.sdk.v1`.
"""

from __future__ import annotations

import argparse
import json
import threading
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import zenoh

# Zenoh rows bridged as raw JSON for plots (besides the derived foxglove.* channels).
PLOT_KEYS = ("ODOM", "PID_STATUS", "HEALTH", "GOAL_STATUS")
DERIVED_KEYS = ("TF", "TF_STATIC", "ODOM", "SCAN", "MAP_GRID", "LOG", "HEALTH")


def register(sub: Any) -> None:
    from autochair.remote import add_link_args

    p: argparse.ArgumentParser = sub.add_parser(
        "foxglove", help="live Foxglove WebSocket bridge (pose, tf, scan, map, plots)",
        description=__doc__)
    add_link_args(p)
    p.add_argument("--host", default="127.0.0.1", help="address to serve on")
    p.add_argument("--port", type=int, default=8765, help="WebSocket port")
    p.set_defaults(func=run)


class Bridge:
    """Zenoh subscriptions -> Foxglove channels. Callbacks only convert and log (non-blocking)."""

    def __init__(self, session: zenoh.Session) -> None:
        import foxglove
        import msgspec

        from autochair.logger import foxglove as fx
        from autochair.logger.schema import Codec, to_json
        from autochair_msgs import keys

        self._deriver = fx.Deriver()
        self._lock = threading.Lock()  # the Deriver keeps state (last fault per service)
        self.errors = 0
        self.sent = 0
        self._derived = {
            topic: foxglove.Channel(topic, message_encoding="json", schema=foxglove.Schema(
                name=name, encoding="jsonschema", data=json.dumps(fx.SCHEMAS[name]).encode()))
            for topic, name in fx.DERIVED.items()}
        self._plots: dict[str, Any] = {}
        rows = {name: getattr(keys, name) for name in {*PLOT_KEYS, *DERIVED_KEYS}}
        for name, row in rows.items():
            codec = Codec(row.type)
            plot = None
            if name in PLOT_KEYS:
                plot = foxglove.Channel(row.key.replace("/*", ""), message_encoding="json",
                                        schema=foxglove.Schema(name=codec.name,
                                                               encoding="jsonschema",
                                                               data=codec.schema))
            session.declare_subscriber(row.key, self._handler(
                row.key, msgspec.msgpack.Decoder(row.type), plot, name in DERIVED_KEYS,
                to_json))

    def _handler(self, key: str, dec: Any, plot: Any, derive: bool, to_json: Any) -> Any:
        import msgspec

        def on(sample: zenoh.Sample) -> None:
            try:
                msg = dec.decode(sample.payload.to_bytes())
            except (msgspec.DecodeError, msgspec.ValidationError):
                self.errors += 1
                return
            stamp = getattr(msg, "stamp_ns", None)
            if plot is not None:
                plot.log(to_json(msg), log_time=stamp)
            if derive:
                with self._lock:
                    out = self._deriver.derive(key, msg)
                for topic, ns, body in out:
                    self._derived[topic].log(json.dumps(body).encode(), log_time=ns)
                    self.sent += 1

        return on


def run(args: argparse.Namespace) -> int:
    import foxglove

    from autochair.cli import CliError
    from autochair.remote import open_session
    from autochair.runtime.node import wait_for_stop

    session = open_session(args)
    try:
        Bridge(session)
        try:
            server = foxglove.start_server(name="autochair", host=args.host, port=args.port)
        except Exception as e:  # e.g. port in use: one line for the user
            raise CliError(f"cannot serve on {args.host}:{args.port}: {e}") from None
        print(f"Foxglove bridge on ws://{args.host}:{server.port} (Ctrl-C quits)", flush=True)
        wait_for_stop(threading.Event())  # until Ctrl-C (KeyboardInterrupt)
        return 0
    finally:
        session.close()
