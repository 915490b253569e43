"""autochair-lidar: Hokuyo SCIP 2.0 ingest (serial/pty or TCP) → checked, stamped LaserScans.

Thin node: transports (serial fd, TCP socket), the reconnect loop and publishing. Protocol,
decoding, clock sync and backoff are in `core` (pure).
"""

from __future__ import annotations

import os
import random
import select
import socket
import sys
import termios
import time
import tty

import msgspec

from autochair.geometry import yaw_quaternion
from autochair.protocol import scip
from autochair.runtime.config import ChairGeometry, ConfigError
from autochair.runtime.node import Node, service_main
from autochair_msgs import FrameTransform, Quaternion, Vector3, keys

from .core import Backoff, LidarClient, LidarTimeout, ScanDecoder


class LidarConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    url: str = "/dev/ttyACM0"  # serial device or pty path, or tcp://HOST:PORT (UST/UTM class)
    baudrate: int = 115200  # serial only; USB-ACM (URG-04LX) and ptys ignore it
    command: str = "MD"  # MD (3-char values) or MS (2-char values, ranges ≤ 4.095 m)
    start_step: int = -1  # -1 = AMIN from PP
    end_step: int = -1  # -1 = AMAX from PP
    cluster: int = 1  # steps per reported range (the device reports their minimum)
    interval: int = 0  # scans skipped between reported scans
    frame_id: str = "laser"
    parent_frame_id: str = "chair"  # the laser's mount in it is the [chair] section
    reply_timeout_s: float = 1.0  # per request during the handshake
    stall_timeout_s: float = 1.0  # no valid scan this long while streaming → reconnect
    max_consecutive_errors: int = 20  # bad scans in a row → reconnect
    backoff_base_s: float = 0.1  # reconnect delays: base · 2^n, capped, ± jitter
    backoff_max_s: float = 1.0
    backoff_jitter: float = 0.25  # fraction
    sync_window: int = 100  # scans in the device→host clock offset min-filter
    tf_period_s: float = 1.0  # static chair→laser transform repeat period


def _classify(e: BaseException) -> str:
    if isinstance(e, scip.SumError):
        return "bad_sum"
    if isinstance(e, scip.EchoError):
        return "bad_echo"
    if isinstance(e, scip.StatusError):
        return "bad_status"
    if isinstance(e, LidarTimeout):
        return "timeouts"
    if isinstance(e, scip.ScipError):
        return "format_errors"
    return "io_errors"


class FdTransport:
    """A serial device or pty, raw 8N1, via select + os.read (pyserial adds nothing here)."""

    def __init__(self, path: str, baudrate: int) -> None:
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            tty.setraw(self.fd)
            attrs = termios.tcgetattr(self.fd)
            speed = getattr(termios, f"B{baudrate}", termios.B115200)
            attrs[4] = attrs[5] = speed
            termios.tcsetattr(self.fd, termios.TCSANOW, attrs)
            termios.tcflush(self.fd, termios.TCIOFLUSH)  # stale bytes from before we opened
        except (termios.error, OSError):
            os.close(self.fd)
            raise

    def write(self, data: bytes) -> None:
        os.write(self.fd, data)

    def read(self, timeout_s: float) -> bytes:
        r, _, _ = select.select([self.fd], [], [], max(timeout_s, 0.0))
        if not r:
            return b""
        data = os.read(self.fd, 65536)
        if not data:
            raise ConnectionError("device closed")
        return data

    def close(self) -> None:
        os.close(self.fd)


class TcpTransport:
    def __init__(self, host: str, port: int, timeout_s: float) -> None:
        self.sock = socket.create_connection((host, port), timeout=timeout_s)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def write(self, data: bytes) -> None:
        self.sock.sendall(data)

    def read(self, timeout_s: float) -> bytes:
        r, _, _ = select.select([self.sock], [], [], max(timeout_s, 0.0))
        if not r:
            return b""
        data = self.sock.recv(65536)
        if not data:
            raise ConnectionError("device closed the connection")
        return data

    def close(self) -> None:
        self.sock.close()


def open_transport(cfg: LidarConfig) -> FdTransport | TcpTransport:
    if cfg.url.startswith("tcp://"):
        host, _, port = cfg.url[6:].rpartition(":")
        return TcpTransport(host, int(port), cfg.reply_timeout_s)
    return FdTransport(cfg.url, cfg.baudrate)


