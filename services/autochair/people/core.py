"""A people tracker from laser scans, pure (time passed in, no I/O).

MPEPC plans around people at constant velocity (σ 0.2 m); in the simulator's evaluation they come
from ground truth, on a live chair only from this tracker. Per scan, in the planning frame:

1. **Not the map's.** Beams that hit within 0.2 m of a cell that is the map's are the
   map's (`StaticMap`, rebuilt with each grid): occupied cells, and
   cells never observed: a wall just come into view lies in cells the live map (a second
   behind) has not taken in yet, while a person walks where the laser has seen the floor.
   Unless they hit where the scan `moved_s` earlier saw past (`_Sweep.saw_past`): something
   moved in there. The live map takes in people too: someone pacing a line leaves hits along
   it faster than the map clears them (a parked chair's map takes one scan a second), and
   someone walking into view walks in cells never observed; either way nearly all their
   points lie near the map's cells (on the live stack a walker pacing 4.4 m ahead of the
   parked chair was reported in 35 % of its scans, 97 % with this). Someone standing still
   is still the map's.
2. **Segments.** The remaining points, in beam order, split where neighbours are more than
   `gap_m` apart or a map beam lies between; a segment of `min_points` or more no wider than
   `max_extent_m` is a detection. Detections closer than `merge_m` are one person (two legs).
   A person's centre lies behind the arc the laser sees: half the arc's width behind its
   nearest point.
3. **Tracks.** A constant-velocity Kalman filter per person (state x, y, vx, vy; white-noise
   acceleration `accel_std`; measurement σ `meas_std_m`); greedy nearest association within
   `gate_m` of the prediction; a track is reported after `confirm` hits and dropped when
   unseen for `coast_s`, or at once when unseen in the first scan with a map: before it every
   point was a candidate, walls too (the inner face of a side room's wall seen through its
   doorway is a person's width), and the map now says what it saw is the map's.

Why this and not a library: the segment-and-track scheme of ROS's `leg_detector` /
`spencer_people_tracking` without their trained classifiers, which need a real laser's data;
everything here is ~200 lines of numpy that the evaluation (`python -m bench people`) measures.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from scipy import ndimage

from autochair.geometry import Pose, sweep_poses
from autochair.mapping.core import OdomBuffer
from autochair_msgs import OccupancyGrid, Odometry, TrackedPerson

F64 = npt.NDArray[np.float64]


# Occupancy (percent) from which a cell of the live map counts as the map's for the tracker:
# lower than the planner's 65, so that a wall seen at a grazing angle (its cells hit and
# passed in turn, ~50–60 %) is the map's, while a cell a person has left is free again after
# about half a second of beams through it (log odds −0.4 a scan). Never observed (255) counts
# as the map's too.
STATIC_PCT = 45


@dataclass(frozen=True)
class TrackerParams:
    gap_m: float = 0.3  # neighbouring points further apart start a new segment
    min_points: int = 3
    max_extent_m: float = 0.9  # a wider segment is furniture or an unmapped wall
    merge_m: float = 0.45  # detections closer than this are one person (legs)
    gate_m: float = 0.7  # association: a detection within this of a track's prediction
    confirm: int = 3  # hits before a track is reported
    coast_s: float = 0.5  # a track unseen this long is dropped
    accel_std_mps2: float = 1.5  # the filter's process noise (people turn and stop)
    meas_std_m: float = 0.06
    radius_m: float = 0.25  # reported radius, at least
    # Moved in (`_Sweep.saw_past`): the scan `moved_s` ago saw at least `moved_m` past the
    # point on every beam within `moved_tol_m` + `moved_tol_rad` of its bearing (what odometry
    # may be off by between the two scans; on the simulated stack ~2 cm and 0.6° in a turn).
    moved_s: float = 1.0
    moved_m: float = 0.3
    moved_tol_m: float = 0.1
    moved_tol_rad: float = 0.0175


def _key(static: npt.NDArray[np.bool_], *geometry: float) -> bytes:
    return static.tobytes() + repr((static.shape, *geometry)).encode()


@dataclass
class StaticMap:
    """Which cells lie within `near_m` of a cell that is the map's: occupied, or never
    observed (a wall just come into view is in cells the live map has not taken in yet); off
    the grid counts as never observed. A box max-filter of the grid (5 ms for 40 × 20 m at
    5 cm, where an exact distance transform took 30-80 ms a grid)."""

    near: npt.NDArray[np.bool_]  # (H, W), row = y
    resolution_m: float
    origin_x_m: float
    origin_y_m: float
    key: bytes = b""  # what it was made of (from_grid: the same again is not redone)

    @classmethod
    def of(cls, static: npt.NDArray[np.bool_], resolution_m: float, origin_x_m: float,
           origin_y_m: float, near_m: float = 0.2) -> StaticMap:
        size = 2 * math.ceil(near_m / resolution_m - 1e-9) + 1
        near = ndimage.maximum_filter(static.view(np.uint8), size=size).astype(np.bool_)
        return cls(near, resolution_m, origin_x_m, origin_y_m,
                   _key(static, resolution_m, origin_x_m, origin_y_m, near_m))

    @classmethod
    def from_grid(cls, msg: OccupancyGrid, near_m: float = 0.2,
                  reuse: StaticMap | None = None) -> StaticMap:
        """From the live map: a cell is the map's unless it has been seen free (p <
        `STATIC_PCT`, not 255). `reuse` is returned if it was made of the same cells (a parked
        chair's map, republished every second, settles: its filter is not redone)."""
        data = np.frombuffer(msg.data, dtype=np.uint8).reshape(msg.height, msg.width)
        static = data >= STATIC_PCT
        if reuse is not None and reuse.key == _key(static, msg.resolution_m, msg.origin_x_m,
                                                   msg.origin_y_m, near_m):
            return reuse
        return cls.of(static, msg.resolution_m, msg.origin_x_m, msg.origin_y_m, near_m)

    def is_near(self, pts: F64) -> npt.NDArray[np.bool_]:
        """Per (N, 2) point: whether it lies near what is the map's (off the grid: yes)."""
        ij = np.floor((pts - (self.origin_x_m, self.origin_y_m)) / self.resolution_m)
        col, row = ij[:, 0].astype(np.int64), ij[:, 1].astype(np.int64)
        h, w = self.near.shape
        inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
        out = np.ones(len(pts), np.bool_)
        out[inside] = self.near[row[inside], col[inside]]
        return out


@dataclass(frozen=True)
class _Sweep:
    """A past scan as the rays it cast: how far each beam saw, from where."""

    t: float
    ox: F64  # (N,) the laser's position at each beam
    oy: F64
    angle: F64  # (N,) each beam's direction, increasing from angle[0] (unwrapped)
    reach: F64  # (N,) how far it saw: 0 for an invalid beam (no return proves nothing)

    @classmethod
    def of(cls, t: float, pts: F64, rays: tuple[F64, F64, F64]) -> _Sweep:
        ox, oy, angle = rays
        reach = np.hypot(pts[:, 0] - ox, pts[:, 1] - oy)
        return cls(t, ox, oy, np.asarray(angle, np.float64),
                   np.where(np.isfinite(reach), reach, 0.0))

    def saw_past(self, pts: F64, p: TrackerParams) -> npt.NDArray[np.bool_]:
        """Per (N, 2) point: whether every beam of this sweep within the tolerance of its
        bearing saw at least `moved_m` past it (free space then, so something moved in since;
        a static surface stops at least one of those beams at or before it)."""
        n = len(self.angle)
        mid = n // 2
        dx, dy = pts[:, 0] - self.ox[mid], pts[:, 1] - self.oy[mid]
        dist = np.hypot(dx, dy)
        rel = np.mod(np.arctan2(dy, dx) - self.angle[0], 2 * math.pi)
        half = np.arctan2(p.moved_tol_m, np.maximum(dist, 1e-6)) + p.moved_tol_rad
        span = self.angle - self.angle[0]
        lo = np.searchsorted(span, rel - half)
        hi = np.searchsorted(span, rel + half, side="right")
        inside = (rel - half >= 0.0) & (rel + half <= span[-1]) & (hi > lo)
        lo, hi = lo[inside], hi[inside]
        # The least reach over beams lo..hi−1 (a sparse table: level k holds the least of the
        # 2^k beams from each; two overlapping runs of 2^k cover any window).
        levels = [self.reach]
        while 2 ** len(levels) <= n:
            h = 2 ** (len(levels) - 1)
            levels.append(np.minimum(levels[-1][:-h], levels[-1][h:]))
        table = np.full((len(levels), n), np.inf)
        for k, level in enumerate(levels):
            table[k, :level.size] = level
        k = np.floor(np.log2(hi - lo)).astype(np.int64)
        least = np.minimum(table[k, lo], table[k, hi - 2 ** k])
        past = np.zeros(len(pts), np.bool_)
        past[inside] = least >= dist[inside] + p.moved_m
        return past


@dataclass
class _Track:
    track_id: int
    x: F64  # (4,) x, y, vx, vy
    cov: F64  # (4, 4)
    t: float  # time of the state
    seen_t: float
    hits: int = 1
    radius_m: float = 0.25

    def predict(self, t: float, accel_std: float) -> None:
        dt = t - self.t
        if dt <= 0:
            return
        f = np.eye(4)
        f[0, 2] = f[1, 3] = dt
        g = np.array([[dt * dt / 2, 0], [0, dt * dt / 2], [dt, 0], [0, dt]])
        self.x = f @ self.x
        self.cov = f @ self.cov @ f.T + accel_std ** 2 * (g @ g.T)
        self.t = t

    def correct(self, z: F64, meas_std: float) -> None:
        h = np.zeros((2, 4))
        h[0, 0] = h[1, 1] = 1.0
        s = h @ self.cov @ h.T + np.eye(2) * meas_std ** 2
        k = self.cov @ h.T @ np.linalg.inv(s)
        self.x = self.x + k @ (z - h @ self.x)
        self.cov = (np.eye(4) - k @ h) @ self.cov


@dataclass
class PeopleTracker:
    p: TrackerParams = field(default_factory=TrackerParams)
    static: StaticMap | None = None  # None: no map yet, every point is a candidate
    _tracks: list[_Track] = field(default_factory=list)
    _next_id: int = 1
    _sweeps: deque[_Sweep] = field(default_factory=deque)  # the last `moved_s` and one more
    _mapless: bool = True  # the last scan had no map

    def detect(self, pts: F64, origin: tuple[float, float], before: _Sweep | None = None
               ) -> F64:
        """(K, 3) detections x, y, half-extent from scan points `pts` (N, 2, beam order,
        invalid beams NaN) seen from the laser at `origin`, all in the map's frame; a point
        `before` saw past is not the map's."""
        p = self.p
        valid = np.isfinite(pts).all(axis=1)
        free = valid
        if self.static is not None and valid.any():
            near = np.zeros(len(pts), dtype=np.bool_)
            near[valid] = self.static.is_near(pts[valid])
            if before is not None and near.any():
                near[near] = ~before.saw_past(pts[near], p)
            free = valid & ~near
        # Segment boundaries: a map point or an invalid beam between, or a jump.
        idx = np.flatnonzero(free)
        if idx.size < p.min_points:
            return np.zeros((0, 3))
        q = pts[idx]
        jump = np.hypot(*(np.diff(q, axis=0).T)) > p.gap_m
        broken = np.diff(idx) > 1  # (a skipped beam: invalid or the map's)
        starts = np.flatnonzero(np.concatenate(([True], jump | broken)))
        ends = np.append(starts[1:], len(q))
        found = []
        for a, b in zip(starts, ends, strict=True):
            if b - a < p.min_points:
                continue
            seg = q[a:b]
            extent = float(np.hypot(*(seg[-1] - seg[0])))
            if extent > p.max_extent_m:
                continue
            # The centre: on the ray through the mean, half the width behind the nearest
            # point (a disc of radius R shows an arc about 2R wide).
            ray = seg.mean(axis=0) - origin
            unit = ray / max(float(np.hypot(*ray)), 1e-6)
            closest = float(np.min(np.hypot(*(seg - origin).T)))
            c = np.asarray(origin) + unit * (closest + extent / 2)
            found.append((c[0], c[1], extent / 2))
        return self._merge(np.array(found).reshape(-1, 3))

    def _merge(self, det: F64) -> F64:
        out: list[F64] = []
        for d in det:
            for i, o in enumerate(out):
                if math.hypot(d[0] - o[0], d[1] - o[1]) < self.p.merge_m:
                    out[i] = np.array(((o[0] + d[0]) / 2, (o[1] + d[1]) / 2,
                                       max(o[2], d[2])))
                    break
            else:
                out.append(d)
        return np.array(out).reshape(-1, 3)

    def update(self, pts: F64, origin: tuple[float, float], t: float,
               rays: tuple[F64, F64, F64] | None = None) -> list[TrackedPerson]:
        """One scan (see `detect`) at time `t` (s): the confirmed people. `rays`: each beam's
        laser x, y and direction (increasing), for the free-space test of the scans after."""
        p = self.p
        if self._sweeps and t < self._sweeps[-1].t:
            self._sweeps.clear()  # time went back: those scans are void
        while len(self._sweeps) > 1 and t - self._sweeps[1].t >= p.moved_s:
            self._sweeps.popleft()  # (the newest at least `moved_s` old is kept)
        old = self._sweeps[0] if self._sweeps else None
        before = old if old is not None and p.moved_s <= t - old.t <= 2 * p.moved_s else None
        if rays is not None:
            self._sweeps.append(_Sweep.of(t, pts, rays))
        det = self.detect(pts, origin, before)
        for tr in self._tracks:
            tr.predict(t, p.accel_std_mps2)
        pairs = sorted(
            (math.hypot(d[0] - tr.x[0], d[1] - tr.x[1]), i, j)
            for i, tr in enumerate(self._tracks) for j, d in enumerate(det))
        used_t: set[int] = set()
        used_d: set[int] = set()
        for dist, i, j in pairs:
            if dist > p.gate_m or i in used_t or j in used_d:
                continue
            used_t.add(i)
            used_d.add(j)
            tr = self._tracks[i]
            tr.correct(det[j, :2], p.meas_std_m)
            tr.seen_t, tr.hits = t, tr.hits + 1
            tr.radius_m = max(p.radius_m, float(det[j, 2]))
        for j, d in enumerate(det):
            if j not in used_d:
                cov = np.diag([p.meas_std_m ** 2] * 2 + [1.0, 1.0])  # speed unknown: ~1 m/s
                self._tracks.append(_Track(self._next_id, np.array([d[0], d[1], 0.0, 0.0]),
                                           cov, t, t, radius_m=max(p.radius_m, float(d[2]))))
                self._next_id += 1
        # (a track of the map's points is not coasted on into the map: see the docstring)
        first_map, self._mapless = self._mapless and self.static is not None, self.static is None
        self._tracks = [tr for tr in self._tracks
                        if t - tr.seen_t <= p.coast_s and not (first_map and tr.seen_t < t)]
        return self.people()

    def people(self) -> list[TrackedPerson]:
        return [TrackedPerson(track_id=tr.track_id, x_m=float(tr.x[0]), y_m=float(tr.x[1]),
                              vx_mps=float(tr.x[2]), vy_mps=float(tr.x[3]),
                              radius_m=tr.radius_m)
                for tr in self._tracks if tr.hits >= self.p.confirm]


def scan_points(ranges: F64, angle_min: float, angle_inc: float, range_min: float,
                range_max: float, laser_pose: tuple[float | F64, float | F64, float | F64]
                ) -> F64:
    """(N, 2) points of a scan in the frame of `laser_pose` (x, y, yaw of the laser in it:
    one pose, or one per beam), beam order kept; invalid beams (non-finite, outside the range
    window) are NaN."""
    r = np.asarray(ranges, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        r = np.where(np.isfinite(r) & (r >= range_min) & (r <= range_max), r, np.nan)
    x, y, yaw = laser_pose
    a = yaw + angle_min + angle_inc * np.arange(r.size)
    return np.column_stack((x + r * np.cos(a), y + r * np.sin(a)))


@dataclass
class ScanPeople:
    """The tracker fed as a service feeds it: scans placed by odometry, beam by beam, with the
    chair's laser `mount`."""

    mount: Pose
    tracker: PeopleTracker = field(default_factory=PeopleTracker)
    odom: OdomBuffer = field(default_factory=lambda: OdomBuffer(keep=200))
    max_dt_s: float = 0.1  # no odometry this close to the scan: skipped
    points: F64 | None = None  # the newest placed scan's points (odom, (M, 2); NaN: no return)

    def on_odom(self, msg: Odometry) -> None:
        self.odom.add(msg)

    def on_scan(self, stamp_ns: int, ranges: list[float], angle_min: float, angle_inc: float,
                range_min: float, range_max: float, time_increment_s: float = 0.0
                ) -> list[TrackedPerson] | None:
        """The confirmed people after this scan, in the odometry's frame; None when no
        odometry places it. Beam i is placed with the pose at its own time, stamp +
        i·`time_increment_s` (a chair turning at 0.9 rad/s turns 3.4° during a URG-04LX's
        sweep: 0.27 m at 4.5 m)."""
        end_ns = stamp_ns + round(time_increment_s * 1e9 * max(len(ranges) - 1, 0))
        dt_ns = round(self.max_dt_s * 1e9)
        first, last = self.odom.at(stamp_ns, dt_ns), self.odom.at(end_ns, dt_ns)
        if first is None or last is None:
            return None
        lx, ly, lyaw = sweep_poses(first, last, self.mount, len(ranges))
        pts = scan_points(np.asarray(ranges, dtype=np.float64), angle_min, angle_inc,
                          range_min, range_max, (lx, ly, lyaw))
        self.points = pts
        mid = len(ranges) // 2
        angle = lyaw + angle_min + angle_inc * np.arange(len(ranges))  # (lyaw: unwrapped)
        return self.tracker.update(pts, (float(lx[mid]), float(ly[mid])),
                                   (stamp_ns + end_ns) / 2e9, (lx, ly, angle))

