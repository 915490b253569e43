"""Goals given in `map` (REP-105), driven in `odom` (pure).

The control law and MPEPC work in `odom`, where the pose is smooth. Localization publishes the
`map` → `odom` correction (keys.TF) and its state (keys.LOC_POSE); a goal given in `map` is
re-expressed in `odom` with the newest correction on every control step, so the chair ends at
the place on the map however far odometry has drifted. Only a tracking localization is trusted
(hazard H33): none heard, initializing, lost, or silent for longer than `stale_s` is a reason
not to drive, said in words.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from autochair.geometry import Pose, compose, inverse

TRACKING = "tracking"


@dataclass
class MapFrame:
    stale_s: float = 2.5  # a parked chair's localization reports once a second
    correction: Pose | None = None  # map → odom
    state: str = ""  # localization's, from keys.LOC_POSE
    heard_t: float = -math.inf  # when the newest state came

    def on_correction(self, map_to_odom: Pose) -> None:
        self.correction = map_to_odom

    def on_state(self, state: str, now: float) -> None:
        self.state, self.heard_t = state, now

    def why_not(self, now: float) -> str:
        """"" if goals in `map` can be driven now, else why not (one line)."""
        if self.correction is None or self.heard_t == -math.inf:
            return "no localization heard (start it with a map: autochair up --map NAME)"
        if now - self.heard_t > self.stale_s:
            return f"localization silent for {now - self.heard_t:.1f} s"
        if self.state != TRACKING:
            return f"localization is {self.state}, not tracking"
        if not all(math.isfinite(c) for c in self.correction):
            # (it made every waypoint and zone NaN: the planner raised on every tick and the
            # goal hung, "driving", with no command; the zones were silently dropped)
            return "its map → odom correction is not finite"
        return ""

    def to_odom(self, p: Pose) -> Pose:
        """A `map` pose in `odom` (call only when `why_not` is "")."""
        assert self.correction is not None
        return compose(inverse(self.correction), p)
