"""Mapping core, pure: log-odds occupancy grid, voxel point cloud, odometry lookup by stamp.

Ray updates are vectorised: every beam is sampled at half-cell steps (free) up to its end point
(occupied); each cell changes at most once per scan, and a cell hit in this scan is not also
cleared by it.
"""

from __future__ import annotations

import bisect
import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from autochair.geometry import Pose, compose, sweep_poses, wrap_angle
from autochair_msgs import OccupancyGrid, Odometry, People, PointCloud

F64 = npt.NDArray[np.float64]


def scan_points(ranges: F64, angle_min: float, angle_inc: float, pose: Pose) -> F64:
    """World (N, 2) end points of the finite beams of a scan taken from laser `pose`."""
    a = angle_min + angle_inc * np.arange(ranges.size) + pose[2]
    ok = np.isfinite(ranges)
    r = ranges[ok]
    return np.stack([pose[0] + r * np.cos(a[ok]), pose[1] + r * np.sin(a[ok])], axis=1)


# A track is someone walking once it has been reported this far from where it was first: only
# theirs are left out of the map (a trail is walked; something set down that the tracker takes
# for a person, a bin or a door leaf moved into seen floor, is mapped as before, and once it is
# the map's the tracker drops it)
WALKED_M = 0.5
# A tracked person's returns lie within their reported radius of the track (the tracker puts a
# person's centre half the arc it sees behind its nearest point, and reports at least 0.25 m):
# this much more, and as far as they may have walked off their predicted line since the report.
PEOPLE_MARGIN_M = 0.15
PEOPLE_MAX_AGE_S = 0.5  # an older report is not used: every return is then the map's


@dataclass
class Walkers:
    """The tracks of a People report that have walked (`WALKED_M` from where each was first
    reported); forgotten once a report leaves them out."""

    first: dict[int, tuple[float, float]] = field(default_factory=dict)
    walked: set[int] = field(default_factory=set)

    def of(self, report: People) -> People:
        ids = {q.track_id for q in report.people}
        self.first = {k: v for k, v in self.first.items() if k in ids}
        self.walked &= ids
        for q in report.people:
            x0, y0 = self.first.setdefault(q.track_id, (q.x_m, q.y_m))
            if math.hypot(q.x_m - x0, q.y_m - y0) >= WALKED_M:
                self.walked.add(q.track_id)
        return People(stamp_ns=report.stamp_ns, frame_id=report.frame_id,
                      people=[q for q in report.people if q.track_id in self.walked])


def people_discs(report: People | None, stamp_ns: int, frame_id: str,
                 max_age_s: float = PEOPLE_MAX_AGE_S, margin_m: float = PEOPLE_MARGIN_M
                 ) -> F64 | None:
    """(K, 3) discs (x, y, r) of the people in `report` moved on at their velocity to the scan
    at `stamp_ns` (either way: the report may be of a later scan), r their radius plus
    `margin_m` and speed × that time; for `OccupancyMapper.integrate`. None when there is
    no report, or it is in another frame or more than `max_age_s` from the scan: the map then
    takes in every return (a trail, never a hole)."""
    if report is None or not report.people or report.frame_id != frame_id:
        return None
    dt = (stamp_ns - report.stamp_ns) / 1e9
    if abs(dt) > max_age_s:
        return None
    return np.array([(q.x_m + q.vx_mps * dt, q.y_m + q.vy_mps * dt,
                      q.radius_m + margin_m + math.hypot(q.vx_mps, q.vy_mps) * abs(dt))
                     for q in report.people], dtype=np.float64)


@dataclass
class GridSpec:
    resolution_m: float = 0.05
    width_m: float = 40.0
    height_m: float = 20.0
    origin_x_m: float = -10.0  # map-frame position of cell (0, 0)'s corner
    origin_y_m: float = -10.0


