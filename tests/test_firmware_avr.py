"""The real firmware: avr-gcc build, then simavr in real time with the real gateway on its UART.

The harness (firmware/autochair_arduino/sim/simavr_harness.c) bridges UART0 to a pty, drives
both encoders, and prints the MCP4922 outputs with simulated-time stamps, so the watchdog timing
is measured in MCU time, independent of how loaded this machine is.
"""

from __future__ import annotations

import itertools
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import msgspec
import pytest
import serial
import zenoh

from autochair.launcher import free_port
from autochair.protocol import arduino as proto
from autochair_msgs import JoystickCommand, keys
from tests.firmware_lib import build_firmware
from tests.helpers import Recorder, session_when_up, stop_process, wait_for

LEFT_CPS, RIGHT_CPS = 1000, -2000  # encoder rates driven by the harness, counts/s


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    return build_firmware(tmp_path_factory.mktemp("avr"))


def test_avr_build_fits_atmega328p(built: tuple[Path, Path]) -> None:
    elf, _ = built
    out = subprocess.run(["avr-size", str(elf)], check=True, capture_output=True,
                         text=True).stdout
    text, data, bss = (int(v) for v in out.splitlines()[1].split()[:3])
    assert text + data <= 32256 - 1024, out  # 32 KiB flash less optiboot (512 B), with margin
    assert data + bss <= 2048 - 768, out  # leave >= 768 B of the 2 KiB SRAM for the stack
    syms = subprocess.run(["avr-nm", str(elf)], check=True, capture_output=True,
                          text=True).stdout
    for vector in ("__vector_4", "__vector_11", "__vector_12", "__vector_18", "__vector_19"):
        assert vector in syms, \
            f"{vector} (PCINT1, TIMER1_COMPA/B, USART_RX, USART_UDRE) missing"


class Harness:
    """simavr running the firmware; collects its stdout event lines."""

    def __init__(self, harness: Path, elf: Path) -> None:
        self.proc = subprocess.Popen(
            [str(harness), str(elf), "--left-cps", str(LEFT_CPS), "--right-cps", str(RIGHT_CPS)],
            stdout=subprocess.PIPE, text=True)
        assert self.proc.stdout is not None
        first = self.proc.stdout.readline().split()
        assert first[:1] == ["PTY"], f"harness said {first}"
        self.pty = first[1]
        self.lines: list[str] = []
        self._lock = threading.Lock()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            with self._lock:
                self.lines.append(line.strip())

    def events(self, kind: str) -> list[list[int]]:
        with self._lock:
            return [[int(v) for v in ln.split()[1:]] for ln in self.lines if ln.startswith(kind)]






@pytest.fixture
def rig(built: tuple[Path, Path]) -> Iterator[tuple[Harness, zenoh.Session,
                                                    subprocess.Popen[bytes]]]:
    elf, harness_bin = built
    hub = f"tcp/127.0.0.1:{free_port()}"
    procs: list[subprocess.Popen[bytes] | subprocess.Popen[str]] = []
    session: zenoh.Session | None = None
    try:
        harness = Harness(harness_bin, elf)
        procs.append(harness.proc)
        procs.append(subprocess.Popen([sys.executable, "-m", "autochair.router.node",
                                      "--listen", hub]))
        session = session_when_up(hub)
        gateway = subprocess.Popen([sys.executable, "-m", "autochair.gateway.node", "--connect",
                                    hub, "--set", f"port={harness.pty}",
                                    "--set", "require_estop=false"])
        procs.append(gateway)
        yield harness, session, gateway
    finally:
        if session is not None:
            session.close()
        for p in reversed(procs):
            stop_process(p)


