"""`autochair teleop`'s loop and link driving the simulated chair from scripted inputs.

Terminal keys (a 600 ms first auto-repeat, then 30 Hz repeats) and a gamepad (its current
state sampled every tick: a steady stick, the enable button held then let go; the e-stop
button) through the same loop the command runs. Goals measured from the recording (printed
with -s): no gap in the drive command while the input is held, the stop after release, and no
velocity step beyond the teleop ramp.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable, Collection, Mapping, Sequence

import pytest

from autochair.commands.teleop import Event, TeleopLink, loop, status_text
from autochair.commands.teleop_core import PadConfig, Teleop, TeleopConfig
from autochair.launcher import Launcher
from autochair.runtime.client import Publisher
from autochair_msgs import EStopAssert, keys
from tests.helpers import Recorder, client_session, pid_ready, wait_for
from tests.test_teleop_foxglove import CFG, DRIVE_CHAIN, STALE_S, Chair, stream_figures

pytestmark = pytest.mark.slow

PAD = PadConfig()


class Laptop:
    """The teleop loop as `autochair teleop` runs it, on its own session and thread."""

    def __init__(self, hub: str, samplers: Sequence[Callable[[float], None]] = ()) -> None:
        self.session = client_session(hub)
        self.core = Teleop(TeleopConfig().limits())
        self.link = TeleopLink(self.session, self.core, by="test")
        self.events: queue.Queue[Event] = queue.Queue()
        self.stop = threading.Event()
        self.thread = threading.Thread(target=loop, args=(
            self.link, self.events, self.stop, CFG.rate_hz, None, samplers), daemon=True)

    def start(self) -> None:
        wait_for(lambda: self.link.link_ok, 10, "the PID's token seen by the laptop")
        self.thread.start()

    def take_over(self, chair: Chair) -> None:
        """Start once the PID is ready and take the drive over (`t`), as a person would."""
        pid_ready(chair.session)
        self.start()
        self.events.put("t")
        wait_for(chair.handed_to_teleop, 10, "the drive handed to teleop")

    def close(self) -> None:
        self.stop.set()
        self.thread.join(timeout=5)
        self.session.close()


def check(figs: dict[str, float], chair: Chair, first_ms: float, last_ms: float,
          stop_within_s: float) -> None:
    print(", ".join(f"{k} {v:.3f}" for k, v in figs.items() if not k.endswith("_ns")))
    assert figs["max_gap_s"] < 2.0 / CFG.rate_hz, "a gap in the drive command"
    assert figs["stop_after_release_s"] <= stop_within_s
    assert figs["steps_beyond_ramp"] == 0, "a step beyond the ramp"
    status = [(m.stamp_ns, m) for m in chair.pid.messages()]
    on = [m for t, m in status if first_ms * 1e6 + 0.3e9 <= t <= last_ms * 1e6]
    assert on and all(m.active for m in on), "the PID stopped obeying while the input was held"
    def pid_off() -> int | None:
        return next((m.stamp_ns for m in chair.pid.messages() if m.stamp_ns > figs["zero_ns"]
                     and (not m.active or m.v_desired_mps == 0.0)), None)

    off = wait_for(pid_off, 3, "the PID stopping")
    pid_stop = (off - last_ms * 1e6) / 1e9
    print(f"PID desired zero or inactive {pid_stop:.3f} s after the release")
    assert pid_stop <= stop_within_s + STALE_S
    assert max(m.v_mps for m in chair.truth.messages()) > 0.15, "the chair did not drive"


def test_terminal_keys_drive_without_stop_go_and_stop_after_the_last_repeat(
        stack_factory: Callable[..., Launcher], hub: str) -> None:
    stack_factory(DRIVE_CHAIN)
    chair = Chair(hub)
    laptop = Laptop(hub)
    try:
        laptop.take_over(chair)
        # Hold "w": the press, the OS's 600 ms first-repeat delay, then 30 Hz repeats.
        times = [0.0, *[0.6 + i / 30 for i in range(60)]]
        t0 = time.monotonic()
        sent_ms: list[float] = []
        for t in times:
            time.sleep(max(0.0, t0 + t - time.monotonic()))  # pacing the key repeat itself
            laptop.events.put(("w", time.monotonic()))  # as the terminal reader stamps it
            sent_ms.append(time.time_ns() / 1e6)
        wait_for(lambda: any(c.v_mps == 0.0 for c in chair.cmds.messages()), 3, "the stop")
        figs = stream_figures(chair.cmds.messages(), {"first": sent_ms[0], "last": sent_ms[-1]})
        # ≤ 0.3 s after the last repeat (deadman 0.2 s + one 50 ms tick, + scheduling)
        check(figs, chair, sent_ms[0], sent_ms[-1], 0.3)
        assert laptop.core.presses == 1
    finally:
        laptop.close()
        chair.close()


def test_a_gamepad_sampled_every_tick_drives_steadily_and_its_buttons_stop(
        stack_factory: Callable[..., Launcher], hub: str) -> None:
    stack_factory(DRIVE_CHAIN)
    chair = Chair(hub)
    estop = Recorder(chair.session, keys.ESTOP_STATE)
    state: dict[str, tuple[Mapping[str, float], Collection[str]]] = {"now": ({}, set())}
    laptop: Laptop | None = None

    def sample(now: float) -> None:  # the pad's current state, read every tick
        assert laptop is not None
        laptop.core.pad(PAD, *state["now"], now)

    laptop = Laptop(hub, [sample])
    try:
        laptop.take_over(chair)
        pressed_ms = time.time_ns() / 1e6
        state["now"] = ({"lefty": -0.8, "leftx": 0.0}, {PAD.enable_button})  # steady stick
        time.sleep(1.2)  # the person holds the stick steady for a while
        state["now"] = ({"lefty": -0.8, "leftx": 0.1}, {PAD.enable_button, PAD.turbo_button})
        time.sleep(1.0)
        released_ms = time.time_ns() / 1e6
        state["now"] = ({"lefty": -0.8}, set())  # enable let go, the stick still pushed
        wait_for(lambda: any(c.v_mps == 0.0 for c in chair.cmds.messages()), 3, "the stop")
        figs = stream_figures(chair.cmds.messages(), {"first": pressed_ms,
                                                      "last": released_ms})
        check(figs, chair, pressed_ms, released_ms, 1 / CFG.rate_hz + 0.05)  # one period
        assert figs["v_max"] <= CFG.max_v_mps + 1e-9  # turbo within the caps
        # The e-stop button: a momentary press that latches the e-stop (active=False).
        state["now"] = ({}, {PAD.estop_button})
        wait_for(lambda: laptop is not None and laptop.link.estop_latched, 5,
                 "the e-stop latched by the pad's button")
        # The laptop saw the latch on its own subscription; this recorder's copy of the same
        # state may arrive a moment later (two subscribers, no common order).
        latched = wait_for(lambda: (m := estop.latest()) is not None and m.latched and m, 5,
                           "the latched state on the chair's side")
        assert any(c.source.startswith("teleop:") for c in latched.causes)
        assert laptop.core.estop_presses == 1
    finally:
        laptop.close()
        chair.close()


def test_the_status_line_says_why_the_pid_holds_a_press(
        stack_factory: Callable[..., Launcher], hub: str) -> None:
    """An e-stop latched by someone else (not this laptop's button): a press then drives
    nothing, and the status line says why instead of just "driving"."""
    stack_factory(DRIVE_CHAIN)
    chair = Chair(hub)
    laptop = Laptop(hub)
    try:
        laptop.take_over(chair)

        def holding(key: str) -> str:  # one key repeat (the OS's 30 Hz), then the status line
            laptop.events.put((key, time.monotonic()))
            return status_text(laptop.link, laptop.core, None, None)

        # Positive control: a free press drives, and says nothing of a hold.
        wait_for(lambda: "driving" in holding("w") and chair.truth.latest().v_mps > 0.1, 10,
                 "the press driving", interval=1 / 30)
        assert "HELD" not in holding("w")
        laptop.events.put(" ")  # let go (space: stop at once)
        Publisher(chair.session, keys.ESTOP_ASSERT, reliable=True).put(EStopAssert(
            stamp_ns=time.time_ns(), source="another laptop", reason="test", active=False))
        wait_for(lambda: (lambda m: m is not None and m.inhibit == "e-stop latched")(
            chair.pid.latest()), 5, "the e-stop latched at the PID")
        line = wait_for(lambda: (lambda t: t if "HELD BY THE PID: e-stop latched" in t else None)(
            holding("w")), 5, "the status line naming the hold", interval=1 / 30)
        assert "E-STOP LATCHED" not in line  # (that one is this laptop's own button)
    finally:
        laptop.close()
        chair.close()
