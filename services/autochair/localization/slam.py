"""Mapping mode, pure: keyframe SLAM with loop closure.

Each scan is predicted by odometry and refined against a local submap (the distance field of
the last `submap_keyframes` keyframes). Every `keyframe_m` / `keyframe_rad` of motion the scan
becomes a keyframe: a node of the pose graph, tied to the previous one by the tracked relative
pose. A new keyframe is also matched against older keyframes near it (that the chair left at
least `loop_min_travel_m` of travel ago): a brute-force search then refinement on their
submap; a good fit adds a loop edge and the graph is re-optimised, which moves every keyframe
and so the map. The occupancy grid is rendered from the keyframes' scans at their optimised
poses (`render`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from autochair.geometry import sweep_poses
from autochair.mapping.core import GridSpec, OccupancyMapper

from .core import Estimate, Localizer, LocParams, LocState
from .graph import PoseGraph
from .matching import (
    F64,
    DistanceField,
    GridFrame,
    LineField,
    Match,
    between,
    compose,
    inverse,
    refine,
    rotate,
    scan_normals,
    score_grid,
    transform,
)


@dataclass(frozen=True)
class Scan:
    """A laser scan as taken: ranges (inf = no return) from `mount` (laser in chair frame).
    A laser sweeps its beams one after another; on a moving chair `first`/`last` are the
    chair's poses at the first and last beam in the frame the scan is used in (the odometry
    pose given with it), the beams between taken linearly between them: `points` places each
    beam from where it was taken (de-skewed). Both zero: all beams from the one pose."""

    ranges: F64
    angle_min: float
    angle_inc: float
    mount: tuple[float, float, float]
    first: tuple[float, float, float] = (0.0, 0.0, 0.0)
    last: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def points(self, max_range_m: float = 30.0) -> F64:
        """Finite end points in the chair frame."""
        n = self.ranges.size
        a = self.angle_min + self.angle_inc * np.arange(n)
        ok = np.isfinite(self.ranges) & (self.ranges > 0.02) & (self.ranges < max_range_m)
        r, a = self.ranges[ok], a[ok]
        if self.first == self.last == (0.0, 0.0, 0.0):
            lp = np.column_stack((r * np.cos(a + self.mount[2]), r * np.sin(a + self.mount[2])))
            return transform(np.array([self.mount[0], self.mount[1], 0.0]), lp)
        lx, ly, lyaw = sweep_poses(self.first, self.last, self.mount, n)
        lx, ly, lyaw = lx[ok], ly[ok], lyaw[ok]
        return np.column_stack((lx + r * np.cos(lyaw + a), ly + r * np.sin(lyaw + a)))


@dataclass(frozen=True)
class SlamParams:
    resolution_m: float = 0.05
    keyframe_m: float = 0.3
    keyframe_rad: float = math.radians(15.0)
    submap_keyframes: int = 15
    submap_radius_m: float = 40.0  # 10 m lost the loop on the SENA log: far walls hold the heading
    max_points: int = 200
    line_field: bool = True  # submaps matched point-to-line, sub-cell (LineField)
    loop_min_travel_m: float = 8.0  # a keyframe this much travel old can close a loop
    loop_radius_m: float = 3.0  # candidates within this of the current estimate
    # The search window grows with the travel since the last loop closed (how far the front
    # end can have drifted), up to these: small while the chair keeps revisiting (cheap, and
    # a corridor has fewer look-alike places in it), wide after a long way through new space.
    loop_search_xy_m: float = 1.0
    loop_search_yaw: float = math.radians(12.0)
    loop_window_m: float = 0.25  # half-size right after a loop closed
    loop_window_yaw: float = math.radians(5.0)
    loop_every_m: float = 0.6  # travel between loop-closure tries: each costs a search
    # A fit is ambiguous (a corridor without features in view, repeated doors) when a refined
    # peak ≥ loop_unique_m from the best fits within loop_unique of it; such a loop is not
    # taken. With the small window this took the hallway's map from 30 to 3–4 cm (seed 7).
    loop_unique: float = 0.04
    loop_unique_m: float = 0.15
    loop_peaks: int = 4  # separate peaks of the search refined
    loop_quality: float = 0.85  # fraction of points within 5 cm of the candidate submap
    # Smallest/largest eigenvalue of the match's translation information: below this the scan
    # pins the pose in one direction only (a corridor), and a loop there may be any place.
    loop_min_constraint: float = 0.1
    loop_max_chi2: float = 16.0  # a loop edge the optimised graph misses by more is dropped
    loop_drift_per_m: float = 0.02  # a loop may correct 10 cm + this × travel since, no more
    seq_sigma_xy_m: float = 0.02  # keyframe-to-keyframe edge
    seq_sigma_yaw: float = math.radians(0.5)
    loop_sigma_xy_m: float = 0.05
    loop_sigma_yaw: float = math.radians(1.0)
    max_range_m: float = 30.0
    # Tracking against the submap: a match far from the odometry prediction is never taken
    # (in mapping there is no map to recover on; the odometry carries the chair through).
    # The odometry noise is set high: the SENA chair's real odometry is worse than the
    # localization defaults assume, and trusting it tore the loop there (4 cm → 0.7 cm);
    # `adapt_odometry` lowers it where the odometry proves better (simulator: ×0.11–0.14,
    # SENA: ×0.5–0.9).
    # `refine_prior_m`: along a corridor the point-to-line fit is singular (see refine).
    # The match's information is scaled to 0.3: along a corridor a few points at the
    # submap's ends fixed the position and the loop world's map shrank (−0.5 %); 0.1 with
    # 3 %/m odometry was better in the simulator but lost every loop on the SENA log.
    tracking: LocParams = field(default_factory=lambda: LocParams(
        found_quality=2.0, lost_after=10**9, trans_noise=0.15, rot_noise=0.15,
        rot_per_m=0.05, info_scale=0.3, adapt_odometry=True, refine_prior_m=0.05))


@dataclass
class Keyframe:
    scan: Scan
    pts: F64  # chair frame, subsampled
    travel_m: float  # odometry distance at the keyframe
    reach_m: float  # its longest return: how far it mapped
    dense: F64  # every end point (chair frame): submaps are drawn from these
    normals: F64  # of `dense`, chair frame (NaN where none: scan_normals)


@dataclass
class SlamStats:
    keyframes: int = 0
    loops: int = 0
    loop_tries: int = 0
    loops_implausible: int = 0
    loops_degenerate: int = 0
    loops_ambiguous: int = 0
    loops_rejected: int = 0
    submaps: int = 0
    loop_log: list[tuple[int, int, float]] = field(default_factory=list)  # (old, new, fit)


def _subsample(pts: F64, n: int) -> F64:
    if len(pts) <= n:
        return pts
    return pts[np.linspace(0, len(pts) - 1, n).astype(np.int64)]


def points_field(world_pts: F64, res: float, margin: float = 1.0,
                 normals: F64 | None = None) -> DistanceField:
    """Distance field of a point set (map frame) on a grid just large enough for it; with
    the points' `normals`, sub-cell point-to-line (`LineField`)."""
    lo = np.floor((world_pts.min(axis=0) - margin) / res) * res
    hi = world_pts.max(axis=0) + margin
    w, h = math.ceil((hi[0] - lo[0]) / res), math.ceil((hi[1] - lo[1]) / res)
    if normals is not None:
        return LineField(world_pts, normals, GridFrame(res, float(lo[0]), float(lo[1])), (h, w))
    occ = np.zeros((h, w), dtype=np.bool_)
    ix = ((world_pts[:, 0] - lo[0]) / res).astype(np.int64)
    iy = ((world_pts[:, 1] - lo[1]) / res).astype(np.int64)
    occ[iy, ix] = True
    return DistanceField(occ, GridFrame(res, float(lo[0]), float(lo[1])))