@pytest.mark.slow
def test_gateway_talks_to_simulated_firmware(
        rig: tuple[Harness, zenoh.Session, subprocess.Popen[bytes]]) -> None:
    harness, session, gateway = rig
    enc = Recorder(session, keys.ENCODERS)
    # Telemetry from the real firmware reaches Zenoh through the real gateway.
    wait_for(lambda: any(not m.status & proto.ST_BOOT for m in enc.messages()), 30,
             "telemetry past the firmware's boot second")
    start = len(enc.messages()) - 1
    first = enc.messages()[start]
    wait_for(lambda: enc.latest().mcu_time_us - first.mcu_time_us > 1_000_000, 20,
             "1 s of MCU time")
    msgs = enc.messages()[start:]
    last = msgs[-1]
    dt = (last.mcu_time_us - first.mcu_time_us) / 1e6
    # The key table's rate (100 Hz, 10 ms apart on the MCU): AC_FRAME_US matches it.
    assert (last.seq - first.seq) % 65536 == round(dt * keys.DRIVE_RATE_HZ)
    periods = {b.mcu_time_us - a.mcu_time_us for a, b in itertools.pairwise(msgs)
               if b.seq == a.seq + 1}
    assert periods == {1_000_000 // keys.DRIVE_RATE_HZ}, periods
    assert sum(m.dropped for m in msgs) <= 2
    left_rate = proto.wrap_delta(first.left_counts, last.left_counts) / dt
    right_rate = proto.wrap_delta(first.right_counts, last.right_counts) / dt
    assert left_rate == pytest.approx(LEFT_CPS, rel=0.03)  # quadrature decoding, both ways
    assert right_rate == pytest.approx(RIGHT_CPS, rel=0.03)
    assert last.status & proto.ST_HOST_TIMEOUT == 0  # the gateway's keepalive feeds the watchdog
    assert harness.events("DAC")[-1][1:] == [2500, 2500]  # neutral until commanded

    # Drive: commands through Zenoh -> gateway -> UART -> firmware -> MCP4922 on SPI.
    pub = session.declare_publisher(keys.JOYSTICK.key)
    enc_ = msgspec.msgpack.Encoder()
    stop = threading.Event()

    def drive() -> None:
        while not stop.is_set():
            pub.put(enc_.encode(JoystickCommand(stamp_ns=time.time_ns(), longitudinal_v=3.0,
                                                angular_v=2.1)))
            stop.wait(0.02)

    driver = threading.Thread(target=drive, daemon=True)
    driver.start()
    try:
        wait_for(lambda: harness.events("DAC") and harness.events("DAC")[-1][1:] == [3000, 2100],
                 20, "DAC at 3.0 V / 2.1 V")
        wait_for(lambda: enc.latest().status & proto.ST_OUTPUT_ENABLED, 10, "ST_OUTPUT_ENABLED")
        idle_before = len(harness.events("HOSTIDLE"))
        # The host stops sending (process gone): the firmware must go neutral by itself.
        os.kill(gateway.pid, signal.SIGKILL)
        gateway.wait(timeout=10)
    finally:
        stop.set()
        driver.join(timeout=5)
    idle = wait_for(lambda: harness.events("HOSTIDLE")[idle_before:], 20, "host silence")
    last_rx_us = idle[0][0]
    neutral = wait_for(lambda: [e for e in harness.events("DAC")
                                if e[0] > last_rx_us and e[1:] == [2500, 2500]], 20,
                       "DAC back at neutral")
    delay_us = neutral[0][0] - last_rx_us
    phase_us = neutral[0][0] % (1_000_000 // keys.DRIVE_RATE_HZ)
    print(f"firmware neutral {delay_us} µs (MCU time) after the last host byte, "
          f"{phase_us} µs into a frame")
    # 200 ms watchdog, checked every half frame (5 ms); + the last frame still draining from the
    # UART (< 1.3 ms) + simavr's SPI model (~100 µs per byte, 4 bytes) before /LDAC.
    assert 200_000 <= delay_us <= 200_000 + 5_000 + 1_300 + 1_000, delay_us

    # And it says so on the wire: read the pty ourselves now that the gateway is gone.
    with serial.Serial(harness.pty, 115200, timeout=0.05) as port:
        dec = proto.FrameDecoder()
        frames: list[proto.Frame] = wait_for(lambda: dec.feed(port.read(256)), 10, "telemetry")
    tel = frames[-1]
    assert isinstance(tel, proto.Telemetry)
    assert tel.status & proto.ST_HOST_TIMEOUT and not tel.status & proto.ST_OUTPUT_ENABLED
