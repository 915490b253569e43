"""autochair-sim: the simulated chair + Arduino on a pty, speaking the real serial protocol.

The host side (gateway) opens the pty through the symlink `pty_link`, exactly as it would open
/dev/ttyACM0. Ground truth goes out on keys.SIM_TRUTH. Faults for tests come in on the query
key keys.SIM_FAULT (SimFault: "unplug" for duration_s, "replug", "garbage" of count bytes).
"""

from __future__ import annotations

import contextlib
import errno
import math
import os
import random
import sys
import time
import tty
from collections import deque
from typing import Annotated

import msgspec

from autochair.runtime import ConfigError, Node, service_main
from autochair.sim.chair.clock import MAX_CATCH_UP_S, Pacer
from autochair.sim.chair.firmware import NEUTRAL_MV, Firmware
from autochair.sim.chair.model import ChairModel, ChairParams
from autochair_msgs import GroundTruth, keys
from autochair_msgs.sim import SimFault, SimFaultReply

Positive = Annotated[float, msgspec.Meta(gt=0)]


class SimConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """[sim] section."""

    pty_link: str  # symlink created to point at the pty slave (the "serial port")
    # Telemetry frames per simulated second (= model rate; the firmware's AC_FRAME_US).
    telemetry_rate_hz: Positive = float(keys.DRIVE_RATE_HZ)
    time_scale: Positive = 1.0  # simulated seconds per wall second (>1: faster than real time)
    truth_rate_hz: Positive = 100.0  # ground truth per simulated second, while moving
    # ... and while at rest (no wheel turning, joystick at neutral), when it does not change
    parked_truth_rate_hz: Positive = 10.0
    seed: int = 0  # noise and garbage bytes
    noise: bool = False  # wheel-speed noise and encoder slip in the model
    # Systematic odometry errors (model.ChairParams: wheel-diameter ratio, base error, slip in
    # turns and accelerations); the ground truth stays true. Off: exact encoders.
    drift: bool = False
    diameter_ratio: float = 1.004
    base_ratio: float = 1.02


class PtyPort:
    """The master side of a pty with a symlink to its slave; survives hosts coming and going."""

    def __init__(self, link: str) -> None:
        self.link = link
        self.fd = -1
        self.slave_name = ""

    def open(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)  # persists after we close the slave; the host reopens it
        self.slave_name = os.ttyname(slave)
        os.close(slave)  # hold no slave fd: EIO on read then tells us no host is attached
        os.set_blocking(master, False)
        self.fd = master
        self._unlink()
        os.symlink(self.slave_name, self.link)

    def _unlink(self) -> None:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.link)

    def close(self) -> None:
        if self.fd >= 0:
            os.close(self.fd)
            self.fd = -1
        with contextlib.suppress(OSError):
            if os.readlink(self.link) == self.slave_name:
                os.unlink(self.link)

    def read(self) -> bytes | None:
        """All pending host bytes; None when no host has the slave open."""
        chunks = []
        while True:
            try:
                data = os.read(self.fd, 4096)
            except BlockingIOError:
                break
            except OSError as e:
                if e.errno == errno.EIO:
                    return None
                raise
            if not data:
                break
            chunks.append(data)
        return b"".join(chunks)

    def write(self, data: bytes) -> bool:
        """False when the host is not reading (buffer full): the frame is dropped."""
        try:
            return os.write(self.fd, data) == len(data)
        except (BlockingIOError, InterruptedError):
            return False
        except OSError as e:
            if e.errno == errno.EIO:
                return False
            raise