def check_config(cfg: LidarConfig) -> None:
    if cfg.command not in ("MD", "MS"):
        raise ConfigError(f"lidar.command must be MD or MS, not {cfg.command!r}")
    if cfg.url.startswith("tcp://"):
        _, sep, port = cfg.url[6:].rpartition(":")
        if not sep or not port.isdigit():
            raise ConfigError(f"lidar.url {cfg.url!r}: want tcp://HOST:PORT")
    if not 1 <= cfg.cluster <= 99 or not 0 <= cfg.interval <= 9:
        raise ConfigError("lidar.cluster must be 1..99 and lidar.interval 0..9")
    if cfg.stall_timeout_s <= 0 or cfg.reply_timeout_s <= 0 or cfg.backoff_max_s <= 0:
        raise ConfigError("lidar timeouts and backoff_max_s must be > 0")


def mount_transform(cfg: LidarConfig, chair: ChairGeometry, stamp_ns: int) -> FrameTransform:
    """The chair→laser transform from the [chair] geometry (the one definition of the mount)."""
    return FrameTransform(
        stamp_ns=stamp_ns, parent_frame_id=cfg.parent_frame_id, child_frame_id=cfg.frame_id,
        translation=Vector3(chair.laser_x_m, chair.laser_y_m, chair.laser_z_m),
        rotation=Quaternion(*yaw_quaternion(chair.laser_yaw_rad)))


def start(node: Node, cfg: LidarConfig) -> None:
    check_config(cfg)
    scans = node.publisher(keys.SCAN)
    tf = node.publisher(keys.TF_STATIC)
    health = node.health
    health.thresholds.update(stall_timeout_s=cfg.stall_timeout_s,
                             backoff_max_s=cfg.backoff_max_s)
    node.every(cfg.tf_period_s, lambda: tf.put(mount_transform(cfg, node.chair, time.time_ns())),
               "tf")
    stop = node.stop_event

    def count(name: str, n: int) -> None:
        health.count(name, n)

    def session(t: FdTransport | TcpTransport) -> None:
        client = LidarClient(t, count, time.monotonic, cfg.reply_timeout_s)
        params, req = client.start(None if cfg.start_step < 0 else cfg.start_step,
                                   None if cfg.end_step < 0 else cfg.end_step,
                                   cfg.cluster, cfg.interval, cfg.command)
        dec = ScanDecoder(params, req, cfg.frame_id, count, cfg.sync_window)
        health.state, health.detail = "ok", f"{params.model} on {cfg.url}"
        node.event("info", f"lidar streaming: {params.model}, {dec.n} beams, "
                   f"{params.scan_rpm} rpm, on {cfg.url}")
        last_ok, errors = time.monotonic(), 0
        while not stop.is_set():
            blocks = client.scan_blocks(0.1)
            rx_ns = time.time_ns()
            for block in blocks:
                try:
                    msg = dec.decode(block, rx_ns)
                except scip.ScipError as e:
                    count(_classify(e), 1)
                    errors += 1
                    if errors in (1, 10, 100) or errors >= cfg.max_consecutive_errors:
                        node.event("warning", f"lidar: bad scan: {e}")
                    if errors >= cfg.max_consecutive_errors:
                        raise
                    continue
                errors, last_ok = 0, time.monotonic()
                scans.put(msg)
                count("scans", 1)
            if time.monotonic() - last_ok > cfg.stall_timeout_s:
                raise LidarTimeout(f"no valid scan for {cfg.stall_timeout_s} s")

    def loop() -> None:
        backoff = Backoff(cfg.backoff_base_s, 2.0, cfg.backoff_max_s, cfg.backoff_jitter)
        rng = random.Random()
        connected_once = False
        while not stop.is_set():
            try:
                t = open_transport(cfg)
            except OSError as e:
                count("connect_failures", 1)
                if backoff.attempt == 0:
                    node.event("warning", f"lidar: cannot open {cfg.url}: {e}")
                health.state, health.detail = "degraded", f"waiting for {cfg.url}"
                stop.wait(backoff.next_s(rng.random()))
                continue
            if connected_once:
                count("reconnects", 1)
            connected_once = True
            before = health.counters.get("scans", 0)
            try:
                session(t)
            except (scip.ScipError, OSError) as e:
                count(_classify(e), 1)
                if not stop.is_set():
                    node.event("warning", f"lidar: link lost ({_classify(e)}): {e}")
            finally:
                t.close()
            if health.counters.get("scans", 0) > before:
                backoff.reset()  # it worked for a while: retry quickly
            health.state, health.detail = "degraded", f"reconnecting to {cfg.url}"
            stop.wait(backoff.next_s(rng.random()))

    node.thread(loop, "ingest")


def main(argv: list[str] | None = None) -> int:
    return service_main("lidar", LidarConfig, start, argv, description=__doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
