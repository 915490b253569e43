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
from typing import Annotated, Literal

import msgspec

from autochair.backoff import Backoff
from autochair.geometry import yaw_quaternion
from autochair.protocol import scip
from autochair.runtime.config import ChairGeometry
from autochair.runtime.node import Node, service_main
from autochair_msgs import FrameTransform, Quaternion, Vector3, keys

from .core import IngestPolicy, LidarClient, LidarTimeout, ScanDecoder

Positive = Annotated[float, msgspec.Meta(gt=0)]


class LidarConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    url: str = "/dev/ttyACM0"  # serial device or pty path, or tcp://HOST:PORT (UST/UTM class)
    baudrate: Annotated[int, msgspec.Meta(gt=0)] = 115200  # serial only; USB-ACM/ptys ignore it
    command: Literal["MD", "MS"] = "MD"  # MD (3-char values) or MS (2-char, ranges ≤ 4.095 m)
    start_step: int = -1  # -1 = AMIN from PP
    end_step: int = -1  # -1 = AMAX from PP
    cluster: Annotated[int, msgspec.Meta(ge=1, le=99)] = 1  # steps per range (their minimum)
    interval: Annotated[int, msgspec.Meta(ge=0, le=9)] = 0  # scans skipped between reported
    frame_id: str = "laser"
    parent_frame_id: str = "chair"  # the laser's mount in it is the [chair] section
    reply_timeout_s: Positive = 1.0  # per request during the handshake
    stall_timeout_s: Positive = 1.0  # no valid scan this long while streaming → reconnect
    max_consecutive_errors: Annotated[int, msgspec.Meta(ge=1)] = 20  # bad scans in a row
    backoff_base_s: Positive = 0.1  # reconnect delays: base · 2^n, capped, ± jitter
    backoff_max_s: Positive = 1.0
    backoff_jitter: Annotated[float, msgspec.Meta(ge=0, lt=1)] = 0.25  # fraction
    sync_window: Annotated[int, msgspec.Meta(ge=1)] = 100  # scans in the clock-offset filter
    tf_period_s: Positive = 1.0  # static chair→laser transform repeat period

    def __post_init__(self) -> None:
        if self.url.startswith("tcp://"):
            _, sep, port = self.url[6:].rpartition(":")
            if not sep or not port.isdigit():
                raise ValueError(f"url {self.url!r}: want tcp://HOST:PORT")


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


def mount_transform(cfg: LidarConfig, chair: ChairGeometry, stamp_ns: int) -> FrameTransform:
    """The chair→laser transform from the [chair] geometry (the one definition of the mount)."""
    return FrameTransform(
        stamp_ns=stamp_ns, parent_frame_id=cfg.parent_frame_id, child_frame_id=cfg.frame_id,
        translation=Vector3(chair.laser_x_m, chair.laser_y_m, chair.laser_z_m),
        rotation=Quaternion(*yaw_quaternion(chair.laser_yaw_rad)))


def start(node: Node, cfg: LidarConfig) -> None:
    tf = node.publisher(keys.TF_STATIC)
    node.health.thresholds.update(stall_timeout_s=cfg.stall_timeout_s,
                                  backoff_max_s=cfg.backoff_max_s)
    node.every(cfg.tf_period_s, lambda: tf.put(mount_transform(cfg, node.chair, time.time_ns())),
               "tf")
    node.thread(_Ingest(node, cfg).loop, "ingest")


class _Ingest:
    """The reconnect loop and one streaming session per link; IngestPolicy decides."""

    def __init__(self, node: Node, cfg: LidarConfig) -> None:
        self.node, self.cfg = node, cfg
        self.scans = node.publisher(keys.SCAN)
        self.policy = IngestPolicy(cfg.max_consecutive_errors, cfg.stall_timeout_s,
                                   Backoff(cfg.backoff_base_s, 2.0, cfg.backoff_max_s,
                                           cfg.backoff_jitter))
        self.rng = random.Random()

    def count(self, name: str, n: int) -> None:
        self.node.health.count(name, n)

    def loop(self) -> None:
        node, cfg, stop = self.node, self.cfg, self.node.stop_event
        while not stop.is_set():
            try:
                t = open_transport(cfg)
            except OSError as e:
                self.count("connect_failures", 1)
                delay, report = self.policy.open_failed(self.rng.random())
                if report:
                    node.event("warning", f"lidar: cannot open {cfg.url}: {e}")
                node.health.state, node.health.detail = "degraded", f"waiting for {cfg.url}"
                stop.wait(delay)
                continue
            if self.policy.opened():
                self.count("reconnects", 1)
            try:
                self.session(t)
            except (scip.ScipError, OSError) as e:
                self.count(_classify(e), 1)
                if not stop.is_set():
                    node.event("warning", f"lidar: link lost ({_classify(e)}): {e}")
            finally:
                t.close()
            node.health.state, node.health.detail = "degraded", f"reconnecting to {cfg.url}"
            stop.wait(self.policy.lost(self.rng.random()))

    def session(self, t: FdTransport | TcpTransport) -> None:
        cfg, node, policy = self.cfg, self.node, self.policy
        client = LidarClient(t, self.count, time.monotonic, cfg.reply_timeout_s)
        params, req = client.start(None if cfg.start_step < 0 else cfg.start_step,
                                   None if cfg.end_step < 0 else cfg.end_step,
                                   cfg.cluster, cfg.interval, cfg.command)
        dec = ScanDecoder(params, req, cfg.frame_id, self.count, cfg.sync_window)
        node.health.state, node.health.detail = "ok", f"{params.model} on {cfg.url}"
        node.event("info", f"lidar streaming: {params.model}, {dec.n} beams, "
                   f"{params.scan_rpm} rpm, on {cfg.url}")
        policy.streaming(time.monotonic())
        while not node.stop_event.is_set():
            blocks = client.scan_blocks(0.1)
            rx_ns = time.time_ns()
            for block in blocks:
                try:
                    msg = dec.decode(block, rx_ns)
                except scip.ScipError as e:
                    self.count(_classify(e), 1)
                    report, give_up = policy.scan_bad()
                    if report:
                        node.event("warning", f"lidar: bad scan: {e}")
                    if give_up:
                        raise
                    continue
                policy.scan_ok(time.monotonic())
                self.scans.put(msg)
                self.count("scans", 1)
            if policy.stalled(time.monotonic()):
                raise LidarTimeout(f"no valid scan for {cfg.stall_timeout_s} s")


def main(argv: list[str] | None = None) -> int:
    return service_main("lidar", LidarConfig, start, argv, description=__doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