class Simulator:
    """The loop: host bytes -> firmware -> model -> telemetry frame, one step per 1/rate of
    simulated time, on the wall clock × time_scale (`Pacer`)."""

    def __init__(self, node: Node, cfg: SimConfig) -> None:
        self.node, self.cfg = node, cfg
        self.dt = 1.0 / cfg.telemetry_rate_hz
        self.model = ChairModel(ChairParams(noise=cfg.noise, seed=cfg.seed, drift=cfg.drift,
                                            diameter_ratio=cfg.diameter_ratio,
                                            base_ratio=cfg.base_ratio))
        self.fw = Firmware()
        self.port = PtyPort(cfg.pty_link)
        self.t = 0.0
        self.pacer = Pacer(self.dt / cfg.time_scale, max(1, round(MAX_CATCH_UP_S / self.dt)))
        self._rng = random.Random(cfg.seed)
        self._truth_period = 1.0 / cfg.truth_rate_hz
        self._parked_period = 1.0 / cfg.parked_truth_rate_hz
        self._next_truth = 0.0
        self._last_truth = -math.inf
        self._truth_pub = node.publisher(keys.SIM_TRUTH)
        self._faults: deque[SimFault] = deque()
        self._unplugged_until: float | None = None
        self._host_present = False
        self._reported: dict[str, int] = {}

    # --- faults (Zenoh thread enqueues, loop thread applies) --------------------------------
    def on_fault(self, fault: SimFault) -> SimFaultReply:
        if fault.kind not in ("unplug", "replug", "garbage"):
            self.node.health.count("bad_fault_requests")
            return SimFaultReply(ok=False, detail=f"unknown fault kind {fault.kind!r}")
        self._faults.append(fault)
        return SimFaultReply(ok=True, detail=f"{fault.kind} queued")

    def _apply_faults(self) -> None:
        while self._faults:
            f = self._faults.popleft()
            if f.kind == "unplug":
                if self.port.fd >= 0:
                    self.port.close()
                    self.node.health.count("unplugs")
                self._unplugged_until = time.monotonic() + max(f.duration_s, 0.0)
                self.node.event("warning", f"fault: pty unplugged for {f.duration_s} s")
            elif f.kind == "replug":
                self._unplugged_until = time.monotonic()
            elif f.kind == "garbage" and self.port.fd >= 0:
                junk = bytes(self._rng.randrange(256) for _ in range(max(f.count, 0)))
                self.port.write(junk)
                self.node.health.count("garbage_bytes_out", len(junk))
        if self._unplugged_until is not None and time.monotonic() >= self._unplugged_until:
            self._unplugged_until = None
            self.port.open()
            self.node.event("info", f"fault: pty replugged at {self.port.slave_name}")

    # --- the loop -------------------------------------------------------------------------
    def tick(self) -> None:
        self._apply_faults()
        run, lost = self.pacer.steps(self.node.due.get("sim", time.monotonic()))
        if run > 1:
            self.node.health.count("steps_caught_up", run - 1)
        if lost:
            self.node.health.count("steps_lost", lost)
        for _ in range(run):
            self._step()
        self._report_counters()

    def _step(self) -> None:
        if self.port.fd >= 0:
            data = self.port.read()
            present = data is not None
            if present != self._host_present:
                self._host_present = present
                self.node.event("info", "host attached" if present else "host detached")
            if data:
                self.fw.receive(data, self.t)
        else:
            self._host_present = False
        # The firmware also checks its watchdog in mid-frame; the model holds one output over
        # the whole tick, so that check is applied now: neutral never later than the MCU's.
        self.fw.watch(self.t + 0.5 * self.dt)
        self.model.step(*self.fw.output_volts, self.dt)
        self.t += self.dt
        wire = self.fw.tick(self.t, self.model.left_counts, self.model.right_counts)
        if not self._host_present:
            self.node.health.count("frames_unread")  # a UART talking to nobody
        elif self.port.write(wire):
            self.node.health.count("frames_out")
        else:
            self.node.health.count("frames_dropped_host_not_reading")
        if self.t + 1e-9 >= self._next_truth:
            self._next_truth += self._truth_period
            m, fw = self.model, self.fw
            parked = abs(m.v) < 1e-4 and abs(m.omega) < 1e-4 and \
                fw.longitudinal_mv == fw.angular_mv == NEUTRAL_MV
            if not parked or self.t - self._last_truth + 1e-9 >= self._parked_period:
                self._last_truth = self.t
                self._publish_truth()

    def _publish_truth(self) -> None:
        m = self.model
        lv, av = self.fw.output_volts
        self._truth_pub.put(GroundTruth(
            stamp_ns=time.time_ns(), sim_time_s=self.t, x_m=m.x, y_m=m.y, yaw_rad=m.yaw,
            v_mps=m.v, omega_radps=m.omega, longitudinal_v=lv, angular_v=av))

    def _report_counters(self) -> None:
        c = self.fw.counters
        for name, value in (("host_frames", c.host_frames), ("host_bad_frames",
                            c.host_bad_frames), ("host_timeouts", c.host_timeouts),
                            ("rejected_commands", c.rejected_commands)):
            delta = value - self._reported.get(name, 0)
            if delta:
                self.node.health.count(name, delta)
                self._reported[name] = value


def start(node: Node, cfg: SimConfig) -> None:
    sim = Simulator(node, cfg)
    try:
        sim.port.open()
    except OSError as e:
        raise ConfigError(f"cannot create pty link {cfg.pty_link}: {e.strerror}") from None
    node.on_close(sim.port.close)
    for name in ("frames_out", "host_frames", "host_bad_frames", "host_timeouts"):
        node.health.count(name, 0)
    node.health.thresholds.update({"telemetry_rate_hz": cfg.telemetry_rate_hz,
                                   "time_scale": cfg.time_scale,
                                   "firmware_watchdog_s": sim.fw.watchdog_s})
    node.health.detail = f"pty {sim.port.slave_name} via {cfg.pty_link}"
    node.serve(keys.SIM_FAULT, sim.on_fault)
    node.every(sim.dt / cfg.time_scale, sim.tick, "sim")


def main(argv: list[str] | None = None) -> int:
    return service_main("sim", SimConfig, start, argv, description=__doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
