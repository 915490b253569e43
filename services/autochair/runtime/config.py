"""Configuration: one TOML file with a section per service, plus `--set key=value` overrides.

Every service's settings are a msgspec Struct with defaults, so a typo or a wrong type is a clear
error naming the field, not a silent default.
"""

from __future__ import annotations

import json
import os
import re
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any, TypeVar

import msgspec
import zenoh

from autochair.geometry import mount_mismatch
from autochair_msgs import FrameTransform

T = TypeVar("T")

ENV_CONFIG = "AUTOCHAIR_CONFIG"  # path of the TOML file
ENV_CONNECT = "AUTOCHAIR_CONNECT"  # comma-separated Zenoh endpoints of the hub
ENV_CHAIR = "AUTOCHAIR_CHAIR"  # the chair's name: the Zenoh namespace of all its keys
DEFAULT_HUB = "tcp/127.0.0.1:7447"


class ConfigError(Exception):
    """Bad configuration; the message is one line meant for a person."""


class ZenohSettings(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """How a process joins the Zenoh network ([zenoh] section of the config file).

    Default: a peer that connects to the hub (the `router` process) for discovery and listens on
    an ephemeral loopback port, so peers then talk directly (lower latency than via the hub).
    """

    mode: str = "peer"  # peer | client | router
    connect: list[str] = msgspec.field(default_factory=lambda: [DEFAULT_HUB])
    listen: list[str] = msgspec.field(default_factory=lambda: ["tcp/127.0.0.1:0"])
    multicast_scouting: bool = False
    lease_ms: int = 1000  # a hung process is declared gone after about this long
    config_file: str = ""  # a full Zenoh JSON5 config (TLS, ACL...) applied before the above
    # The chair's name: Zenoh's own session namespace, prefixed to every key expression of the
    # session (puts, subscriptions, queries, queryables, liveliness) and stripped from what it
    # receives, so services and tools keep writing `autochair/...` while the network carries
    # `NAME/autochair/...`. Two chairs on one hub never see each other's keys. "" = none.
    namespace: str = ""

    def to_zenoh(self) -> zenoh.Config:
        if self.config_file:
            try:
                cfg = zenoh.Config.from_file(self.config_file)
            except Exception as e:
                raise ConfigError(f"zenoh config file {self.config_file}: {e}") from None
        else:
            cfg = zenoh.Config()
        if self.mode not in ("peer", "client", "router"):
            raise ConfigError(f"zenoh.mode must be peer, client or router, not {self.mode!r}")
        cfg.insert_json5("mode", json.dumps(self.mode))
        if self.namespace:
            cfg.insert_json5("namespace", json.dumps(check_chair(self.namespace,
                                                                 "[zenoh] namespace")))
        cfg.insert_json5("scouting/multicast/enabled", json.dumps(self.multicast_scouting))
        cfg.insert_json5("transport/link/tx/lease", json.dumps(self.lease_ms))
        # Zenoh's defaults (2 batches per priority, drop after waiting 1 ms) lose samples
        # whenever a process is descheduled for a few ms, as on a busy 2-core machine or a VM:
        # the drive chain measured ~1 % of encoder frames lost at 200 Hz. A deeper queue and
        # a 20 ms grace keep every sample; the stale-data watchdogs still bound the age.
        cfg.insert_json5("transport/link/tx/queue/size/data", "16")
        cfg.insert_json5("transport/link/tx/queue/congestion_control/drop/wait_before_drop",
                         "20000")
        # A blocked link (its peer stopping too, as when a whole stack shuts down) held
        # session.close() for the default 5 s, so SIGTERM sometimes ended in SIGKILL.
        cfg.insert_json5("transport/link/tx/queue/congestion_control/block/wait_before_close",
                         "500000")
        # No shared memory: zenoh 1.10 copies every put over 3 kB (scans, maps) into a shared
        # segment for a peer on this host, and each process that touches one runs two watchdog
        # threads (~30 wake-ups a second). Nothing here gains from it (10 Hz scans, 1 Hz maps;
        # compose's containers share no /dev/shm). Measured in README, CPU and recording size.
        cfg.insert_json5("transport/shared_memory/enabled", "false")
        if self.connect:
            cfg.insert_json5("connect/endpoints", json.dumps(self.connect))
            # Keep retrying the hub instead of failing at start: the launcher, supervisor or
            # compose may start us before it.
            # Peers: 1 ms, not 0: with 0 zenoh 1.10 never retries a hub that is not up yet
            # (supervisord/systemd start order); with >0 it keeps retrying in the background.
            cfg.insert_json5("connect/timeout_ms", json.dumps(-1 if self.mode == "client" else 1))
            cfg.insert_json5("connect/exit_on_failure", "false")
        if self.listen:
            cfg.insert_json5("listen/endpoints", json.dumps(self.listen))
        return cfg


Seconds = Annotated[float, msgspec.Meta(gt=0, le=10)]  # a watchdog threshold
Metres = Annotated[float, msgspec.Meta(gt=0, le=5)]  # a body dimension
Coordinate = Annotated[float, msgspec.Meta(ge=-10, le=10)]  # a mount coordinate (m or rad)


class StaleConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """Every stale threshold of the watchdog chain, in one place: the [stale] section.

    Set from the command line of any service with `--set stale.joystick_s=0.2`. Each is a
    msgspec constraint, so a bad value is an error naming the field (also NaN and ±inf).
    """

    joystick_s: Seconds = 0.1  # gateway: no valid joystick command → neutral
    estop_s: Seconds = 0.5  # gateway: no e-stop heartbeat → neutral
    desired_velocity_s: Seconds = 0.3  # velocity PID: no desired velocity → zero effort
    odometry_s: Seconds = 0.3  # control law: no odometry → abort the goal and stop
    scan_s: Seconds = 0.5  # safety monitor: no laser scan → stop
    scan_age_s: Seconds = 0.35  # safety monitor: a scan whose own stamp is older → stop
    clock_skew_s: Seconds = 0.1  # commands stamped further in the future than this are rejected
    watchdog_s: Seconds = 1.5  # a service whose loops stop for this long is killed and restarted
    safety_limit_s: Seconds = 0.5  # velocity PID: no safety limit (when required) → stop
    firmware_host_s: Seconds = 0.2  # Arduino: no host frame → neutral (fixed in the firmware)


class ChairGeometry(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """The chair's body and laser mount: the [chair] section, defined ONCE for every service
    (safety monitor, mapping, lidar ingest, simulators). Two different mounts on one chair
    would be a hazard: the monitor would see obstacles where they are not.

    Chair frame (REP-103): origin at the drive-axle centre, x forward, y left, z up.
    """

    front_m: Metres = 0.95  # footprint ahead of the drive axle
    rear_m: Metres = 0.25  # footprint behind the axle (1.2 m long in all)
    half_width_m: Metres = 0.35  # 0.7 m wide
    laser_x_m: Coordinate = 0.8636  # the laser's pose in the chair frame (thesis mount)
    laser_y_m: Coordinate = 0.2032
    laser_z_m: Coordinate = 0.3937
    laser_yaw_rad: Coordinate = 0.0

    @property
    def laser_mount(self) -> tuple[float, float, float]:
        """(x, y, yaw) of the laser in the chair frame."""
        return (self.laser_x_m, self.laser_y_m, self.laser_yaw_rad)

    def laser_tf_error(self, tf: FrameTransform) -> str:
        """"" if a received chair→laser transform agrees with this mount, else why not."""
        t, q = tf.translation, tf.rotation
        return mount_mismatch(tf.parent_frame_id, (t.x, t.y, t.z), (q.x, q.y, q.z, q.w),
                              (self.laser_x_m, self.laser_y_m, self.laser_z_m),
                              self.laser_yaw_rad)


def _parse_value(text: str) -> Any:
    """A `--set` value: TOML syntax if it parses (numbers, booleans, arrays), else a string."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def read_file(path: str | None) -> dict[str, Any]:
    path = path or os.environ.get(ENV_CONFIG) or None
    if not path:
        return {}
    try:
        return tomllib.loads(Path(path).read_text())
    except FileNotFoundError:
        raise ConfigError(f"config file not found: {path}") from None
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"config file {path}: {e}") from None


def apply_overrides(table: dict[str, Any], overrides: list[str]) -> dict[str, Any]:
    """Apply `key=value` (or `a.b=value`) overrides to a section."""
    out = dict(table)
    for item in overrides:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ConfigError(f"--set wants key=value, got {item!r}")
        node = out
        *parents, leaf = key.strip().split(".")
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = _parse_value(value.strip())
    return out


def load_section(
    type_: type[T], section: str, path: str | None = None, overrides: list[str] | None = None
) -> T:
    """Build `type_` from `[section]` of the config file with overrides applied."""
    table = read_file(path).get(section, {})
    table = apply_overrides(table, overrides or [])
    try:
        return msgspec.convert(table, type_)
    except msgspec.ValidationError as e:
        raise ConfigError(f"[{section}] {e}") from None


_CHAIR_NAME = re.compile(r"[A-Za-z0-9_-]+")


def check_chair(name: str, what: str = "--chair") -> str:
    """`name` if it is a chair name (one key chunk: letters, digits, - and _), else a
    one-line ConfigError naming `what` it came from."""
    if not _CHAIR_NAME.fullmatch(name):
        raise ConfigError(f"{what}: a chair name is one word of letters, digits, - and _ "
                          f"(e.g. chair-2), not {name!r}")
    return name


def load_zenoh(path: str | None = None, connect: str | None = None,
               chair: str | None = None) -> ZenohSettings:
    """[zenoh] of the config file; `connect` (else $AUTOCHAIR_CONNECT) replaces its hub and
    `chair` (else $AUTOCHAIR_CHAIR) its namespace. `chair=""` means explicitly none."""
    settings = load_section(ZenohSettings, "zenoh", path)
    connect = connect or os.environ.get(ENV_CONNECT)
    if connect:
        settings.connect = [e.strip() for e in connect.split(",") if e.strip()]
    if chair is not None:
        settings.namespace = chair and check_chair(chair)
    elif os.environ.get(ENV_CHAIR):
        settings.namespace = check_chair(os.environ[ENV_CHAIR], f"${ENV_CHAIR}")
    elif settings.namespace:
        check_chair(settings.namespace, "[zenoh] namespace")
    return settings


def chair_in(env: Mapping[str, str]) -> str:
    """The chair (namespace) a service started with environment `env` joins: $AUTOCHAIR_CHAIR,
    else [zenoh] namespace of $AUTOCHAIR_CONFIG; "" for none. ConfigError if invalid."""
    if env.get(ENV_CHAIR):
        return check_chair(env[ENV_CHAIR], f"${ENV_CHAIR}")
    namespace = load_section(ZenohSettings, "zenoh", env.get(ENV_CONFIG) or None).namespace
    return namespace and check_chair(namespace, "[zenoh] namespace")
