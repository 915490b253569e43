"""One backoff for every retry loop (serial and lidar reconnects, the launcher's restarts). Pure:
the random draw is passed in."""

from __future__ import annotations


class Backoff:
    """Exponential backoff with jitter, capped: retries slow down to one per `max_s`, never a
    storm, yet a returning device is picked up within about `max_s`."""

    def __init__(self, base_s: float = 0.1, factor: float = 2.0, max_s: float = 1.0,
                 jitter: float = 0.25) -> None:
        self.base_s, self.factor, self.max_s, self.jitter = base_s, factor, max_s, jitter
        self.attempt = 0

    def reset(self) -> None:
        self.attempt = 0

    def next_s(self, u: float) -> float:
        """Delay before the next attempt; `u` uniform in [0, 1) (passed in: pure)."""
        d = min(self.max_s, self.base_s * self.factor ** self.attempt)
        self.attempt += 1
        return d * (1.0 - self.jitter + 2.0 * self.jitter * u)
