"""The live dashboard's state and rendering (pure: no Zenoh, times passed in).

`autochair monitor` feeds it liveliness changes and decoded messages and prints `render(now)`.
"""

from __future__ import annotations

import math
from collections import deque

from autochair_msgs import Health, LaserScan, LogEvent, Odometry

FAULT_LEVELS = ("warning", "error", "fatal")


class MonitorState:
    def __init__(self, expected: list[str], faults_kept: int = 6) -> None:
        self.expected = list(expected)  # services a deployed chair should have
        self.alive: set[str] = set()
        self.health: dict[str, tuple[float, Health]] = {}
        self.odom: tuple[float, Odometry] | None = None
        self.scan: tuple[float, LaserScan] | None = None
        self.faults: deque[LogEvent] = deque(maxlen=faults_kept)

    def on_alive(self, service: str, up: bool) -> None:
        (self.alive.add if up else self.alive.discard)(service)

    def on_health(self, h: Health, now: float) -> None:
        self.health[h.service] = (now, h)

    def on_odom(self, o: Odometry, now: float) -> None:
        self.odom = (now, o)

    def on_scan(self, s: LaserScan, now: float) -> None:
        self.scan = (now, s)

    def on_log(self, e: LogEvent) -> None:
        if e.level in FAULT_LEVELS:
            self.faults.append(e)

    def render(self, now: float, stale_s: float = 3.0) -> str:
        names = self.expected + sorted((self.alive | set(self.health)) - set(self.expected))
        lines = ["SERVICE       LIVE  STATE      UPTIME   LAST FAULT"]
        for n in names:
            seen = self.health.get(n)
            h = seen[1] if seen and now - seen[0] < stale_s else None
            lines.append(f"{n:<13} {'up' if n in self.alive else 'DOWN':<5} "
                         f"{h.state if h else '-':<10} "
                         f"{f'{h.uptime_s:.0f}s' if h else '-':>6}   "
                         f"{h.last_fault if h and h.last_fault else ''}"[:100].rstrip())
        lines.append("")
        if self.odom and now - self.odom[0] < stale_s:
            o = self.odom[1]
            lines.append(f"pose   x {o.x_m:+8.3f} m  y {o.y_m:+8.3f} m  "
                         f"yaw {math.degrees(o.yaw_rad):+7.1f} deg")
            lines.append(f"vel    v {o.v_mps:+6.3f} m/s  w {o.omega_radps:+6.3f} rad/s  "
                         f"odometer {o.distance_m:.2f} m")
        else:
            lines.append("pose   (no odometry)")
        lines.append(self._scan_line(now, stale_s))
        pid = self.health.get("pid")
        if pid and now - pid[0] < stale_s and pid[1].detail:
            lines.append(f"drive  {pid[1].detail}"[:110])  # who owns it, or why it is stopped
        lines.append("")
        lines.append("faults" + ("" if self.faults else "  (none)"))
        lines += [f"  {e.service}: {e.level}: {e.message}"[:110] for e in self.faults]
        return "\n".join(lines)

    def _scan_line(self, now: float, stale_s: float) -> str:
        if not self.scan or now - self.scan[0] >= stale_s:
            return "scan   (no scan)"
        s = self.scan[1]
        valid = [(r, i) for i, r in enumerate(s.ranges_m) if math.isfinite(r)]
        if not valid:
            return f"scan   #{s.scan_seq}: {len(s.ranges_m)} beams, none valid"
        r, i = min(valid)
        bearing = math.degrees(s.angle_min_rad + i * s.angle_increment_rad)
        return (f"scan   #{s.scan_seq}: {len(valid)}/{len(s.ranges_m)} valid, "
                f"nearest {r:.2f} m at {bearing:+.0f} deg")