@dataclass(frozen=True)
class NoReturn:
    """How a beam with no return (non-finite: nothing within the laser's range, or an error
    code) clears free space. Without it nothing clears where a walker was when nothing is
    within range behind them (a corridor's far end), and their trail stays mapped. But a dark
    or glancing surface gives no return too: so only up to `range_m`, by `l_miss` (weaker
    than a return's), never a cell at or above `keep_above` (hit more than once, l_hit 0.85
    each: only beams that end beyond it lower those), and not at all in a scan with fewer than
    `min_valid` of its beams valid (a blinded or dazzled laser). (Cartographer clears up to
    its missing_data_ray_length, 5 m; costmap_2d's inf_is_valid to its raytrace range.)

    Off by default (MappingConfig.no_return_m = 0; session 22, nav_eval --map scans, 2 m):
    'person: back' / 'to the side' take ×1.7 / ×1.7 the least time, not ×3.2 / ×3.0 (laser
    noise seed 0; seeds 1, 2: ×2.1 / ×1.6, ×2.4 / ×1.6, were ×2.1 / ×2.8, ×3.0 / ×1.8), but
    the cluttered room's cases then touch on each of the 3 seeds (1 to 8 contacts in one case;
    none in 24 runs of them without it, over 3 laser and 3 MPEPC seeds). Traced: it clears
    the cell in front of a face on a cell boundary (hit once by noise, free in truth); hit
    again as the chair sees the face better, it comes back, the chair now reads 0 on the map,
    and there MPEPC counted only getting closer as a hit (H57, since fixed: 2 of 12 of those
    runs still touched, not traced). At 1 m it changed nothing; at 3 m
    (floor 1.5) 'person: back' touched. A dark bin seen along 2.5 m, then giving no return
    (tests/test_mapping.py): its face stays whole, 2 of its 20 mapped cells behind the face
    cleared (with a floor of 1.5: 2 in the face; without one: 11)."""

    range_m: float = 2.0
    l_miss: float = -0.2
    keep_above: float = 1.0
    min_valid: float = 0.5


