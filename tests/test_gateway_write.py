"""The gateway's serial write: a frame the port took is never reported as a lost link, and a
port with no room for it is (on a real pty)."""

from __future__ import annotations

import contextlib
import os
import select
import time
from collections.abc import Iterator

import pytest
import serial

from autochair.gateway.node import WRITE_TIMEOUT_S, write_all

FRAME = b"\x05frame\x00"


class Descheduled:
    """A monotonic clock that moves 1 s at every reading: as if the thread lost the CPU
    (or the GIL) between any two lines, as it can on a loaded machine."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        self.t += 1.0
        return self.t


@pytest.fixture
def pty_port() -> Iterator[tuple[serial.Serial, int]]:
    master, slave = os.openpty()
    port = serial.Serial(os.ttyname(slave), timeout=0.02, write_timeout=WRITE_TIMEOUT_S)
    os.close(slave)
    try:
        yield port, master
    finally:
        port.close()
        os.close(master)


def read_all(master: int, n: int) -> bytes:
    got, end = b"", time.monotonic() + 5.0
    while len(got) < n and select.select([master], [], [], max(end - time.monotonic(), 0))[0]:
        got += os.read(master, n - len(got))
    return got


def test_a_frame_the_port_took_is_not_a_write_timeout(pty_port: tuple[serial.Serial, int],
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    port, master = pty_port
    # Positive control: pyserial's own write raises "Write timeout" for a frame it sent.
    monkeypatch.setattr(serial.serialutil.Timeout, "TIME", staticmethod(Descheduled()))
    with pytest.raises(serial.SerialTimeoutException):
        port.write(FRAME)
    assert read_all(master, len(FRAME)) == FRAME
    write_all(port, FRAME, WRITE_TIMEOUT_S, clock=Descheduled())
    assert read_all(master, len(FRAME)) == FRAME


def test_a_port_with_no_room_is_a_write_timeout(pty_port: tuple[serial.Serial, int]) -> None:
    port, master = pty_port
    os.set_blocking(port.fileno(), False)
    taken, end = 0, time.monotonic() + 5.0
    # Fill the pty until it takes no more and stays so: the kernel moves bytes on to the far
    # side's line discipline after a write, which can make room again (CI's machine did).
    while True:
        with contextlib.suppress(BlockingIOError):
            while True:
                taken += os.write(port.fileno(), b"x" * 4096)
        if not select.select([], [port.fileno()], [], 0.2)[1]:
            break
        assert time.monotonic() < end, "the pty never filled"
    assert taken > 0
    t0 = time.monotonic()
    with pytest.raises(serial.SerialTimeoutException, match="not taken"):
        write_all(port, FRAME, WRITE_TIMEOUT_S)
    assert time.monotonic() - t0 >= WRITE_TIMEOUT_S
    # Room again (the far side reads): the same write goes through.
    assert len(read_all(master, taken)) == taken
    write_all(port, FRAME, WRITE_TIMEOUT_S)
    assert read_all(master, len(FRAME)) == FRAME
