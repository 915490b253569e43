"""Localization core, pure: odometry-predicted, scan-matched pose of the chair on a known map.

A 3-state Kalman filter in the map frame. Prediction: the odometry increment since the last
scan (`odom` is the odometry pose, odom frame), with noise growing with distance and turn.
Update: the scan refined on the map's distance field (matching.refine) from the prediction,
with the match's information matrix as measurement noise, so a corridor's weak axis is left to
odometry. Quality is the fraction of scan points that fall on the map.

States (LocState): INITIALIZING (no pose yet: global search over the map's free space, or
a person's guess being checked by a search around it), TRACKING, LOST (quality below
`lost_quality` for `lost_after` scans: search around the last pose in a window that widens
every scan until the scan fits again; a weak fit is checked against the whole map's best).

`correction` is the map→odom transform (REP-105): map pose ∘ odom pose⁻¹.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from .matching import (
    F64,
    BoolGrid,
    DistanceField,
    Match,
    between,
    compose,
    inverse,
    refine,
    search,
    search_wide,
)

# A tracking chair's scans are matched once it has moved this far or turned this much (and
# once a second parked: the node's MoveGate). Not the mapping service's 10 cm / 0.1 rad:
# matched that seldom, a corridor's unobservable drift grew to 13 cm on one of loc_eval's
# self-built maps (7 cm matching every scan; bench.loc_eval, loop, mapping seed 1).
TRACK_MOVE_M = 0.02
TRACK_TURN_RAD = 0.02


class LocState(enum.StrEnum):
    INITIALIZING = "initializing"
    TRACKING = "tracking"
    LOST = "lost"


@dataclass(frozen=True)
class LocParams:
    trans_noise: float = 0.05  # odometry σ per metre travelled (m/m)
    rot_noise: float = 0.05  # odometry yaw σ per radian turned (rad/rad)
    rot_per_m: float = 0.02  # odometry yaw σ per metre travelled (rad/m)
    base_sigma_m: float = 0.005  # floor on prediction noise per scan
    lost_quality: float = 0.45  # a scan fitting worse than this is a bad scan
    found_quality: float = 0.85  # a search result must fit this well to be taken (0.7 let
    # a 5 m-wrong pose in the hallway through: a corridor looks much the same along it)
    sure_quality: float = 0.95  # a lost search's fit below this is checked against the map's
    alias_margin: float = 0.05  # ... best, which must fit this much better to be taken
    lost_after: int = 3  # consecutive bad scans: lost
    search_xy_m: float = 0.8  # first window half-size when lost (grows ×1.5 per scan)
    search_yaw: float = math.radians(30.0)  # first yaw window half-size when lost (grows too)
    max_search_xy_m: float = 8.0
    max_points: int = 200  # scan points used in matching (evenly subsampled)
    gate: float = 25.0  # χ² (3 dof) beyond which a match is not fused, unless it fits well
    # ... for `jump_confirm` scans in a row (the chair was carried): one good-looking match
    # far off is more often a slip of the matcher (measured: a single 13 cm jump at a turn in
    # the hallway, fit 0.99) than a kidnap. (3 of the last 5 instead, with the jump refined
    # further, recovered a chair pushed 36 cm while parked in 8-16 scans instead of 11-26,
    # but took more slips at turns: on-own-map heading max 2.4 -> 8.3 deg. Not taken.)
    jump_confirm: int = 3
    # A chair whose odometry stood still since the last scan (parked: matched once a second)
    # is also searched for within this window, and a confirmed far match is then taken whole:
    # pushed with its wheels free, the refine from the old pose stops in the corridor's local
    # minima (fit 0.98, 10-20 cm off), and a jump took 12-21 scans; measured, see H33.
    still_search_xy_m: float = 0.5
    still_search_yaw: float = math.radians(15.0)
    still_m: float = 0.005  # odometry travel (m, and rad) between scans below which it stood
    # The match's information counts every point as an independent measurement; its errors
    # are not (a submap's wall ends, grid quantisation), so it can be scaled down against
    # the odometry (mapping's tracker: along a corridor only a few points fix the position).
    info_scale: float = 1.0
    refine_prior_m: float | None = None  # matching.refine's prior_m while tracking
    # Learn how good the odometry is: between scans that pin the pose in every direction,
    # `adapt_window_m` of travel apart, the odometry's translation error is compared with the
    # noise the prediction assumed, and the prediction's translation noise scaled (in
    # [adapt_min, 1] × the above: never less sure than configured) so that they agree. A
    # corridor leaves the pose along it to the odometry: the simulator's is good to ~1 %,
    # the SENA chair's is 20 % noisy per keyframe; one fixed figure served one and tore the
    # other. Measured, loop world on its own map (4 mapping seeds): ATE max 8–15 → 5–7.5 cm.
    adapt_odometry: bool = True
    adapt_window_m: float = 1.0
    adapt_min: float = 0.1
    adapt_strong_sd_m: float = 0.01  # a match this sure in every direction is a reference
    adapt_rate: float = 0.3  # fraction of the log-ratio taken per window


@dataclass(frozen=True)
class Estimate:
    pose: F64  # chair in map (x, y, yaw)
    covariance: F64  # (3, 3)
    correction: F64  # map → odom (x, y, yaw)
    quality: float  # fraction of scan points on the map, 0..1
    state: LocState


def chair_cells(occupied: BoolGrid, free: BoolGrid, resolution_m: float) -> BoolGrid:
    """Where the chair's centre may be on a map: ≥ 0.3 m from walls, ≤ 1.2 m from seen free
    space (the centre is behind the laser, often outside its view, so not itself seen)."""
    from scipy import ndimage

    clear, reach = max(1, int(0.3 / resolution_m)), max(1, int(1.2 / resolution_m))
    return np.asarray(ndimage.binary_dilation(free, iterations=reach)
                      & ~ndimage.binary_dilation(occupied, iterations=clear), dtype=np.bool_)


class Localizer:
    def __init__(self, field: DistanceField, free: BoolGrid | None = None,
                 params: LocParams | None = None) -> None:
        self.field, self.free = field, free
        self.p = params or LocParams()
        self.state = LocState.INITIALIZING
        self.pose = np.zeros(3)
        self.cov = np.eye(3)
        self.quality = 0.0
        self._last_odom: F64 | None = None
        self._bad = 0
        self._window = self.p.search_xy_m
        self.scans = 0
        self.searches = 0
        self._far = 0  # good fits far from the prediction in a row
        self._still = False  # the odometry stood still since the last scan
        self._hint: tuple[float, float] | None = None  # a guess's search window (m, rad)
        self.odom_scale = 1.0  # × the translation noise (adapt_odometry)
        self._anchor: tuple[F64, F64] | None = None  # (odometry, matched pose) of a reference
        self._since_var = 0.0  # prediction variance (per axis) and travel since the reference
        self._since_m = 0.0

    def set_pose(self, pose: F64, sigma_xy_m: float = 0.1, sigma_yaw: float = 0.1) -> None:
        """A pose known to this accuracy (SLAM's own keyframe, a closed loop): tracking
        from it."""
        self.pose = np.array(pose, dtype=np.float64)
        self.cov = np.diag([sigma_xy_m**2, sigma_xy_m**2, sigma_yaw**2])
        self.state, self._bad = LocState.TRACKING, 0
        self._anchor = None  # the map frame may have moved (a loop closed): a new reference

    def hint(self, pose: F64, sigma_xy_m: float, sigma_yaw: float) -> None:
        """A person's guess (`autochair localize X Y YAW`): not tracked until a scan fits
        near it. The next scan is searched for over its 2σ window, as AMCL spreads its
        particles over an initial pose's covariance; if nothing fits there, the whole map is
        searched. Tracked from the guess itself, a 36 cm wrong hint stayed 'tracking' 10-20 cm
        off for 10-25 scans on a saved map (the matcher's local minima along a corridor fit
        0.98), and a parked chair is matched once a second."""
        self.pose = np.array(pose, dtype=np.float64)
        self.state, self._bad, self._far = LocState.INITIALIZING, 0, 0
        self._hint = (max(2.0 * sigma_xy_m, 0.1), min(max(2.0 * sigma_yaw, math.radians(5)),
                                                       math.pi))

    def relocalize(self) -> None:
        """Forget the pose: search the whole map (`autochair localize --global`)."""
        self.state, self._hint = LocState.INITIALIZING, None

    def _predict(self, odom: F64) -> None:
        if self._last_odom is None:
            self._last_odom = odom
            return
        delta = between(self._last_odom, odom)
        self._last_odom = odom
        c, s = math.cos(self.pose[2]), math.sin(self.pose[2])
        f = np.array([[1.0, 0.0, -s * delta[0] - c * delta[1]],
                      [0.0, 1.0, c * delta[0] - s * delta[1]], [0.0, 0.0, 1.0]])
        dist, turn = math.hypot(delta[0], delta[1]), abs(delta[2])
        self._still = dist < self.p.still_m and turn < self.p.still_m
        q_xy = (self.odom_scale * (self.p.base_sigma_m + self.p.trans_noise * dist)) ** 2
        self._since_var += q_xy
        self._since_m += dist
        q_yaw = (0.002 + self.p.rot_noise * turn + self.p.rot_per_m * dist) ** 2
        self.pose = compose(self.pose, delta)
        self.cov = f @ self.cov @ f.T + np.diag([q_xy, q_xy, q_yaw])

    def _fuse(self, z: F64, info: F64) -> None:
        r = np.linalg.inv(info + np.eye(3) * 1e-6)
        innov = z - self.pose
        innov[2] = math.atan2(math.sin(innov[2]), math.cos(innov[2]))
        s = self.cov + r
        k = self.cov @ np.linalg.inv(s)
        self.pose = self.pose + k @ innov
        self.pose[2] = math.atan2(math.sin(self.pose[2]), math.cos(self.pose[2]))
        self.cov = (np.eye(3) - k) @ self.cov
        self.cov = 0.5 * (self.cov + self.cov.T)

    def _subsample(self, pts: F64) -> F64:
        if len(pts) <= self.p.max_points:
            return pts
        return pts[np.linspace(0, len(pts) - 1, self.p.max_points).astype(np.int64)]

    def _search(self, pts: F64) -> bool:
        """Around a person's guess, global (INITIALIZING) or windowed (LOST) search; True when
        the scan fits again."""
        self.searches += 1
        if self._hint is not None:
            m = self._near(pts, *self._hint)
            self._hint = None  # if nothing fits near the guess: the whole map, as with none
            return self._fits(m)
        if self.state is LocState.INITIALIZING:
            return self._fits(self._global_search(pts))
        m = self._window_search(pts)
        # A fit in the window may be an alias of a better one further out (a corridor: 0.86
        # at 1.9 m off, 1.00 at 3 m, measured): a fit short of sure is checked against the
        # whole map's best, taken only if clearly better (not a twin room's noise).
        if self.p.found_quality <= m.inliers < self.p.sure_quality:
            whole = self._global_search(pts)
            m = whole if whole.inliers > m.inliers + self.p.alias_margin else m
        return self._fits(m)

    def _global_search(self, pts: F64) -> Match:
        f = self.field.frame
        centre = np.array([f.origin_x_m + self.field.w * self.field.res / 2,
                           f.origin_y_m + self.field.h * self.field.res / 2, 0.0])
        half = max(self.field.w, self.field.h) * self.field.res / 2
        cand, _ = search(self.field, pts, centre, half_xy_m=half, half_yaw=math.pi,
                         step_xy_m=0.2, step_yaw=math.radians(5), free=self.free, max_points=40)
        return refine(self.field, pts, cand)

    def _window_search(self, pts: F64) -> Match:
        """The best fit in the window round the last pose; the window grows for the next."""
        m = self._near(pts, self._window, self.p.search_yaw * self._window / self.p.search_xy_m)
        self._window = min(self._window * 1.5, self.p.max_search_xy_m)
        return m

    def _near(self, pts: F64, half_xy_m: float, half_yaw: float, levels_step: int = 8
              ) -> Match:
        """The best fit within ±half_xy_m, ±half_yaw of the pose."""
        cand, _ = search_wide(self.field, pts, self.pose, half_xy_m=half_xy_m,
                              half_yaw=min(half_yaw, math.pi), free=self.free,
                              levels_step=levels_step)
        return refine(self.field, pts, cand)

    def _fits(self, m: Match) -> bool:
        """A search's result, taken whole (there is no prediction to blend) if it fits well
        enough."""
        if m.inliers < self.p.found_quality:
            return False
        self.pose, self.quality = m.pose, m.inliers
        self.cov = np.asarray(np.linalg.inv(m.information + np.eye(3) * 1e-6),
                              dtype=np.float64) + np.diag([1e-4, 1e-4, 1e-4])
        self.state, self._bad, self._window = LocState.TRACKING, 0, self.p.search_xy_m
        self._far, self._anchor = 0, None  # the odometry since the reference did not carry it
        return True

    def update(self, odom: F64, pts: F64) -> Estimate:
        """One scan: `odom` the odometry pose at the scan's stamp, `pts` the scan's end points
        in the chair frame."""
        self.scans += 1
        self._predict(np.asarray(odom, dtype=np.float64))
        pts = self._subsample(pts)
        if self.state is not LocState.TRACKING:
            self._search(pts)
            return self.estimate()
        m = refine(self.field, pts, self.pose, prior_m=self.p.refine_prior_m)
        if self._still:
            near = self._near(pts, self.p.still_search_xy_m, self.p.still_search_yaw,
                              levels_step=4)  # (coarser: 1.6 ms, not 3.1; as found, 6 seeds)
            m = near if near.inliers > m.inliers else m
        self.quality = m.inliers
        if m.inliers < self.p.lost_quality:
            self._bad += 1
            if self._bad >= self.p.lost_after:
                self.state = LocState.LOST
            return self.estimate()
        self._bad = 0
        info = m.information * self.p.info_scale
        innov = m.pose - self.pose
        innov[2] = math.atan2(math.sin(innov[2]), math.cos(innov[2]))
        chi2 = float(innov @ np.linalg.solve(self.cov + np.linalg.inv(
            info + np.eye(3) * 1e-6), innov))
        if chi2 > self.p.gate:  # far from the prediction: only a good fit, seen repeatedly
            self._far = self._far + 1 if m.inliers >= self.p.found_quality else 0
            if self._far < self.p.jump_confirm:
                return self.estimate()
            if self._still:  # no slip of a turn to fear: the searched pose, taken whole
                self._fits(m)
                return self.estimate()
        self._far = 0
        if self.p.adapt_odometry:
            self._adapt(self._last_odom if self._last_odom is not None else odom, m.pose,
                        m.information)
        self._fuse(m.pose, info)
        return self.estimate()

    def _adapt(self, odom: F64, matched: F64, information: F64) -> None:
        """Scale the odometry noise by how far the odometry's motion between two reference
        scans missed the matched motion, against the variance the prediction assumed."""
        p = self.p
        if np.linalg.eigvalsh(information[:2, :2])[0] < p.adapt_strong_sd_m ** -2:
            return
        if self._anchor is not None and self._since_m < p.adapt_window_m:
            return
        if self._anchor is not None and self._since_var > 0.0:
            e = between(self._anchor[1], matched)[:2] - between(self._anchor[0], odom)[:2]
            ratio = float(e @ e) / (2.0 * self._since_var)  # ~ Exp(1) when the noise is right
            # + Euler's γ: the mean log of an Exp(1) ratio is −γ, not 0
            log_r = math.log(max(ratio, 1e-12)) + 0.5772
            step = p.adapt_rate * 0.5 * float(np.clip(log_r, -3, 3))
            self.odom_scale = float(np.clip(self.odom_scale * math.exp(step), p.adapt_min, 1.0))
        self._anchor = (odom.copy(), matched.copy())
        self._since_var, self._since_m = 0.0, 0.0

    def estimate(self) -> Estimate:
        odom = self._last_odom if self._last_odom is not None else np.zeros(3)
        return Estimate(self.pose.copy(), self.cov.copy(), compose(self.pose, inverse(odom)),
                        self.quality, self.state)