class OccupancyMapper:
    def __init__(self, spec: GridSpec, l_hit: float = 0.85, l_miss: float = -0.4,
                 l_min: float = -4.0, l_max: float = 4.0, max_range_m: float = 30.0,
                 no_return: NoReturn | None = None) -> None:
        self.spec = spec
        self.res = spec.resolution_m
        self.w = round(spec.width_m / self.res)
        self.h = round(spec.height_m / self.res)
        self.l_hit, self.l_miss, self.l_min, self.l_max = l_hit, l_miss, l_min, l_max
        self.max_range_m = max_range_m
        self.no_return = no_return
        self.logodds = np.zeros((self.h, self.w), dtype=np.float32)
        # Scratch for integrate: per cell, the last free sample that wrote it (int32: as
        # large as the grid itself; a scan has far fewer than 2³¹ samples).
        self._owner = np.zeros(self.h * self.w, dtype=np.int32)
        self.scans = 0

    def cells(self, pts: F64) -> npt.NDArray[np.int64]:
        """Flat cell indices of (N, 2) map-frame points; -1 outside the grid."""
        ix = np.floor((pts[:, 0] - self.spec.origin_x_m) / self.res).astype(np.int64)
        iy = np.floor((pts[:, 1] - self.spec.origin_y_m) / self.res).astype(np.int64)
        inside = (ix >= 0) & (ix < self.w) & (iy >= 0) & (iy < self.h)
        return np.where(inside, iy * self.w + ix, -1)

    def _inside(self, x: F64, y: F64) -> npt.NDArray[np.int64]:
        """Flat indices of the points inside the grid (the others dropped), as `cells` with
        the same arithmetic, done in place: `x` and `y` are overwritten (the free samples of
        a scan are tens of thousands; temporaries cost more than the arithmetic)."""
        x -= self.spec.origin_x_m
        x /= self.res
        np.floor(x, out=x)
        y -= self.spec.origin_y_m
        y /= self.res
        np.floor(y, out=y)
        ix, iy = x.astype(np.int64), y.astype(np.int64)
        # a negative index is a huge unsigned one: one comparison per axis
        inside = ix.view(np.uint64) < self.w
        inside &= iy.view(np.uint64) < self.h
        iy *= self.w
        iy += ix
        return iy[inside]

    def integrate(self, ranges: F64, angle_min: float, angle_inc: float, pose: Pose,
                  beam_poses: tuple[F64, F64, F64] | None = None,
                  people: F64 | None = None) -> int:
        """Add one scan seen from laser `pose` (grid frame); returns the number of beams used.
        `beam_poses`: the laser's x, y, yaw for each beam instead (a sweep taken moving).
        Beams with no return (non-finite) clear as `no_return` says, if it is set.
        `people`: discs (K, 3: x, y, radius; grid frame) of the people tracked: a return
        within one is theirs, not the map's; its beam clears up to it, and marks nothing
        (else someone pacing leaves a trail of hits faster than beams through it clear them:
        on the laser's map a person pacing across a door's exit closed it, H75)."""
        n = ranges.size
        lx, ly, lyaw = beam_poses if beam_poses is not None else (
            np.full(n, pose[0]), np.full(n, pose[1]), np.full(n, pose[2]))
        a = angle_min + angle_inc * np.arange(n) + lyaw
        ok = np.isfinite(ranges) & (ranges > 0) & (ranges <= self.max_range_m)
        theirs = np.zeros(n, dtype=np.bool_)
        if people is not None and len(people) and ok.any():
            with np.errstate(invalid="ignore"):
                ex, ey = lx + ranges * np.cos(a), ly + ranges * np.sin(a)
                theirs = ok & (np.hypot(ex[:, None] - people[None, :, 0],
                                        ey[:, None] - people[None, :, 1])
                               <= people[None, :, 2]).any(1)
        nr = self.no_return
        blank = np.flatnonzero(~np.isfinite(ranges)) if nr is not None and n \
            and ok.mean() >= nr.min_valid else np.zeros(0, dtype=np.intp)
        # The no-return beams first, as free beams nr.range_m long (no end point to keep).
        reach = np.full(blank.size, nr.range_m + self.res if nr is not None else 0.0)
        sel = np.concatenate([blank, np.flatnonzero(ok)]) if blank.size else ok
        r = np.concatenate([reach, ranges[ok]]) if blank.size else ranges[ok]
        a, ox, oy = a[sel], lx[sel], ly[sel]
        if r.size == 0:
            return 0
        step = self.res / 2
        t = np.arange(0.0, float(r.max()), step)
        cos, sin = np.cos(a), np.sin(a)
        # Free samples stop a cell short of the end point so the hit cell is not cleared; only
        # those are computed (a beam × sample product would be mostly past short beams' ends).
        count = np.searchsorted(t, r - self.res)  # per beam, the samples t < r − res
        tk = t[np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)]
        x = np.repeat(cos, count)
        x *= tk
        x += np.repeat(ox, count)  # ox + cos·t, sample by sample
        y = np.repeat(sin, count)
        y *= tk
        y += np.repeat(oy, count)
        m = int(count[:blank.size].sum())  # (the no-return beams' samples)
        free_nr = self._inside(x[:m], y[:m])
        free = np.concatenate([free_nr, self._inside(x[m:], y[m:])]) if m else \
            self._inside(x, y)
        k = ok.sum()
        mine = ~theirs[ok]  # (the returns' beams, in `r`'s order: the last k)
        hits = np.unique(self._inside((ox[-k:] + r[-k:] * cos[-k:])[mine],
                                      (oy[-k:] + r[-k:] * sin[-k:])[mine])) if k else free[:0]
        # Each cell once, and none hit by this scan: the cells whose own sample is the one
        # that wrote them last (no sort of the many samples, no pass over the whole grid); a
        # cell a return crosses is that return's (written after the no-return beams).
        owner, order = self._owner, np.arange(free.size, dtype=np.int32)
        owner[free] = order
        owner[hits] = -1
        last = owner[free] == order
        cleared, free = free[:free_nr.size][last[:free_nr.size]], free[free_nr.size:][
            last[free_nr.size:]]
        flat = self.logodds.reshape(-1)
        flat[free] = np.clip(flat[free] + np.float32(self.l_miss), self.l_min, self.l_max)
        if nr is not None and cleared.size:
            cleared = cleared[flat[cleared] < nr.keep_above]
            flat[cleared] = np.clip(flat[cleared] + np.float32(nr.l_miss), self.l_min,
                                    self.l_max)
        flat[hits] = np.clip(flat[hits] + np.float32(self.l_hit), self.l_min, self.l_max)
        self.scans += 1
        return int(r.size)

    def occupied(self, threshold: float = 0.5) -> npt.NDArray[np.bool_]:
        """(H, W) cells whose log odds exceed `threshold` (0.5 ≈ p 0.62)."""
        return self.logodds > threshold

    def cell_centres(self, mask: npt.NDArray[np.bool_]) -> F64:
        iy, ix = np.nonzero(mask)
        return np.stack([self.spec.origin_x_m + (ix + 0.5) * self.res,
                         self.spec.origin_y_m + (iy + 0.5) * self.res], axis=1)

    def to_msg(self, stamp_ns: int, frame_id: str = "odom") -> OccupancyGrid:
        p = 1.0 / (1.0 + np.exp(-self.logodds))
        data = np.where(self.logodds == 0, 255, np.rint(p * 100)).astype(np.uint8)
        return OccupancyGrid(stamp_ns=stamp_ns, frame_id=frame_id, resolution_m=self.res,
                             width=self.w, height=self.h, origin_x_m=self.spec.origin_x_m,
                             origin_y_m=self.spec.origin_y_m, data=data.tobytes())


