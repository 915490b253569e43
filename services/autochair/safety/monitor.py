"""The monitor's decisions around the sweep, pure (`now` monotonic seconds, passed in): which
limit to publish for a scan, the e-stop action, blind and fault changes, and health's verdict.
The node only wires these to Zenoh, counters and events."""

from __future__ import annotations

import math
from dataclasses import dataclass

from autochair.geometry import Pose
from autochair_msgs import OccupancyGrid

from .core import DIRECTIONS, EStopAction, Fault, Limit, MonitorState, SafetyCore, Scan, stop_limit
from .keepout import Keepout


@dataclass(frozen=True)
class ScanVerdict:
    published: Limit  # the limit to publish: the scan's, or a stop for a fault it cannot fix
    assessed: Limit  # the scan's own verdict
    estop: EStopAction
    imminent: bool
    imminent_changed: bool
    blind: tuple[str, ...]  # directions blind in this scan
    blind_changed: bool
    odometry_stale: bool  # assessed as if at rest: no fresh motion
    v: float  # the motion assessed (m/s)
    degraded: bool
    detail: str


@dataclass(frozen=True)
class TickVerdict:
    stop: Limit | None  # publish this stop (no fresh scan), else nothing
    faults: tuple[Fault, ...]
    changed: bool
    reason: str


class Monitor:
    def __init__(self, core: SafetyCore, stale_s: float, odometry_s: float, clear_hold_s: float,
                 frame_id: str, max_age_s: float = 0.35, skew_s: float = 0.1,
                 keepout: Keepout | None = None) -> None:
        self.core, self.odometry_s, self.frame_id = core, odometry_s, frame_id
        self.max_age_s, self.skew_s = max_age_s, skew_s
        self.state = MonitorState(stale_s=stale_s, clear_hold_s=clear_hold_s)
        self._motion = (0.0, 0.0, -math.inf)  # v, ω, when
        self._pose: Pose | None = None  # in odom
        self.keepout = keepout

    def on_odom(self, v: float, omega: float, now: float, pose: Pose | None = None) -> None:
        if not all(math.isfinite(x) for x in (v, omega, *(pose or ()))):
            # Unknown motion is no motion known: as stale odometry, not as a NaN path (a NaN
            # ω swept no arc, so a wall ahead read as clear) nor NaN zones (H10, H42).
            self._motion, self._pose = (0.0, 0.0, -math.inf), None
            return
        self._motion, self._pose = (v, omega, now), pose

    def on_correction(self, map_to_odom: Pose) -> None:
        """Localization's `map` → `odom` correction (places the keep-out zones)."""
        if self.keepout is not None:
            self.keepout.frame.on_correction(map_to_odom)

    def on_loc_state(self, state: str, mode: str, now: float) -> None:
        if self.keepout is not None:
            self.keepout.on_loc(state, mode, now)

    def on_loc_map(self, grid: OccupancyGrid) -> None:
        """Localization's map: the keep-out mask must have been drawn over it."""
        if self.keepout is not None:
            self.keepout.on_map(grid)

    def on_mount(self, error: str) -> tuple[Limit | None, bool]:
        """A tf_static check: a stop to publish at once when it disagrees, and whether
        agreement changed."""
        changed = self.state.on_mount(error)
        return (stop_limit(f"laser mount mismatch: {error}") if error else None), changed

    def source_lost(self) -> None:
        self.state.source_lost()

    def on_scan(self, scan: Scan, now: float, age_s: float = 0.0) -> ScanVerdict:
        """`age_s`: wall-clock now minus the scan's own stamp (the start of its sweep)."""
        v, w, t = self._motion
        stale = now - t > self.odometry_s
        if stale:
            v, w = 0.0, 0.0
        unseen, unplaced = None, ""
        if self.keepout is not None:  # H42: zones it cannot place are a stop (unknown: unsafe)
            p = self.core.p
            unseen, unplaced = self.keepout.points(None if stale else self._pose, now,
                                                   (p.front_m, p.rear_m, p.half_width_m))
        lim = (stop_limit(unplaced) if unplaced
               else self.core.assess(scan, v, w, self.frame_id, unseen))
        # A scan that arrives late (a backlog after a stall, a starved process) shows the world
        # as it was: judged as now it could clear a path a person has since stepped into (H38).
        if not -self.skew_s <= age_s <= self.max_age_s:
            kind = "old" if age_s > 0 else "future"
            lim = stop_limit(f"scan rejected: {kind}: its stamp is {age_s:+.2f} s from now "
                             f"(allowed −{self.skew_s:g} … +{self.max_age_s:g} s)", rejected=kind)
        st = self.state
        st.on_scan(now, lim.reason if lim.rejected else "")  # "scan rejected: why"
        # A rejected scan says nothing new about a collision: the previous verdict stands.
        imminent = st.imminent if lim.rejected else lim.imminent
        action, imminent_changed = st.estop(imminent, now)
        published = stop_limit(f"laser mount mismatch: {st.mount_error}") if st.mount_error \
            else lim
        min_valid = self.core.p.min_valid_fraction
        blind = tuple(n for n, f in zip(DIRECTIONS, lim.valid_fraction, strict=True)
                      if f is not None and f < min_valid)
        blind_changed = st.on_blind(blind)
        return ScanVerdict(published, lim, action, imminent, imminent_changed, blind,
                           blind_changed, stale, v,
                           published is not lim or bool(lim.rejected) or bool(lim.blind)
                           or bool(unplaced),
                           f"stop: {unplaced}" if unplaced else self._detail(published, lim))

    def tick(self, now: float) -> TickVerdict:
        silent = self.state.stale(now)
        faults, changed = self.state.poll(now)
        reason = self.state.reason(now)
        return TickVerdict(stop_limit(reason) if silent else None, faults, changed, reason)

    def _detail(self, published: Limit, lim: Limit) -> str:
        head = (f"fwd ≤ {published.v_fwd:.2f} rev ≤ {published.v_rev:.2f} (autonomy "
                f"{published.v_rev_autonomy:.2f}) m/s |ω| ≤ {published.omega:.2f} rad/s")
        if published.reason != lim.reason or lim.rejected:
            return f"stop: {published.reason}; {head}"
        parts = [f"nearest {lim.nearest_m:.2f} m; {head}", *lim.blind]
        if not lim.rear_seen:
            parts.append("rear unseen: autonomy may not reverse" if lim.v_rev_autonomy == 0
                         else f"rear unseen: autonomy reverses blind ≤ {lim.v_rev_autonomy:.2f}"
                              " m/s")
        if lim.unseen_radius_m > 0:
            parts.append(f"|ω| ≤ {lim.omega_unseen_cap:.2f} rad/s for the unseen footprint "
                         f"(R {lim.unseen_radius_m:.2f} m at {self.core.p.blind_speed_mps} m/s)")
        return "; ".join(parts)