class Slam:
    def __init__(self, params: SlamParams | None = None) -> None:
        self.p = params or SlamParams()
        self.graph = PoseGraph()
        self.kfs: list[Keyframe] = []
        self.pose = np.zeros(3)
        self.quality = 0.0
        self.stats = SlamStats()
        self._last_odom: F64 | None = None
        self._travel = 0.0
        self.tracker: Localizer | None = None  # scan-to-submap, fused with odometry
        self._submap_ids = range(0)
        self._loop_travel = -math.inf  # travel when a loop last closed
        self._try_travel = -math.inf  # travel when a loop was last tried
        self._beams: tuple[range, F64, tuple[F64, F64, F64, F64, F64, F64]] | None = None

    def _submap_of(self, idx: range, crop: bool = True) -> DistanceField:
        """Distance field of keyframes `idx`, cropped to `submap_radius_m` round the chair:
        the distance transform is most of a keyframe's cost, and it grows with the area."""
        pts = np.vstack([transform(self.graph.nodes[i], self.kfs[i].dense) for i in idx])
        nrm = np.vstack([rotate(self.graph.nodes[i][2], self.kfs[i].normals) for i in idx])
        near = np.hypot(pts[:, 0] - self.pose[0], pts[:, 1] - self.pose[1])
        if crop and (near <= self.p.submap_radius_m).sum() >= 10:
            keep = near <= self.p.submap_radius_m
            pts, nrm = pts[keep], nrm[keep]
        self.stats.submaps += 1
        return points_field(pts, self.p.resolution_m,
                            normals=nrm if self.p.line_field else None)

    def update(self, odom: F64, scan: Scan) -> Estimate:
        odom = np.asarray(odom, dtype=np.float64)
        delta = np.zeros(3)
        if self._last_odom is not None:
            delta = between(self._last_odom, odom)
            self._travel += math.hypot(delta[0], delta[1])
        self._last_odom = odom
        pts = _subsample(scan.points(self.p.max_range_m), self.p.max_points)
        if self.tracker is not None:
            seen = self._seen(compose(self.pose, delta), pts, self._submap_ids)
            est = self.tracker.update(odom, pts[seen])  # odometry prediction fused with match
            self.pose, self.quality = est.pose, est.quality
        elif len(pts) >= 10:
            self._add_keyframe(scan, pts)
        if self.tracker is not None and len(pts) >= 10 and self._moved(self.graph.nodes[-1]):
            self._add_keyframe(scan, pts)
        return self.estimate()

    def _seen(self, pose: F64, pts: F64, ids: range) -> npt.NDArray[np.bool_]:
        """Points some submap keyframe's laser saw (or would have seen) along its beams. The
        submap ends where its scans ended; a wall that runs on past that end would pull the
        points seen beyond it back onto its end, and the chair would slide along a corridor.
        Such points are left out."""
        world = transform(pose, pts)
        if not len(ids) or not len(pts):
            return np.ones(len(pts), dtype=np.bool_)
        laser, amin, ainc, size, reach, ranges = self._beams_of(ids)
        dx, dy = world[None, :, 0] - laser[:, 0, None], world[None, :, 1] - laser[:, 1, None]
        r = np.hypot(dx, dy)
        rel = np.mod(np.arctan2(dy, dx) - laser[:, 2, None] + np.pi, 2 * np.pi) - np.pi
        k = np.rint((rel - amin) / ainc)
        inside = (k >= 0) & (k < size)
        beam = np.take_along_axis(ranges, np.clip(k, 0, size - 1).astype(np.int64), axis=1)
        # no return: free up to its reach, but keep clear of where its walls ended
        beam = np.where(np.isfinite(beam), beam + 0.05, reach - 0.3)
        ok: npt.NDArray[np.bool_] = np.asarray((inside & (r <= beam)).any(axis=0))
        return ok if ok.sum() >= 10 else np.ones(len(pts), dtype=np.bool_)

    def _beams_of(self, ids: range) -> tuple[F64, F64, F64, F64, F64, F64]:
        """`_seen`'s per-keyframe arrays (all keyframes at once: row per keyframe): the lasers'
        poses, each scan's angle_min, angle_inc, beam count and reach (columns), its ranges
        (NaN-padded rows). Kept while the keyframes and their poses are unchanged: every
        tracked scan asks for the same submap's until a keyframe is added or a loop moves it."""
        nodes = np.array([self.graph.nodes[i] for i in ids])
        hit = self._beams
        if hit is not None and hit[0] == ids and np.array_equal(hit[1], nodes):
            return hit[2]
        kfs = [self.kfs[i] for i in ids]
        laser = np.array([compose(node, np.array(kf.scan.mount))
                          for node, kf in zip(nodes, kfs, strict=True)])
        col = np.array([(kf.scan.angle_min, kf.scan.angle_inc, kf.scan.ranges.size,
                         kf.reach_m) for kf in kfs])
        amin, ainc, size, reach = (col[:, j, None] for j in range(4))
        ranges = np.full((len(kfs), int(size.max())), np.nan)
        for row, kf in zip(ranges, kfs, strict=True):
            row[:kf.scan.ranges.size] = kf.scan.ranges
        out = (laser, amin, ainc, size, reach, ranges)
        self._beams = (ids, nodes, out)
        return out

    def _moved(self, last: F64) -> bool:
        d = between(last, self.pose)
        return math.hypot(d[0], d[1]) >= self.p.keyframe_m or abs(d[2]) >= self.p.keyframe_rad

    def _add_keyframe(self, scan: Scan, pts: F64) -> None:
        p = self.p
        j = self.graph.add_node(self.pose)
        finite = scan.ranges[np.isfinite(scan.ranges)]
        reach = float(min(finite.max(), p.max_range_m)) if finite.size else 0.0
        dense = scan.points(p.max_range_m)
        self.kfs.append(Keyframe(scan, pts, self._travel, reach, dense, scan_normals(dense)))
        if j > 0:
            info = np.diag([p.seq_sigma_xy_m ** -2, p.seq_sigma_xy_m ** -2,
                            p.seq_sigma_yaw ** -2])
            self.graph.add_edge(j - 1, j, between(self.graph.nodes[j - 1], self.pose), info)
        self.stats.keyframes = len(self.kfs)
        closed = self._close_loop(j, pts)
        if closed:
            self._optimize()
            self.pose = self.graph.nodes[j].copy()
        self._submap_ids = range(max(0, j + 1 - p.submap_keyframes), j + 1)
        submap = self._submap_of(self._submap_ids)
        if self.tracker is None:
            self.tracker = Localizer(submap, None, p.tracking)
            self.tracker.set_pose(self.pose, 0.01, 0.01)
            self.tracker.update(self._last_odom if self._last_odom is not None
                                else np.zeros(3), pts)
        self.tracker.field = submap
        if closed:
            self.tracker.set_pose(self.pose, 0.02, math.radians(1))

    def _optimize(self) -> None:
        """Optimise; then drop loop edges that the optimised graph disagrees with (χ² beyond
        `loop_max_chi2`: a place that only looked like another) and optimise again."""
        g = self.graph
        for _ in range(3):
            g.optimize()
            chi2 = g.edge_chi2()
            bad = [e.loop and c > self.p.loop_max_chi2 for e, c in zip(g.edges, chi2,
                                                                         strict=True)]
            if not any(bad):
                return
            g.edges = [e for e, b in zip(g.edges, bad, strict=True) if not b]
            self.stats.loops_rejected += sum(bad)

    def _close_loop(self, j: int, pts: F64) -> bool:
        p = self.p
        old = [i for i in range(j) if self._travel - self.kfs[i].travel_m >= p.loop_min_travel_m]
        if not old:
            return False
        d = np.array([math.hypot(*(self.graph.nodes[i][:2] - self.pose[:2])) for i in old])
        if d.min() > p.loop_radius_m:
            return False
        i = old[int(d.argmin())]
        if self._travel - self._try_travel < p.loop_every_m:
            return False
        self._try_travel = self._travel
        self.stats.loop_tries += 1
        near = range(max(0, i - 5), min(len(self.kfs), i + 6))
        near = range(near.start, min(near.stop, j - int(p.loop_min_travel_m / p.keyframe_m)))
        if len(near) < 3:
            return False
        sub = self._submap_of(near, crop=False)
        pts = pts[self._seen(self.pose, pts, near)]
        m = self._loop_match(sub, pts)
        if m is None:
            return False
        jump = between(self.pose, m.pose)
        travel = self._travel - self.kfs[i].travel_m
        if math.hypot(jump[0], jump[1]) > 0.1 + p.loop_drift_per_m * travel:
            self.stats.loops_implausible += 1  # more than the front end drifts: another place
            return False
        eig = np.linalg.eigvalsh(m.information[:2, :2])
        if eig[0] < p.loop_min_constraint * eig[1]:
            self.stats.loops_degenerate += 1  # a corridor: it fits anywhere along it
            return False
        # The match's own information, in the edge's frame, with its strongest axis capped at
        # loop_sigma_xy_m: the shape keeps a corridor's weak axis weak (a loop along a corridor
        # must not pin the position along it), the cap keeps it from out-voting the chain.
        c, s_ = math.cos(m.pose[2]), math.sin(m.pose[2])  # the edge error is in j's frame
        rot = np.array([[c, -s_, 0.0], [s_, c, 0.0], [0.0, 0.0, 1.0]])
        info = rot.T @ m.information @ rot
        info *= p.loop_sigma_xy_m ** -2 / max(float(np.linalg.eigvalsh(info[:2, :2])[1]), 1e-9)
        self.graph.add_edge(i, j, between(self.graph.nodes[i], m.pose), info, loop=True)
        self.stats.loops += 1
        self._loop_travel = self._travel
        self.stats.loop_log.append((i, j, m.inliers))
        return True

    def _loop_match(self, sub: DistanceField, pts: F64) -> Match | None:
        """The scan on an old submap: correlative search in a window round the estimate, then
        refinement from its `loop_peaks` best separate peaks. None when no fit is good, or
        when fits that good lie apart (ambiguous: a corridor without features in view fits
        all along it). Refined peaks, not raw scores, decide: the search's steps are coarse
        for far points (1.5° is 50 cm at 20 m on the SENA log)."""
        p = self.p
        since = self._travel - self._loop_travel
        poses, scores = score_grid(
            sub, pts, self.pose, step_xy_m=0.05, step_yaw=math.radians(1.5), inlier_m=0.05,
            half_xy_m=min(p.loop_search_xy_m, p.loop_window_m + p.loop_drift_per_m * since),
            half_yaw=min(p.loop_search_yaw, p.loop_window_yaw + math.radians(0.25) * since))
        peaks: list[F64] = []
        for k in np.argsort(-scores, kind="stable")[:2000]:
            if all(math.hypot(*(poses[k, :2] - q[:2])) >= 2 * p.loop_unique_m for q in peaks):
                peaks.append(poses[k])
                if len(peaks) == p.loop_peaks:
                    break
        fits = [refine(sub, pts, q, inlier_m=0.05) for q in peaks]
        good = [m for m in fits if m.inliers >= p.loop_quality]
        if not good:
            return None
        best = max(good, key=lambda m: m.inliers)
        if any(m.inliers >= best.inliers - p.loop_unique
               and math.hypot(*(m.pose[:2] - best.pose[:2])) >= p.loop_unique_m for m in good):
            self.stats.loops_ambiguous += 1
            return None
        return best

    def estimate(self) -> Estimate:
        odom = self._last_odom if self._last_odom is not None else np.zeros(3)
        cov = np.diag([0.02**2, 0.02**2, math.radians(1) ** 2])
        return Estimate(self.pose.copy(), cov, compose(self.pose, inverse(odom)),
                        self.quality, LocState.TRACKING)

    def points(self) -> F64:
        """All keyframe points in the map frame (optimised poses)."""
        if not self.kfs:
            return np.zeros((0, 2))
        return np.vstack([transform(self.graph.nodes[i], k.pts) for i, k in enumerate(self.kfs)])

    def snapshot(self) -> tuple[list[F64], list[Keyframe]]:
        """Copies of the poses and keyframes, to render the map outside a lock."""
        return [n.copy() for n in self.graph.nodes], list(self.kfs)

    def render(self, spec: GridSpec | None = None) -> OccupancyMapper:
        nodes, kfs = self.snapshot()
        return render(nodes, kfs, self.p, spec)


