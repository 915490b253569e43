"""`autochair foxglove`: a live Foxglove WebSocket bridge (foxglove-sdk) of the chair.

Serves on 127.0.0.1:8765 by default (open Foxglove, "Open connection", ws://127.0.0.1:8765).
Channels: the well-known /map, /log (foxglove.* JSON, converted by the logger's
autochair.logger.foxglove.Deriver, so recordings and the live view match) and the raw
autochair messages as JSON on their Zenoh key names, as recorded, for the Plot panel
(odometry, PID status, health) and the 3D panel (`autochair/lidar/scan`, a foxglove.LaserScan;
`autochair/tf` and `autochair/tf_static`, foxglove.FrameTransform).
The SDK's server speaks the subprotocol `foxglove.sdk.v1`.

Teleop: Foxglove's Teleop panel drives the chair. Set its topic to `autochair/cmd/teleop` and
its publish rate to 20 Hz (anything over 1/deadman_s, 5 Hz; a panel left at a low rate such as
1 Hz never drives); --take-over (or {"owner": "teleop"} published on `autochair/cmd/owner`,
e.g. from a Publish panel) hands the drive to teleop. The panel's geometry_msgs/Twist (JSON:
linear.x m/s, angular.z rad/s) goes through the same teleop core as `autochair teleop`: the
[teleop] caps, the ramp, and the deadman: the chair drives while the panel publishes (a hold
begins on its second message) and stops `deadman_s` after it stops. The bridge publishes with
its own Zenoh identity, so the chair's hub refuses the commands of a view-only laptop.
"""

from __future__ import annotations

import argparse
import json
import threading
from typing import TYPE_CHECKING, Any, cast

if TYPE_CHECKING:
    import zenoh
    from foxglove.websocket import ServerListener

    from autochair.commands.teleop_core import TeleopConfig

# Zenoh rows bridged as they are recorded (plots; scans and transforms for the 3D panel).
PLOT_KEYS = ("ODOM", "PID_STATUS", "HEALTH", "GOAL_STATUS", "SCAN", "TF", "TF_STATIC")
DERIVED_KEYS = ("MAP_GRID", "LOG", "HEALTH")
TELEOP_TOPIC = "autochair/cmd/teleop"  # the Teleop panel's topic (client publishing)
OWNER_TOPIC = "autochair/cmd/owner"  # {"owner": "teleop" | "autonomy"}: take over, hand back


def register(sub: Any) -> None:
    from autochair.commands.link import add_link_args

    p: argparse.ArgumentParser = sub.add_parser(
        "foxglove", help="live Foxglove WebSocket bridge (pose, tf, scan, map, plots)",
        description=__doc__)
    add_link_args(p)
    p.add_argument("--host", default="127.0.0.1", help="address to serve on")
    p.add_argument("--port", type=int, default=8765, help="WebSocket port")
    p.add_argument("--teleop-topic", default=TELEOP_TOPIC,
                   help="topic of Foxglove's Teleop panel (its publish rate: 20 Hz)")
    p.add_argument("--no-teleop", action="store_true", help="view only: refuse client publishing")
    p.add_argument("--take-over", action="store_true",
                   help="hand the drive to teleop at start (as `autochair teleop` `t`)")
    from autochair.commands.teleop import add_teleop_args

    add_teleop_args(p)
    p.set_defaults(func=run)


class Bridge:
    """Zenoh subscriptions -> Foxglove channels. Callbacks only convert and log (non-blocking)."""

    def __init__(self, session: zenoh.Session) -> None:
        import foxglove

        from autochair.logger import foxglove as fx
        from autochair.logger.schema import codec_for
        from autochair.runtime.client import subscribe
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
            codec = codec_for(row.type)
            plot = None
            if name in PLOT_KEYS:
                plot = foxglove.Channel(row.key.replace("/*", ""), message_encoding="json",
                                        schema=foxglove.Schema(name=codec.name,
                                                               encoding="jsonschema",
                                                               data=codec.schema))
            subscribe(session, row, self._handler(row.key, plot, name in DERIVED_KEYS,
                                                 codec.encode_json),
                      on_error=self._bad)

    def _bad(self) -> None:
        self.errors += 1

    def _handler(self, key: str, plot: Any, derive: bool, to_json: Any) -> Any:
        def on(msg: Any) -> None:
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


