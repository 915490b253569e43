"""The teleop key window (pygame-ce) in a real X session (Xvfb): keys held there drive, and
their key-up stops the chair at the next sample; focus lost is a release too.

Keys are typed with xdotool (XTEST, as a keyboard would). Needs Xvfb and xdotool (Debian
packages xvfb, xdotool); skipped with the reason otherwise.
"""

from __future__ import annotations

import os
import queue
import shutil
import subprocess
import time
from collections.abc import Iterator

import pytest

from autochair.commands.teleop_core import Teleop, TeleopLimits
from tests.helpers import stop_process, wait_for

pytest.importorskip("pygame", reason="pygame-ce (the `remote` extra) missing")
pytestmark = pytest.mark.slow


@pytest.fixture
def display(monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    if not (shutil.which("Xvfb") and shutil.which("xdotool")):
        pytest.skip("Xvfb and xdotool are needed (apt-get install xvfb xdotool)")
    r, w = os.pipe()
    xvfb = subprocess.Popen(["Xvfb", "-displayfd", str(w), "-screen", "0", "640x480x24",
                             "-nolisten", "tcp"], pass_fds=(w,), stderr=subprocess.DEVNULL)
    os.close(w)
    try:
        with os.fdopen(r) as f:
            number = f.readline().strip()  # Xvfb picks a free display and says which
        assert number, "Xvfb did not start"
        name = f":{number}"
        monkeypatch.setenv("DISPLAY", name)
        monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
        monkeypatch.delenv("SDL_VIDEODRIVER", raising=False)
        monkeypatch.setenv("PYGAME_HIDE_SUPPORT_PROMPT", "1")
        yield name
    finally:
        stop_process(xvfb)


def xdotool(*args: str) -> str:
    return subprocess.run(["xdotool", *args], capture_output=True, text=True, check=True,
                          timeout=10).stdout.strip()


def test_window_keys_drive_while_held_and_stop_on_key_up(display: str) -> None:
    from autochair.commands.teleop import Event, SdlInputs

    events: queue.Queue[Event] = queue.Queue()
    core = Teleop(TeleopLimits())
    inputs = SdlInputs(None, True, events)
    try:
        assert inputs.window is not None
        win = xdotool("search", "--sync", "--class", "autochair").splitlines()[0]
        xdotool("windowfocus", "--sync", win)

        def sample_tick() -> tuple[float, float] | None:
            now = time.monotonic()
            inputs.sample(core, now)
            return core.tick(now, True)

        wait_for(lambda: (sample_tick(), inputs.pg.key.get_focused())[1], 5, "window focus")
        xdotool("keydown", "w")
        wait_for(lambda: (c := sample_tick()) is not None and c[0] > 0, 5, "driving on w")
        out = []
        for _ in range(30):  # 1.5 s held: no key events at all (no auto-repeat needed)
            time.sleep(0.05)  # the sampling period itself
            out.append(sample_tick())
        assert all(c is not None and c[0] > 0 for c in out), out
        xdotool("keydown", "a")  # w+a: an arc, the same stream
        wait_for(lambda: (c := sample_tick()) is not None and c[1] > 0, 5, "arcing on w+a")
        assert core.presses == 1
        xdotool("keyup", "a", "keyup", "w")
        up = time.monotonic()
        # The key-up stops the chair at the first sample that sees it, not after a deadman.
        wait_for(lambda: sample_tick() == (0.0, 0.0), 2, "the stop on key-up")
        print(f"window key-up to zero command: {time.monotonic() - up:.3f} s")
        assert time.monotonic() - up < core.limits.deadman_s
        # Commands typed in the window reach the command queue (take over, speed, quit).
        xdotool("type", "--delay", "20", "t+")
        wait_for(lambda: (sample_tick(), events.qsize() >= 2)[1], 5, "the command keys")
        assert [events.get_nowait() for _ in range(2)] == ["t", "+"]
    finally:
        inputs.close()


def test_the_pad_reader_runs_headless_and_maps_every_configured_name(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """pygame-ce as installed by the `remote` extra: SDL's game-controller subsystem starts
    without a display (dummy video driver, no window), every [teleop.pad] name maps to an SDL
    constant, and with no pad attached a sample is a release (nothing drives)."""
    from autochair.commands.teleop import Event, SdlInputs
    from autochair.commands.teleop_core import PAD_AXES, PAD_BUTTONS, PadConfig

    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    monkeypatch.setenv("PYGAME_HIDE_SUPPORT_PROMPT", "1")
    events: queue.Queue[Event] = queue.Queue()
    core = Teleop(TeleopLimits())
    inputs = SdlInputs(PadConfig(), False, events)
    try:
        assert inputs.window is None
        assert set(inputs._axes) == set(PAD_AXES) and set(inputs._buttons) == set(PAD_BUTTONS)
        assert len(set(inputs._axes.values())) == len(PAD_AXES)
        assert len(set(inputs._buttons.values())) == len(PAD_BUTTONS)
        if inputs.pad is not None:
            pytest.skip(f"a real pad is attached ({inputs.pad_name}): not touching it")
        for i in range(5):
            inputs.sample(core, i * 0.05)
            assert core.tick(i * 0.05, True) is None
    finally:
        inputs.close()