def render(nodes: list[F64], kfs: list[Keyframe], p: SlamParams, spec: GridSpec | None = None,
           margin_m: float = 2.0) -> OccupancyMapper:
    """The occupancy grid of every keyframe scan at its optimised pose (ray-traced)."""
    if spec is None:
        pts = (np.vstack([transform(n, k.pts) for n, k in zip(nodes, kfs, strict=True)])
               if kfs else np.zeros((1, 2)))
        lo = np.floor((pts.min(axis=0) - margin_m) / p.resolution_m) * p.resolution_m
        hi = pts.max(axis=0) + margin_m
        spec = GridSpec(p.resolution_m, float(hi[0] - lo[0]), float(hi[1] - lo[1]),
                        float(lo[0]), float(lo[1]))
    grid = OccupancyMapper(spec, max_range_m=p.max_range_m)
    for node, kf in zip(nodes, kfs, strict=True):
        _draw(grid, node, kf)
    return grid


def _draw(grid: OccupancyMapper, node: F64, kf: Keyframe) -> None:
    s = kf.scan
    laser = compose(node, np.array(s.mount))
    beams = None
    if not s.first == s.last == (0.0, 0.0, 0.0):  # each beam from where it was taken
        a, b = compose(node, np.array(s.first)), compose(node, np.array(s.last))
        beams = sweep_poses((float(a[0]), float(a[1]), float(a[2])),
                            (float(b[0]), float(b[1]), float(b[2])), s.mount, s.ranges.size)
    grid.integrate(s.ranges, s.angle_min, s.angle_inc,
                   (float(laser[0]), float(laser[1]), float(laser[2])), beams)