class PanelTeleop:
    """Foxglove's Teleop panel -> the teleop core -> keys.TELEOP (a foxglove ServerListener).

    Each client's channel on the teleop topic is one input source (`Teleop.message`): live
    from its second message within the deadman, stopped when its messages stop or it is
    unadvertised. A fixed-rate loop (`run`) publishes what the core decides, like
    `autochair teleop`; the SDK's callbacks only convert and hand over under a lock.
    """

    def __init__(self, session: zenoh.Session, cfg: TeleopConfig, by: str,
                 topic: str = TELEOP_TOPIC, log: Any = print) -> None:
        from autochair.commands.teleop import TeleopLink
        from autochair.commands.teleop_core import Teleop

        self.cfg, self.topic, self.log = cfg, topic, log
        self.core = Teleop(cfg.limits(), scale=1.0)  # the panel sends m/s: no speed scale
        self.link = TeleopLink(session, self.core, by=f"foxglove:{by}")
        self._lock = threading.Lock()
        self._channels: dict[tuple[int, int], str] = {}  # (client, channel) -> its use
        self.messages = self.rejected = 0
        self._last_msg: dict[str, float] = {}
        self._slow_warned = False

    # --- foxglove.websocket.ServerListener (called on the SDK's threads) -------------------
    def on_client_advertise(self, client: Any, channel: Any) -> None:
        use = {self.topic: "teleop", OWNER_TOPIC: "owner"}.get(channel.topic)
        if use is None:
            return
        if channel.encoding != "json":
            self.log(f"teleop: client {client.id} publishes {channel.topic} as "
                     f"{channel.encoding!r}, not json: ignored", flush=True)
            return
        with self._lock:
            self._channels[(client.id, channel.id)] = use

    def on_client_unadvertise(self, client: Any, client_channel_id: int) -> None:
        with self._lock:
            if self._channels.pop((client.id, client_channel_id), None) == "teleop":
                self.core.release(f"panel:{client.id}")

    def on_message_data(self, client: Any, client_channel_id: int, data: bytes) -> None:
        import time

        from autochair.commands.teleop_core import parse_twist, twist_units

        now = time.monotonic()
        with self._lock:
            use = self._channels.get((client.id, client_channel_id))
            if use == "owner":
                self._on_owner(bytes(data))
                return
            if use != "teleop":
                return
            twist = parse_twist(bytes(data))
            if twist is None:
                self.rejected += 1
                return
            self.messages += 1
            source = f"panel:{client.id}"
            gap = now - self._last_msg.get(source, -1e18)
            self._last_msg[source] = now
            if self.core.limits.deadman_s < gap < 2.0 and not self._slow_warned:
                self._slow_warned = True
                self.log(f"teleop: the Teleop panel publishes every {gap:.2f} s; set its "
                         f"publish rate to 20 Hz (the deadman is {self.core.limits.deadman_s:g} "
                         "s)", flush=True)
            self.core.message(source, *twist_units(*twist, self.core.limits), now)

    def _on_owner(self, data: bytes) -> None:
        import msgspec

        try:
            owner = msgspec.json.decode(data).get("owner")
        except (msgspec.DecodeError, AttributeError):
            owner = None
        if owner in ("teleop", "autonomy"):
            self.link.set_owner(owner == "teleop")
            self.log(f"teleop: drive handed to {owner} (sent)", flush=True)
        else:
            self.rejected += 1

    # --- the command loop -------------------------------------------------------------------
    def take_over(self) -> None:
        with self._lock:
            self.link.set_owner(True)

    def run(self, stop: threading.Event) -> None:
        """Publish at the configured rate until `stop`; then one final zero if moving."""
        import time

        period = 1.0 / self.cfg.rate_hz
        next_t = time.monotonic()
        link_was, presses = None, 0
        while not stop.is_set():
            with self._lock:
                cmd = self.link.step(time.monotonic())
                ok, source = self.link.link_ok, self.core.driving_source
            if ok != link_was:
                link_was = ok
                self.log(f"teleop: link to the chair's velocity PID {'ok' if ok else 'LOST'}",
                         flush=True)
            if self.core.presses != presses:
                presses = self.core.presses
                self.log(f"teleop: stream {presses} began ({source})", flush=True)
            elif cmd == (0.0, 0.0) and not source:
                self.log("teleop: stopped (" + ("link lost" if not ok else "released") + ")",
                         flush=True)
            next_t += period
            if next_t < time.monotonic() - period:
                next_t = time.monotonic()
            stop.wait(max(0.0, next_t - time.monotonic()))
        with self._lock:
            self.core.release()
            self.link.step(time.monotonic())


def run(args: argparse.Namespace) -> int:
    import getpass
    import socket

    import foxglove
    from foxglove.websocket import Capability

    from autochair.cli import CliError
    from autochair.commands.link import tool_session
    from autochair.commands.teleop import refuse_beyond_pid_caps, teleop_config
    from autochair.runtime.node import _install_signal_handlers, wait_for_stop

    cfg = None if args.no_teleop else teleop_config(args)
    session = tool_session(args)
    stop = threading.Event()
    loop: threading.Thread | None = None
    try:
        Bridge(session)
        panel = None
        if cfg is not None:
            refuse_beyond_pid_caps(session, cfg.limits())
            panel = PanelTeleop(session, cfg, f"{getpass.getuser()}@{socket.gethostname()}",
                                args.teleop_topic)
        try:
            server = foxglove.start_server(
                name="autochair", host=args.host, port=args.port,
                server_listener=cast("ServerListener | None", panel),
                capabilities=[Capability.ClientPublish] if panel else None,
                supported_encodings=["json"] if panel else None)
        except Exception as e:  # e.g. port in use: one line for the user
            raise CliError(f"cannot serve on {args.host}:{args.port}: {e}") from None
        _install_signal_handlers(stop)  # SIGTERM too: stop cleanly (a final zero)
        print(f"Foxglove bridge on ws://{args.host}:{server.port} (Ctrl-C quits)", flush=True)
        if panel is not None and cfg is not None:
            print(f"teleop: Teleop panel on topic {args.teleop_topic} (publish rate 20 Hz; "
                  f"deadman {cfg.deadman_s:g} s; caps {cfg.max_v_mps:g} m/s, "
                  f"{cfg.max_omega_radps:g} rad/s)", flush=True)
            if args.take_over:
                panel.take_over()
                print("teleop: take-over sent (the chair refuses a view-only identity's)",
                      flush=True)
            loop = threading.Thread(target=panel.run, args=(stop,), daemon=True)
            loop.start()
        try:
            wait_for_stop(stop)
        finally:
            stop.set()
            if loop is not None:
                loop.join(timeout=2)
            server.stop()
        return 0
    finally:
        session.close()
