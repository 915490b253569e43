"""A virtual Xbox 360 pad (Linux uinput) read by `autochair teleop`'s pad reader (pygame-ce,
SDL2's game-controller mapping) into the teleop core: the real library, the real mapping.

Needs /dev/uinput (root, or the input group) and an SDL that sees the new /dev/input node
(devtmpfs or udev); skipped with the reason otherwise.
"""

from __future__ import annotations

import fcntl
import os
import queue
import struct
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from autochair.commands.teleop_core import PadConfig, Teleop, TeleopLimits
from tests.helpers import wait_for

pytest.importorskip("pygame", reason="pygame-ce (the `remote` extra) missing")
pytestmark = pytest.mark.slow

UINPUT = Path("/dev/uinput")
# linux/input-event-codes.h
EV_SYN, EV_KEY, EV_ABS = 0x00, 0x01, 0x03
BTN_A, BTN_B, BTN_X, BTN_Y, BTN_TL, BTN_TR = 0x130, 0x131, 0x133, 0x134, 0x136, 0x137
BTN_SELECT, BTN_START, BTN_MODE, BTN_THUMBL, BTN_THUMBR = 0x13A, 0x13B, 0x13C, 0x13D, 0x13E
ABS_X, ABS_Y, ABS_Z, ABS_RX, ABS_RY, ABS_RZ, ABS_HAT0X, ABS_HAT0Y = 0, 1, 2, 3, 4, 5, 0x10, 0x11
BUTTONS = (BTN_A, BTN_B, BTN_X, BTN_Y, BTN_TL, BTN_TR, BTN_SELECT, BTN_START, BTN_MODE,
           BTN_THUMBL, BTN_THUMBR)
AXES = {ABS_X: (-32768, 32767), ABS_Y: (-32768, 32767), ABS_RX: (-32768, 32767),
        ABS_RY: (-32768, 32767), ABS_Z: (0, 255), ABS_RZ: (0, 255), ABS_HAT0X: (-1, 1),
        ABS_HAT0Y: (-1, 1)}


def _iow(nr: int, size: int) -> int:  # linux/ioctl.h _IOW('U', nr, size)
    return (1 << 30) | (size << 16) | (ord("U") << 8) | nr


UI_DEV_CREATE, UI_DEV_DESTROY = (ord("U") << 8) | 1, (ord("U") << 8) | 2
UI_DEV_SETUP, UI_ABS_SETUP = _iow(3, 92), _iow(4, 28)
UI_SET_EVBIT, UI_SET_KEYBIT, UI_SET_ABSBIT = _iow(100, 4), _iow(101, 4), _iow(103, 4)


class VirtualPad:
    """An Xbox 360 pad (045e:028e, as the xpad driver reports one) on uinput."""

    def __init__(self) -> None:
        self.fd = os.open(UINPUT, os.O_WRONLY | os.O_NONBLOCK)
        try:
            for ev in (EV_KEY, EV_ABS):
                fcntl.ioctl(self.fd, UI_SET_EVBIT, ev)
            for b in BUTTONS:
                fcntl.ioctl(self.fd, UI_SET_KEYBIT, b)
            for code, (lo, hi) in AXES.items():
                fcntl.ioctl(self.fd, UI_SET_ABSBIT, code)
                flat = 128 if hi > 1000 else 0
                fcntl.ioctl(self.fd, UI_ABS_SETUP,
                            struct.pack("=HxxiiiiII", code, 0, lo, hi, 16, flat, 0)[:28])
            name = b"Microsoft X-Box 360 pad (autochair test)"
            fcntl.ioctl(self.fd, UI_DEV_SETUP, struct.pack("=HHHH80sI", 0x03, 0x045E, 0x028E,
                                                           0x0114, name, 0))
            fcntl.ioctl(self.fd, UI_DEV_CREATE)
        except OSError:
            os.close(self.fd)
            raise

    def emit(self, *events: tuple[int, int, int]) -> None:
        t = time.time()
        for type_, code, value in (*events, (EV_SYN, 0, 0)):
            os.write(self.fd, struct.pack("=qqHHi", int(t), int(t % 1 * 1e6), type_, code,
                                          value))

    def close(self) -> None:
        fcntl.ioctl(self.fd, UI_DEV_DESTROY)
        os.close(self.fd)


@pytest.fixture
def pad() -> Iterator[VirtualPad]:
    if not sys.platform.startswith("linux"):
        pytest.skip("uinput is Linux only")
    if not UINPUT.exists():
        pytest.skip("no /dev/uinput: this kernel has no uinput (`modprobe uinput` as root "
                    "where it is a module)")
    try:
        p = VirtualPad()
    except PermissionError:
        pytest.skip("no write access to /dev/uinput (root, or the input group)")
    try:
        yield p
    finally:
        p.close()


def test_a_virtual_xbox_pad_drives_the_core_through_sdl(
        pad: VirtualPad, monkeypatch: pytest.MonkeyPatch) -> None:
    for var, value in (("SDL_VIDEODRIVER", "dummy"), ("SDL_JOYSTICK_DISABLE_UDEV", "1"),
                       ("PYGAME_HIDE_SUPPORT_PROMPT", "1"),
                       ("SDL_JOYSTICK_ALLOW_BACKGROUND_EVENTS", "1")):
        monkeypatch.setenv(var, value)
    from autochair.commands.teleop import Event, SdlInputs

    cfg = PadConfig()
    core = Teleop(TeleopLimits(), scale=0.5)
    events: queue.Queue[Event] = queue.Queue()
    inputs = SdlInputs(cfg, False, events)
    try:
        t0 = time.monotonic()

        def seen() -> bool:
            inputs.sample(core, time.monotonic())
            return inputs.pad is not None

        deadline = time.monotonic() + 5
        while not seen() and time.monotonic() < deadline:
            time.sleep(0.05)  # SDL finds new devices as it pumps its events
        if inputs.pad is None:
            pytest.skip("SDL sees no game controller for the uinput device (no /dev/input "
                        "node: neither devtmpfs nor udev in this container)")
        assert "360" in inputs.pad_name or "X-Box" in inputs.pad_name, inputs.pad_name
        # Stick 80 % up, LB (enable) held: a command every tick while nothing changes.
        pad.emit((EV_ABS, ABS_Y, -26214), (EV_KEY, BTN_TL, 1))

        def sample_tick() -> tuple[float, float] | None:
            now = time.monotonic()
            inputs.sample(core, now)
            return core.tick(now, True)

        wait_for(lambda: (c := sample_tick()) is not None and c[0] > 0, 5, "the pad driving")
        out = []
        for _ in range(20):  # 1 s at 20 Hz: a steady stick sends no events, yet it drives
            time.sleep(0.05)  # the sampling period itself
            out.append(sample_tick())
        assert all(c is not None and c[0] > 0 for c in out), out
        assert core.presses == 1
        pad.emit((EV_KEY, BTN_TL, 0))  # enable released
        stop = wait_for(lambda: sample_tick() == (0.0, 0.0) or None, 2, "the stop")
        assert stop is not None
        pad.emit((EV_KEY, BTN_B, 1))  # the e-stop button
        wait_for(lambda: (sample_tick(), core.estop_presses == 1)[1], 2, "the e-stop press")
        assert time.monotonic() - t0 < 30
    finally:
        inputs.close()
