"""autochair-lidar-sim: a simulated Hokuyo URG-04LX on a pty and on TCP, ray-casting a 2D world
from the simulated chair's true pose (keys.SIM_TRUTH; (0, 0, 0) until the first sample).

The laser sits at the [chair] mount (`node.chair`), like the ingest's tf_static says.

Fault hooks (for tests and benches):
- SIGUSR1 unplugs the device for `unplug_s` seconds (the pty and its link vanish, the TCP
  listener closes), then it comes back rebooted (SCIP 1.1 mode, clock from 0).
- SIGRTMIN (`kill -s RTMIN <pid>`; `BLIND_SIGNAL`) toggles blinding: every beam reports error
  code 1 ("no return within DMAX", what a dazzled, fogged or covered window gives), while the
  link and the protocol stay healthy. `blinded = true` starts it blinded. The health counter
  `blinded_scans` counts such scans. (SIGUSR2 is the runtime's hang hook for every node.)
"""

from __future__ import annotations

import os
import select
import signal
import socket
import sys
import threading
import time
import tty
from pathlib import Path
from typing import Annotated

import msgspec
import numpy as np
import numpy.typing as npt

from autochair.runtime.config import ConfigError
from autochair.runtime.node import Node, service_main
from autochair_msgs import keys

from ..world import DEFAULT_WORLD, World, WorldError, load_world
from .scanner import ERR_NO_RETURN, ScanFn, UrgDevice, UrgParams, ray_scan

BLIND_SIGNAL = signal.SIGRTMIN  # test hook: toggles blinding
MAX_OUT = 1 << 18  # bytes queued for a reader that does not read; more is dropped (counted)


class LidarSimConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    pty_link: str = ""  # path of a symlink to the pty slave ("" = no pty)
    tcp_port: int = -1  # TCP port on 127.0.0.1 (-1 = off; 10940 is the UST/UTM default)
    world: str = ""  # world file ("" = the shipped hallway)
    # URG-04LX: 10 (600 rpm); 40 emulates a UTM-30LX's rate
    scan_rate_hz: Annotated[float, msgspec.Meta(gt=0, le=100)] = 10.0
    noise_std_m: float = 0.01  # Gaussian range noise
    blinded: bool = False  # test hook: every beam an error code (BLIND_SIGNAL toggles it)
    clock_start_ms: int = 0  # device clock at boot (set near 2^24 to exercise wraparound)
    unplug_s: float = 3.0  # how long SIGUSR1 unplugs the device
    seed: int = 0

    def __post_init__(self) -> None:
        if not self.pty_link and self.tcp_port < 0:
            raise ValueError("set pty_link and/or tcp_port")


class Endpoint:
    """One device behind one link; `serve` runs until unplugged or stopped."""

    def __init__(self, node: Node, cfg: LidarSimConfig, params: UrgParams,
                 scan_fn: ScanFn) -> None:
        self.node, self.cfg, self.params, self.scan_fn = node, cfg, params, scan_fn
        self.unplug = threading.Event()

    def run(self) -> None:
        raise NotImplementedError

    def new_device(self) -> tuple[UrgDevice, float]:
        return UrgDevice(self.params, self.scan_fn, self.cfg.clock_start_ms), time.monotonic()

    def pump(self, rfd: int, wfd: int, stop: threading.Event) -> None:
        """Serve one connection: requests in, replies and scans out, until EOF/unplug/stop."""
        (dev, boot), inbuf, out = self.new_device(), b"", b""
        h = self.node.health
        while not (stop.is_set() or self.unplug.is_set()):
            due = dev.next_due_s()
            now = time.monotonic() - boot
            timeout = 0.05 if due is None else min(0.05, max(due - now, 0.0))
            r, _, _ = select.select([rfd], [wfd] if out else [], [], timeout)
            now = time.monotonic() - boot
            if r:
                try:
                    data = os.read(rfd, 4096)
                except OSError:
                    data = b""
                if not data:
                    return
                inbuf += data
                *lines, inbuf = inbuf.split(b"\n")
                inbuf = inbuf[-1024:]
                for line in lines:
                    h.count("requests")
                    out += dev.handle(line, now)
            skipped = dev.skipped_scans
            for block in dev.poll(now):
                h.count("scans_sent")
                out += block
            if dev.skipped_scans > skipped:  # this process stalled past a scan's slot
                h.count("skipped_scans", dev.skipped_scans - skipped)
            if len(out) > MAX_OUT:
                h.count("tx_dropped_bytes", len(out) - MAX_OUT)
                out = out[-MAX_OUT:]
            if out:
                try:
                    n = os.write(wfd, out)
                except BlockingIOError:
                    n = 0
                except OSError:
                    return
                out = out[n:]

    def unplugged(self, stop: threading.Event) -> None:
        if self.unplug.is_set() and not stop.is_set():
            self.node.event("warning", f"lidar-sim: unplugged for {self.cfg.unplug_s} s")
            self.node.health.count("unplugs")
            stop.wait(self.cfg.unplug_s)
            self.unplug.clear()
            self.node.event("info", "lidar-sim: plugged back in")