class VoxelCloud:
    """World points, one per voxel (the first seen), at most `max_points` (oldest evicted)."""

    def __init__(self, voxel_m: float = 0.05, max_points: int = 100_000) -> None:
        self.voxel_m, self.max_points = voxel_m, max_points
        self._pts: dict[int, tuple[float, float, float]] = {}

    def __len__(self) -> int:
        return len(self._pts)

    def add(self, xy: F64, z: float) -> None:
        if xy.size == 0:
            return
        k = np.floor(xy / self.voxel_m).astype(np.int64)
        keys = (k[:, 0] << 32) ^ (k[:, 1] & 0xFFFFFFFF)
        keys, first = np.unique(keys, return_index=True)
        for key, (x, y) in zip(keys.tolist(), xy[first].tolist(), strict=True):
            self._pts.setdefault(key, (x, y, z))
        excess = len(self._pts) - self.max_points
        if excess > 0:
            for key in list(self._pts)[:excess]:
                del self._pts[key]

    def to_msg(self, stamp_ns: int, frame_id: str = "odom") -> PointCloud:
        arr = np.array(list(self._pts.values()), dtype=np.float32).reshape(-1, 3)
        return PointCloud(stamp_ns=stamp_ns, frame_id=frame_id, count=len(arr),
                          points_xyz_f32=arr.astype("<f4").tobytes())


@dataclass
class MoveGate:
    """Whether a scan adds anything to the map (or a tracking estimate): the laser moved
    `min_move_m` or turned `min_turn_rad` since the last one taken, or that is older than
    `max_age_ns`. A parked chair's identical views are taken once a second, not ten times
    (CPU); what changes in front of it still shows within a second. The mapping service
    driving: one scan per 10 cm or 5.7°, at 0.5 m/s every other one (ROS stacks update less
    often still: slam_toolbox every 0.5 m, gmapping 1 m); localization tracks finer
    (localization/core.py TRACK_MOVE_M); the safety monitor and the people tracker take every
    scan."""

    min_move_m: float = 0.1
    min_turn_rad: float = 0.1
    max_age_ns: int = 1_000_000_000
    _last: tuple[Pose, int] | None = None

    def take(self, pose: Pose, stamp_ns: int) -> bool:
        if self._last is not None:
            (x, y, yaw), t = self._last
            still = (math.hypot(pose[0] - x, pose[1] - y) < self.min_move_m
                     and abs(wrap_angle(pose[2] - yaw)) < self.min_turn_rad)
            if still and 0 <= stamp_ns - t < self.max_age_ns:
                return False
        self._last = (pose, stamp_ns)
        return True


