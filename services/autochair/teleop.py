"""Teleop logic (pure: no Zenoh, no tty; times passed in, monotonic seconds).

Input is a stream of (v, ω) requests in [-1, 1] (keyboard auto-repeat or a gamepad's axes).
DEADMAN: when no input came for `deadman_s` or the link to the chair is lost, `tick` yields ONE
zero command and then nothing, so the chair's own stale-command timeout also holds it still.
Speed limits: requests are scaled by `max_v_mps` / `max_omega_radps` and the current `scale`.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class TeleopLimits:
    max_v_mps: float = 0.6  # forward; reverse is half of it (chairs reverse slowly)
    max_omega_radps: float = 0.8
    deadman_s: float = 0.3  # > keyboard auto-repeat period; set repeat delay ≤ 250 ms


# keyboard: (v, ω) unit requests; arrows arrive as escape sequences mapped by the reader
KEYMAP: dict[str, tuple[float, float]] = {
    "w": (1.0, 0.0), "s": (-1.0, 0.0), "a": (0.0, 1.0), "d": (0.0, -1.0),
    "q": (1.0, 1.0), "e": (1.0, -1.0), "up": (1.0, 0.0), "down": (-1.0, 0.0),
    "left": (0.0, 1.0), "right": (0.0, -1.0), " ": (0.0, 0.0),
}


class Teleop:
    def __init__(self, limits: TeleopLimits | None = None) -> None:
        self.limits = limits or TeleopLimits()
        self.scale = 0.5  # fraction of the limits; +/- change it
        self._want = (0.0, 0.0)
        self._last_input = -1e18
        self._sending = False
        self.deadman_stops = 0
        self.presses = 0  # deadman presses: each begins a new command stream (a deliberate act)

    def request(self, v_unit: float, omega_unit: float, now: float) -> None:
        """An input event: the wanted motion as fractions of the limits."""
        self._want = (max(-1.0, min(1.0, v_unit)), max(-1.0, min(1.0, omega_unit)))
        self._last_input = now

    def faster(self, up: bool) -> None:
        self.scale = min(1.0, max(0.1, round(self.scale + (0.1 if up else -0.1), 2)))

    def command(self) -> tuple[float, float]:
        v, w = self._want
        vmax = self.limits.max_v_mps * (1.0 if v >= 0 else 0.5)
        return v * vmax * self.scale, w * self.limits.max_omega_radps * self.scale

    def tick(self, now: float, link_ok: bool) -> tuple[float, float] | None:
        """The command to publish now, or None to publish nothing."""
        live = link_ok and now - self._last_input <= self.limits.deadman_s
        if live:
            if not self._sending:
                self.presses += 1
            self._sending = True
            return self.command()
        if self._sending:  # released or link lost: one explicit zero, then silence
            self._sending = False
            self._want = (0.0, 0.0)
            self.deadman_stops += 1
            return (0.0, 0.0)
        return None