class PtyEndpoint(Endpoint):
    def run(self) -> None:
        stop, link = self.node.stop_event, Path(self.cfg.pty_link)
        while not stop.is_set():
            master, slave = os.openpty()
            try:
                tty.setraw(slave)  # the sim keeps the slave open so the master never sees EIO
                os.set_blocking(master, False)
                tmp = link.with_name(link.name + ".tmp")
                tmp.unlink(missing_ok=True)
                tmp.symlink_to(os.ttyname(slave))
                os.replace(tmp, link)  # atomic: a reader never sees a half-made link
                self.pump(master, master, stop)
            finally:
                link.unlink(missing_ok=True)
                os.close(master)
                os.close(slave)
            self.unplugged(stop)


class TcpEndpoint(Endpoint):
    def run(self) -> None:
        stop = self.node.stop_event
        while not stop.is_set():
            srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                srv.bind(("127.0.0.1", self.cfg.tcp_port))
                srv.listen(1)
                while not (stop.is_set() or self.unplug.is_set()):
                    if not select.select([srv], [], [], 0.1)[0]:
                        continue
                    conn, _ = srv.accept()
                    conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                    conn.setblocking(False)
                    try:
                        self.pump(conn.fileno(), conn.fileno(), stop)
                    finally:
                        conn.close()
            finally:
                srv.close()
            self.unplugged(stop)


class LidarSim:
    """The device's scan source: the world (people where they are now) seen from the chair's
    true pose, or blinded."""

    def __init__(self, node: Node, cfg: LidarSimConfig, world: World) -> None:
        self.node, self.cfg, self.world = node, cfg, world
        self.params = UrgParams(scan_rate_hz=cfg.scan_rate_hz)
        # The true pose, read once per scan: the newest ground truth (100 Hz while moving),
        # kept by Zenoh, so no thread of ours wakes per sample.
        self.truth = node.latest(keys.SIM_TRUTH)
        self.mount = node.chair.laser_mount
        self.rng = np.random.default_rng(cfg.seed)
        self.lock = threading.Lock()  # the generator is shared by the pty and TCP threads
        self.blind = threading.Event()
        if cfg.blinded:
            self.blind.set()
        self.was_blind = False
        self.t0 = time.monotonic()  # people walk from the start of this process
        self.endpoints: list[Endpoint] = []

    def scan_fn(self, _now_s: float) -> npt.NDArray[np.int64]:
        """The sweep that ends now, from the chair's true pose and motion (the newest ground
        truth; at rest at the origin before the first): a turning chair skews it."""
        world = self.world.at(time.monotonic() - self.t0)
        m = self.truth()
        pose, twist = ((0.0, 0.0, 0.0), (0.0, 0.0)) if m is None else \
            ((m.x_m, m.y_m, m.yaw_rad), (m.v_mps, m.omega_radps))
        with self.lock:
            raw = ray_scan(world, self.params, pose, self.mount, self.cfg.noise_std_m,
                           self.rng, twist)
        blinded = self.blind.is_set()
        if blinded != self.was_blind:  # logged here, not in the signal handler
            self.was_blind = blinded
            self.node.event("warning" if blinded else "info",
                            "lidar-sim: blinded (every beam an error code)" if blinded
                            else "lidar-sim: no longer blinded")
        if blinded:
            self.node.health.count("blinded_scans")
            return np.full_like(raw, ERR_NO_RETURN)
        return raw

    def on_usr1(self, _signum: int, _frame: object) -> None:
        for ep in self.endpoints:
            ep.unplug.set()

    def on_blind(self, _signum: int, _frame: object) -> None:
        if self.blind.is_set():
            self.blind.clear()
        else:
            self.blind.set()
        self.node.health.detail = self.detail()

    def detail(self) -> str:
        people = f", {len(self.world.people)} walking" if len(self.world.people) else ""
        return (f"world {self.cfg.world or DEFAULT_WORLD.name}{people}, "
                f"{self.cfg.scan_rate_hz} scans/s"
                + (", BLINDED (test hook)" if self.blind.is_set() else ""))


def start(node: Node, cfg: LidarSimConfig) -> None:
    try:
        world = load_world(cfg.world or DEFAULT_WORLD)
    except WorldError as e:
        raise ConfigError(str(e)) from None
    sim = LidarSim(node, cfg, world)
    if cfg.pty_link:
        sim.endpoints.append(PtyEndpoint(node, cfg, sim.params, sim.scan_fn))
    if cfg.tcp_port >= 0:
        sim.endpoints.append(TcpEndpoint(node, cfg, sim.params, sim.scan_fn))
    for i, ep in enumerate(sim.endpoints):
        node.thread(ep.run, f"endpoint{i}")
    signal.signal(signal.SIGUSR1, sim.on_usr1)
    signal.signal(BLIND_SIGNAL, sim.on_blind)
    node.health.detail = sim.detail()


def main(argv: list[str] | None = None) -> int:
    return service_main("lidar-sim", LidarSimConfig, start, argv, description=__doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