# Odometry samples a scan consumer's ring holds between two scans (`Node.queued`): 2 s of
# keys.ODOM_SLOW (50 Hz), where a scan needs the last 0.25 s.
ODOM_RING = 100


class OdomBuffer:
    """Recent odometry, looked up by the nearest stamp."""

    def __init__(self, keep: int = 1000) -> None:
        self._stamps: deque[int] = deque(maxlen=keep)
        self._poses: deque[Pose] = deque(maxlen=keep)

    def add(self, msg: Odometry) -> None:
        if self._stamps and msg.stamp_ns < self._stamps[-1]:
            self._stamps.clear()  # odometry restarted / time went back: old samples are void
            self._poses.clear()
        self._stamps.append(msg.stamp_ns)
        self._poses.append((msg.x_m, msg.y_m, msg.yaw_rad))

    def nearest(self, stamp_ns: int, max_dt_ns: int) -> Pose | None:
        if not self._stamps:
            return None
        stamps = list(self._stamps)
        i = bisect.bisect_left(stamps, stamp_ns)
        best = min((j for j in (i - 1, i) if 0 <= j < len(stamps)),
                   key=lambda j: abs(stamps[j] - stamp_ns))
        if abs(stamps[best] - stamp_ns) > max_dt_ns:
            return None
        return self._poses[best]

    def at_last_beam(self, stamp_ns: int, beams: int, time_increment_s: float,
                     max_dt_ns: int) -> Pose | None:
        """The pose at a scan's last beam (beam i is taken at stamp + i·time_increment_s);
        None for a scan taken at one instant, or when odometry cannot say."""
        sweep_ns = round(time_increment_s * 1e9 * max(beams - 1, 0))
        return self.at(stamp_ns + sweep_ns, max_dt_ns) if sweep_ns > 0 else None

    def at(self, stamp_ns: int, max_dt_ns: int) -> Pose | None:
        """The pose at `stamp_ns`, interpolated between the samples either side (decimated
        odometry is 20 ms apart: 2 cm at 1 m/s if only the nearest were taken); the nearest
        within `max_dt_ns` when the stamp is not bracketed."""
        stamps = list(self._stamps)
        i = bisect.bisect_left(stamps, stamp_ns)
        if 0 < i < len(stamps) and stamps[i] - stamps[i - 1] <= max_dt_ns:
            a, b = self._poses[i - 1], self._poses[i]
            f = (stamp_ns - stamps[i - 1]) / max(stamps[i] - stamps[i - 1], 1)
            dyaw = math.atan2(math.sin(b[2] - a[2]), math.cos(b[2] - a[2]))
            yaw = math.atan2(math.sin(a[2] + f * dyaw), math.cos(a[2] + f * dyaw))
            return (a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), yaw)
        return self.nearest(stamp_ns, max_dt_ns)


@dataclass(frozen=True)
class Placed:
    """Where a scan was taken: the laser's pose at its stamp, and each beam's (x, y, yaw)
    along the sweep (None: one instant, or odometry cannot say where it ended)."""

    laser: Pose
    beams: tuple[F64, F64, F64] | None


def place_scan(odom: OdomBuffer, gate: MoveGate, stamp_ns: int, beams: int,
               time_increment_s: float, mount: Pose, max_dt_ns: int,
               no_odom: Pose | None = None) -> Placed | str:
    """The mapping service's decision for one scan: placed by odometry at its stamp and last
    beam (each beam from where the laser was when it took it: the sweep lasts ~70 ms, 0.27 m
    at 4.5 m turning at 0.9 rad/s), or why it is not mapped (its health counter's name).
    `no_odom`: the pose to map at when odometry cannot say (None: the scan is skipped)."""
    pose = odom.at(stamp_ns, max_dt_ns)
    if pose is None:
        if no_odom is None:
            return "scans_no_odom"
        pose = no_odom
    if not gate.take(pose, stamp_ns):
        return "scans_still"
    last = odom.at_last_beam(stamp_ns, beams, time_increment_s, max_dt_ns)
    return Placed(compose(pose, mount),
                  sweep_poses(pose, last, mount, beams) if last is not None else None)