class MapRenderer:
    """`render`, kept up to date cheaply: new keyframes are ray-traced into the last grid;
    the whole grid is redrawn only when a loop closure moved a drawn keyframe by more than
    `tolerance_cells` cells (at its laser's reach) or the map outgrew the grid. A full render
    of 500 keyframes took 0.4 s: every 5 s, 9 % of a core while mapping."""

    def __init__(self, params: SlamParams, tolerance_cells: float = 0.5,
                 margin_m: float = 6.0) -> None:
        self.p, self.tol, self.margin_m = params, tolerance_cells, margin_m
        self.grid: OccupancyMapper | None = None
        self.drawn: list[F64] = []  # poses the drawn keyframes were drawn at
        self.full_renders = 0

    def update(self, nodes: list[F64], kfs: list[Keyframe]) -> OccupancyMapper:
        n = len(self.drawn)
        if self.grid is None or n > len(nodes) or self._moved(nodes[:n]) \
                or not self._fits(nodes[n:], kfs[n:]):
            self.grid = render(nodes, kfs, self.p, margin_m=self.margin_m)
            self.full_renders += 1
        else:
            for node, kf in zip(nodes[n:], kfs[n:], strict=True):
                _draw(self.grid, node, kf)
        self.drawn = [x.copy() for x in nodes]
        return self.grid

    def _moved(self, nodes: list[F64]) -> bool:
        if not nodes:
            return False
        a, b = np.array(nodes), np.array(self.drawn)
        yaw = np.abs(np.arctan2(np.sin(a[:, 2] - b[:, 2]), np.cos(a[:, 2] - b[:, 2])))
        shift = np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1]) + yaw * self.p.max_range_m / 4
        return bool(shift.max() > self.tol * self.p.resolution_m)

    def _fits(self, nodes: list[F64], kfs: list[Keyframe]) -> bool:
        if self.grid is None:
            return False
        s = self.grid.spec
        for node, kf in zip(nodes, kfs, strict=True):
            r = kf.reach_m + 0.1
            if (node[0] - r < s.origin_x_m or node[1] - r < s.origin_y_m
                    or node[0] + r > s.origin_x_m + s.width_m
                    or node[1] + r > s.origin_y_m + s.height_m):
                return False
        return True
