"""Gateway node: serial port ↔ Zenoh. Holds neutral whenever in doubt; reconnects with backoff."""

from __future__ import annotations

import contextlib
import os
import random
import select
import sys
import threading
import time
from collections.abc import Callable
from typing import Annotated

import msgspec
import serial

from autochair.backoff import Backoff
from autochair.runtime import ConfigError, Node, service_main
from autochair_msgs import EncoderSample, EStopState, JoystickCommand, JoystickOutput, keys

from .core import GatewayCore, Output

Positive = Annotated[float, msgspec.Meta(gt=0)]
# Watchdog and keepalive tick: after every serial read, which returns on each telemetry frame
# or after TICK_S without one, so ticks are never more than TICK_S apart. The core looks one
# tick ahead, so the stale timeouts hold exactly (neutral no later than [stale] joystick_s
# after the last command). One thread waking at the frame rate, not a second one for the
# tick (profiled: each 100 Hz wake-up of a Python thread costs ~0.5 % of a core here).
TICK_S = 1.0 / keys.DRIVE_RATE_HZ
BACKOFF_SLICE_S = 0.25  # the reconnect wait beats the watchdog at least this often
WRITE_TIMEOUT_S = 0.05  # a frame the port has not taken by then: the link is lost


def write_all(port: serial.SerialBase, data: bytes, timeout_s: float,
              clock: Callable[[], float] = time.monotonic) -> None:
    """Write all of `data`; raise SerialTimeoutException if the port has had no room for it
    for `timeout_s`.

    pyserial's own write timeout also fires after a write that went through, when the thread
    was descheduled past it (pyserial issue #281, open since 2017): under load a frame already
    sent read as a lost link, and the chair stopped (session 24's CI). Here only the time the
    port has no room counts. Ports without a descriptor (loop://) keep pyserial's write."""
    try:
        fd = port.fileno()  # a device, a pty or socket://, all opened non-blocking
    except (AttributeError, NotImplementedError, serial.SerialException):
        port.write(data)
        return
    view, end = memoryview(data), clock() + timeout_s
    while view:
        try:
            view = view[os.write(fd, view):]
        except BlockingIOError:
            # Past the deadline, one look (timeout 0) still lets a port with room through.
            if not select.select([], [fd], [], max(end - clock(), 0.0))[1]:
                raise serial.SerialTimeoutException(
                    f"{len(view)} of {len(data)} bytes not taken in {timeout_s} s") from None


class GatewayConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    port: str = ""  # device (/dev/ttyACM0), pty path, or a pyserial URL (loop://, socket://...)
    baudrate: Annotated[int, msgspec.Meta(gt=0)] = 115200
    require_estop: bool = True  # hold neutral unless the e-stop service says "released"
    # The valid joystick window, volts; it must contain neutral (2.5 V).
    min_v: Annotated[float, msgspec.Meta(ge=0.5, lt=2.5)] = 1.1
    max_v: Annotated[float, msgspec.Meta(gt=2.5, le=4.5)] = 3.9
    # Frames are written at least this often: well inside the firmware's 200 ms watchdog.
    keepalive_hz: Annotated[float, msgspec.Meta(ge=10, le=1000)] = 50.0
    rx_stall_s: Positive = 2.0  # no telemetry this long on an open port → reopen it
    reconnect_min_s: Positive = 0.1
    reconnect_max_s: Positive = 2.0


class Gateway:
    def __init__(self, node: Node, cfg: GatewayConfig) -> None:
        if not cfg.port:
            raise ConfigError("[gateway] port is not set (device path, pty or pyserial URL)")
        self.node, self.cfg = node, cfg
        stale = node.stale
        self.core = GatewayCore(stale_s=stale.joystick_s, estop_stale_s=stale.estop_s,
                                skew_s=stale.clock_skew_s,
                                require_estop=cfg.require_estop, min_v=cfg.min_v, max_v=cfg.max_v,
                                keepalive_s=1.0 / cfg.keepalive_hz, rx_stall_s=cfg.rx_stall_s,
                                tick_s=TICK_S)
        self.lock = threading.Lock()  # core + port writes: command callback vs tick vs reader
        self.port: serial.SerialBase | None = None
        self.backoff = Backoff(cfg.reconnect_min_s, 2.0, cfg.reconnect_max_s, 0.2)
        self.link_epoch = 0  # serial connections so far (EncoderSample.link_epoch)
        self.enc_pub = node.publisher(keys.ENCODERS)
        self.out_pub = node.publisher(keys.JOYSTICK_OUT)
        h = node.health
        h.thresholds.update(joystick_s=stale.joystick_s, estop_s=stale.estop_s,
                            firmware_host_s=stale.firmware_host_s, min_v=cfg.min_v,
                            max_v=cfg.max_v)
        h.state, h.detail = "degraded", f"connecting to {cfg.port}"
        node.subscribe(keys.JOYSTICK, self.on_command)
        node.subscribe(keys.ESTOP_STATE, self.on_estop)
        # A hung e-stop is still caught by the heartbeat; a dead one by its token at once.
        node.watch_alive("estop", self.on_estop_alive)
        self.beat = node.beat("tick", TICK_S)
        node.thread(self.serial_loop, "serial")

    # --- host → chair ----------------------------------------------------------------------
    def on_command(self, cmd: JoystickCommand) -> None:
        with self.lock:
            age_s = (time.time_ns() - cmd.stamp_ns) / 1e9
            if not self.core.on_command(cmd.longitudinal_v, cmd.angular_v, cmd.enable,
                                        time.monotonic(), cmd.source_seq, age_s):
                self.node.health.count("rejected_commands")
                return
            self.node.health.count("commands")
            self._write(self.core.output(time.monotonic()))

    def on_estop(self, state: EStopState) -> None:
        with self.lock:
            self.core.on_estop(state.latched, time.monotonic())
            if state.latched:
                self._write(self.core.output(time.monotonic()))  # at once, not at the next tick

    def on_estop_alive(self, alive: bool) -> None:
        if not alive:
            with self.lock:
                self.core.on_estop_gone()
                self._write(self.core.output(time.monotonic()))

    def tick(self) -> None:
        """Watchdog and keepalive: write when the output changes or the keepalive is due."""
        with self.lock:
            out = self.core.due(time.monotonic())
            if out is not None:
                self._write(out)

    def _write(self, out: Output) -> None:
        if self.port is None:
            return
        data, seq = self.core.frame(out)
        try:
            write_all(self.port, data, WRITE_TIMEOUT_S)
        except (serial.SerialException, OSError) as e:
            self._lost(f"write failed: {e}")
            return
        changed, fault, report = self.core.sent(out, time.monotonic())
        if changed:
            self.node.event("warning" if fault else "info", f"output {out.reason}")
        self.node.health.count("frames_out")
        if report:
            self.out_pub.put(JoystickOutput(
                stamp_ns=time.time_ns(), seq=seq, longitudinal_v=out.longitudinal_v,
                angular_v=out.angular_v, enable=out.enable, reason=out.reason,
                clamped=out.clamped))

    # --- chair → host ----------------------------------------------------------------------
    def serial_loop(self) -> None:
        """Read telemetry and tick after every read; reopen a lost port with backoff."""
        stop = self.node.stop_event
        while not stop.is_set():
            if self.port is None:
                self.beat.pause()  # opening a URL (socket://) may block for its own timeout
                opened = self._open()
                self.beat()
                if opened:
                    self.backoff.reset()
                    continue
                if self.backoff.attempt == 0:  # say it once per outage, not once per attempt
                    self.node.event("warning", f"serial port {self.cfg.port} unavailable; "
                                    "holding neutral and retrying with backoff")
                # jitter keeps several gateways (or a flapping hub) from retrying in lockstep
                end = time.monotonic() + self.backoff.next_s(random.random())
                while not stop.wait(min(BACKOFF_SLICE_S, max(end - time.monotonic(), 0.0))) \
                        and time.monotonic() < end:
                    self.beat()
                continue
            self._read_once()
            self.tick()
            self.beat()

    def _open(self) -> bool:
        try:
            # A read returns on the first byte, or after TICK_S: the tick's pace.
            port = serial.serial_for_url(self.cfg.port, baudrate=self.cfg.baudrate,
                                         timeout=TICK_S, write_timeout=WRITE_TIMEOUT_S)
        except (serial.SerialException, OSError, ValueError):
            return False
        with self.lock:
            self.port = port
            self.core.link_up(time.monotonic())
            with contextlib.suppress(serial.SerialException, OSError):
                write_all(port, b"\x00", WRITE_TIMEOUT_S)  # end a partial frame the firmware holds
            self._write(self.core.output(time.monotonic()))
        self.link_epoch += 1
        self.node.health.count("connects")
        self.node.health.state, self.node.health.detail = "ok", f"connected to {self.cfg.port}"
        self.node.event("info", f"serial port {self.cfg.port} open")
        return True

    def _read_once(self) -> None:
        port = self.port
        if port is None:
            return
        try:
            data = port.read(max(1, port.in_waiting))
            if len(data) == 1 and port.in_waiting:
                # Woken by a frame's first byte: the rest is there too, so take it in this
                # pass instead of a second one (half the loop's passes, each with its tick).
                data += port.read(port.in_waiting)
        except (serial.SerialException, OSError, TypeError) as e:
            # TypeError: pyserial on a pty whose other side went away can fail inside read()
            with self.lock:
                self._lost(f"read failed: {e}")
            return
        stamp = time.time_ns()
        stats = self.core.decoder.stats
        bad_before = stats.bad_frames
        with self.lock:
            now = time.monotonic()
            frames = self.core.on_bytes(data) if data else []
            if self.core.received(len(frames), now):
                self._lost(f"no telemetry for {self.cfg.rx_stall_s:.1f} s")
                return
            passed = [self.core.pass_on(frame, gap, now) for frame, gap in frames]
        for (frame, gap), publish in zip(frames, passed, strict=True):
            if not publish:
                continue
            self.enc_pub.put(EncoderSample(
                stamp_ns=stamp, seq=frame.seq, mcu_time_us=frame.t_us, left_counts=frame.left,
                right_counts=frame.right, status=frame.status, dropped=gap,
                link_epoch=self.link_epoch))
        h = self.node.health
        h.count("frames_in", len(frames))
        if stats.bad_frames != bad_before:
            h.count("bad_frames", stats.bad_frames - bad_before)
        if frames and any(gap for _, gap in frames):
            h.count("dropped_frames", sum(gap for _, gap in frames))

    def _lost(self, why: str) -> None:
        """Call with the lock held: drop the port; the reader loop reconnects with backoff."""
        port, self.port = self.port, None
        if port is None:
            return
        with contextlib.suppress(serial.SerialException, OSError):
            port.close()
        self.node.health.count("disconnects")
        self.node.health.state, self.node.health.detail = "degraded", f"disconnected: {why}"
        self.node.event("warning", f"serial port {self.cfg.port} lost ({why}); holding neutral")


def start(node: Node, cfg: GatewayConfig) -> None:
    Gateway(node, cfg)


def main(argv: list[str] | None = None) -> int:
    return service_main("gateway", GatewayConfig, start, argv, __doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
