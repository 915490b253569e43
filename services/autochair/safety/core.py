"""Pure safety-monitor core: speed bounds from a laser scan and the current motion.

The chair's footprint is a rectangle in the chair frame (origin at the drive-axle centre, x
forward, y left): `front_m` ahead of the axle, `rear_m` behind it, `half_width_m` to each side
(the [chair] geometry), grown by `padding_m`. For each direction of motion (forward, reverse,
turn in place counter-clockwise, clockwise) the core sweeps that rectangle along the path in
small steps and finds the free extent: how far (m, or rad) the chair can move before a scan
point is inside it. A point already inside the padded rectangle only blocks a direction that
takes it deeper, so the chair can always back or turn away from something it is touching.

Forward and reverse follow the current arc (curvature ω/v from odometry while moving in that
direction, else straight). The bound for a free extent d is the largest speed that still stops
within d − stop_margin after a reaction latency t_r at decel a:  v·t_r + v²/(2a) = d − margin.
The same with angular decel for ω (one symmetric bound: SafetyLimit has a single |ω| field).

Unknown is unsafe (`SafetyCore.assess`, what the node uses):

- A scan whose fields are non-finite or absurd (angles, increment, range window, beam count
  against the angles, frame) is rejected: every direction is blocked (`check_scan`).
- Blind sector: the *swept sector* of a direction is the set of beams whose bearing from the
  laser falls within the bearings of the region that direction's sweep newly occupies within
  the horizon (the swept footprint minus the footprint the chair already covers: the laser sits
  inside the footprint, so the whole sweep would surround it; `SafetyCore.sector`, 0.1° bins;
  straight ahead that is −81°..+64° from the laser for the default chair). When fewer than
  `min_valid_fraction` of those beams hold a valid range (a blinded, fogged or dazzled laser
  reports error codes, NaN here, which would otherwise read as "nothing there"), that direction
  is blocked (free extent 0). The reverse sector, unless the laser sees all of it (behind a
  240° laser it sees little or none: the unseen rear, bounded below), is judged by the whole
  scan's fraction, so a blind laser blocks every direction.
- Unseen rear: the footprint boundary points the laser cannot see (their bearing from the laser
  is outside the scan's angle range) swing at radius R around the axle when the chair turns, so
  |ω| ≤ blind_speed_mps / R_max. Autonomy may not reverse into the unseen sector
  (v_rev_autonomy = 0) unless `blind_reverse_autonomy_mps` > 0 allows it (then the smaller of
  that and the reverse bound); attended (teleop) reverse keeps `v_rev`.

`MonitorState` holds the node's fault state (typed: `Fault`) and decides the e-stop messages.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

import msgspec
import numpy as np
import numpy.typing as npt

F64 = npt.NDArray[np.float64]
BOOL = npt.NDArray[np.bool_]
TWO_PI = 2.0 * math.pi
_WINDOW = 5  # poses per coarse window of the sweep (SafetyCore._free)

# Direction names, the order of the per-direction tuples in `Limit`.
DIRECTIONS = ("fwd", "rev", "ccw", "cw")
_WORDS = {"fwd": "ahead", "rev": "behind", "ccw": "turning left", "cw": "turning right"}


class SafetyTuning(msgspec.Struct, kw_only=True, frozen=True, forbid_unknown_fields=True):
    """The monitor's tuning, SI units: the [safety] settings the core uses (the node's
    SafetyConfig extends this, so each default is written once, here). Checked on creation."""

    padding_m: float = 0.05  # grown on every side (laser noise, mounting tolerance)
    decel_mps2: float = 1.0  # planned braking deceleration (comfort limit ~1 m/s²)
    reaction_s: float = 1.0  # latency margin: scan age + PID + chair controller lag (~1 s)
    stop_margin_m: float = 0.10  # stop this short of the obstacle
    alpha_radps2: float = 1.5  # planned angular deceleration
    stop_margin_rad: float = 0.05
    v_max_fwd_mps: float = 1.2  # caps of the published bounds (no obstacle in view)
    v_max_rev_mps: float = 0.5  # attended (teleop) reverse: the laser cannot see behind
    omega_max_radps: float = 1.0
    kappa_max_per_m: float = 3.0  # arc curvature is clamped to this (|ω/v| at low speed)
    moving_mps: float = 0.05  # |v| above this follows the arc, below it the path is straight
    step_m: float = 0.02  # sweep resolution
    step_rad: float = 0.02
    estop_decel_mps2: float = 2.0  # faster than this could not stop: imminent collision
    # Fewer valid beams than this in a direction's swept sector: blind, that direction blocked.
    # Normal scans of the simulated hallway have ≥ 72 % in every sector (5882 poses × 6
    # motions; the least facing along the 22 m corridor, whose far beams are beyond DMAX); a
    # blinded laser has 0 %. 0.3 leaves room for dark or glass surfaces; open spaces wider than
    # DMAX read as blind.
    min_valid_fraction: float = 0.3
    # The footprint the laser cannot see swings at most this fast: |ω| ≤ this / R_max.
    blind_speed_mps: float = 0.3
    # Autonomy may reverse this fast with nothing sensing behind the chair (0 = never).
    blind_reverse_autonomy_mps: float = 0.0
    max_increment_rad: float = math.radians(2.0)  # coarser scans miss chair legs: rejected
    max_range_min_m: float = 0.5  # a device that cannot see nearer than this: rejected
    max_range_max_m: float = 100.0

    def __post_init__(self) -> None:
        err = self.check()
        if err:
            raise ValueError(err)  # msgspec reports it naming the section when decoding

    def check(self) -> str:
        """"" if sane, else why not (one line)."""
        for name in ("decel_mps2", "alpha_radps2", "step_m", "step_rad", "estop_decel_mps2",
                     "max_increment_rad", "max_range_max_m"):
            if not getattr(self, name) > 0:
                return f"{name} must be > 0"
        for name in ("padding_m", "reaction_s", "stop_margin_m", "stop_margin_rad",
                     "v_max_fwd_mps", "v_max_rev_mps", "omega_max_radps", "kappa_max_per_m",
                     "moving_mps", "blind_speed_mps", "blind_reverse_autonomy_mps",
                     "max_range_min_m"):
            if not getattr(self, name) >= 0:
                return f"{name} must be ≥ 0"
        if not 0.0 <= self.min_valid_fraction <= 1.0:
            return "min_valid_fraction must be within [0, 1]"
        return ""


class SafetyParams(SafetyTuning, kw_only=True, frozen=True):
    """The tuning plus the chair's geometry ([chair]: footprint and laser mount)."""

    front_m: float = 0.95  # footprint ahead of the drive axle (the laser sits at 0.86)
    rear_m: float = 0.25  # behind the axle
    half_width_m: float = 0.35  # 0.7 m wide
    # The laser's (x, y, yaw) in the chair frame ([chair] laser_x_m, laser_y_m, laser_yaw_rad).
    mount: tuple[float, float, float] = (0.8636, 0.2032, 0.0)

    def check(self) -> str:
        for name in ("front_m", "rear_m", "half_width_m"):
            if not getattr(self, name) > 0:
                return f"{name} must be > 0"
        if not all(math.isfinite(m) for m in self.mount):
            return "the laser mount must be finite"
        return super().check()

    @classmethod
    def of(cls, tuning: SafetyTuning, front_m: float, rear_m: float, half_width_m: float,
           mount: tuple[float, float, float]) -> SafetyParams:
        """`tuning` (or any subclass, e.g. the node's config) on this chair."""
        return cls(**{n: getattr(tuning, n) for n in SafetyTuning.__struct_fields__},
                   front_m=front_m, rear_m=rear_m, half_width_m=half_width_m, mount=mount)


@dataclass(frozen=True)
class Limit:
    v_fwd: float
    v_rev: float  # attended (teleop) reverse bound
    omega: float
    free_fwd_m: float  # free extent along the forward path (inf = beyond the horizon)
    free_rev_m: float
    free_ccw_rad: float
    free_cw_rad: float
    nearest_m: float  # nearest scan point to the unpadded footprint (inf: none)
    imminent: bool  # moving faster than could stop within the free extent at estop_decel
    reason: str
    v_rev_autonomy: float = 0.0  # reverse bound for autonomy (0 while nothing sees behind)
    # Valid-beam fraction in each direction's swept sector (fwd, rev, ccw, cw), the whole
    # scan's for a reverse sector not wholly in view; None: no sweep or no scan information.
    valid_fraction: tuple[float | None, ...] = (None, None, None, None)
    blind: tuple[str, ...] = ()  # "blind ahead: 4 % valid beams", ...
    omega_unseen_cap: float = math.inf  # |ω| bound from the unseen footprint swing
    unseen_radius_m: float = 0.0  # R_max of the footprint boundary the laser cannot see
    rear_seen: bool = False  # the reverse sweep lies wholly within the scan's field of view
    rejected: str = ""  # the scan was rejected (why): every direction blocked


def stop_limit(reason: str, rejected: str = "") -> Limit:
    """Every direction blocked."""
    return Limit(v_fwd=0.0, v_rev=0.0, omega=0.0, free_fwd_m=0.0, free_rev_m=0.0,
                 free_ccw_rad=0.0, free_cw_rad=0.0, nearest_m=math.inf, imminent=False,
                 reason=reason, rejected=rejected)


@dataclass(frozen=True)
class Scan:
    """One laser scan as the core sees it (laser frame, metres; invalid beams NaN)."""

    ranges: F64
    angle_min: float
    angle_inc: float
    range_min: float
    range_max: float
    frame_id: str = "laser"

    def angles(self) -> F64:
        return self.angle_min + self.angle_inc * np.arange(self.ranges.size, dtype=np.float64)

    def valid(self) -> BOOL:
        r = self.ranges
        with np.errstate(invalid="ignore"):
            return np.isfinite(r) & (r >= self.range_min) & (r <= self.range_max)


def check_scan(scan: Scan, frame_id: str, p: SafetyParams) -> tuple[str, str]:
    """("", "") if the scan's fields are sane, else (kind, why): kind names a health counter
    (frame, fields, increment, angles, beams, range_window)."""
    if scan.frame_id != frame_id:
        return "frame", f"frame {scan.frame_id!r}, want {frame_id!r}"
    fields = {"angle_min": scan.angle_min, "angle_increment": scan.angle_inc,
              "range_min": scan.range_min, "range_max": scan.range_max}
    bad = [k for k, v in fields.items() if not math.isfinite(v)]
    if bad:
        return "fields", "non-finite " + ", ".join(f"{k} {fields[k]}" for k in bad)
    n = int(scan.ranges.size)
    if scan.ranges.ndim != 1 or n < 2:
        return "beams", f"{n} beams"
    if not 0 < scan.angle_inc <= p.max_increment_rad:
        return "increment", (f"angle increment {scan.angle_inc:.4g} rad outside "
                             f"(0, {p.max_increment_rad:.4g}]")
    span = (n - 1) * scan.angle_inc
    if span >= TWO_PI:
        return "beams", f"{n} beams × {scan.angle_inc:.4g} rad cover {span:.2f} rad > 2π"
    if not -TWO_PI <= scan.angle_min <= TWO_PI:
        return "angles", f"angle_min {scan.angle_min:.4g} rad"
    if not (0 <= scan.range_min <= p.max_range_min_m
            and scan.range_min < scan.range_max <= p.max_range_max_m):
        return "range_window", (f"range window [{scan.range_min:.4g}, {scan.range_max:.4g}] m "
                                f"(want 0 ≤ min ≤ {p.max_range_min_m} < max ≤ "
                                f"{p.max_range_max_m})")
    return "", ""


def scan_points(ranges: F64, angle_min: float, angle_inc: float, range_min: float,
                range_max: float, mount: tuple[float, float, float]) -> F64:
    """Valid beams (finite, within the device's range window) as (N, 2) chair-frame points."""
    r = np.asarray(ranges, dtype=np.float64)
    a = angle_min + angle_inc * np.arange(r.size)
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(r) & (r >= range_min) & (r <= range_max)
    r, a = r[ok], a[ok] + mount[2]
    return np.column_stack((mount[0] + r * np.cos(a), mount[1] + r * np.sin(a)))


def stop_speed(free: float, decel: float, latency: float, margin: float) -> float:
    """Largest speed that stops within free − margin after `latency` at `decel`."""
    d = free - margin
    if d <= 0:
        return 0.0
    if math.isinf(d):
        return math.inf
    return -decel * latency + math.sqrt((decel * latency) ** 2 + 2 * decel * d)


def rect_outline(front: float, rear: float, half_width: float, step: float) -> F64:
    """Boundary points of the rectangle [−rear, front] × [−half_width, half_width], corners
    included, at most `step` apart."""
    def edge(a: tuple[float, float], b: tuple[float, float]) -> F64:
        n = max(1, math.ceil(math.hypot(b[0] - a[0], b[1] - a[1]) / step))
        t = np.arange(n, dtype=np.float64)[:, None] / n  # b itself starts the next edge
        pa, pb = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
        out: F64 = pa + t * (pb - pa)
        return out

    c = [(front, half_width), (-rear, half_width), (-rear, -half_width), (front, -half_width)]
    return np.concatenate([edge(c[i], c[(i + 1) % 4]) for i in range(4)])


SECTOR_BINS = 3600  # bearing resolution of swept sectors: 0.1°


def bearing_bins(angles: F64) -> npt.NDArray[np.int64]:
    """The sector bin of each bearing (rad, any turn)."""
    b = np.floor(np.mod(angles, TWO_PI) * (SECTOR_BINS / TWO_PI)).astype(np.int64)
    return np.minimum(b, SECTOR_BINS - 1)


def cover_bins(lo: F64, width: F64) -> BOOL:
    """Mask of the bins that the bearing intervals [lo, lo + width] (rad) touch."""
    scale = SECTOR_BINS / TWO_PI
    first = np.floor(np.mod(lo, TWO_PI) * scale).astype(np.int64)
    last = first + np.floor(np.mod(lo, TWO_PI) * scale - first + width * scale).astype(np.int64)
    last = np.minimum(last, first + SECTOR_BINS - 1)
    diff = np.zeros(2 * SECTOR_BINS + 1, dtype=np.int64)
    np.add.at(diff, first, 1)
    np.add.at(diff, last + 1, -1)
    covered = np.cumsum(diff)[: 2 * SECTOR_BINS] > 0
    return np.asarray(covered[:SECTOR_BINS] | covered[SECTOR_BINS:])


def fov_bins(start: float, width: float) -> BOOL:
    """Mask of the bins wholly within the field of view [start, start + width]."""
    if width >= TWO_PI - 1e-12:
        return np.ones(SECTOR_BINS, dtype=np.bool_)
    centres = (np.arange(SECTOR_BINS) + 0.5) * (TWO_PI / SECTOR_BINS)
    half = 0.5 * TWO_PI / SECTOR_BINS
    return np.asarray((np.mod(centres - half - start, TWO_PI) <= width)
                      & (np.mod(centres + half - start, TWO_PI) <= width))


def in_fov(angles: F64, start: float, width: float) -> BOOL:
    if width >= TWO_PI - 1e-12:
        return np.ones(angles.shape, dtype=np.bool_)
    return np.asarray(np.mod(angles - start, TWO_PI) <= width + 1e-9)


def unseen_swing(p: SafetyParams, fov: tuple[float, float], step: float = 0.001
                 ) -> tuple[float, float]:
    """(R_max, |ω| cap) for a laser seeing the laser-frame arc `fov` (start, width): R_max is
    the largest distance from the axle of a footprint boundary point whose bearing from the
    laser is outside `fov` (0 if it sees all of it), and the cap blind_speed_mps / R_max."""
    pts = rect_outline(p.front_m, p.rear_m, p.half_width_m, step)
    lx, ly, lyaw = p.mount
    b = np.arctan2(pts[:, 1] - ly, pts[:, 0] - lx) - lyaw
    unseen = ~in_fov(b, *fov)
    if not unseen.any():
        return 0.0, math.inf
    r_max = float(np.hypot(pts[unseen, 0], pts[unseen, 1]).max())
    return r_max, (p.blind_speed_mps / r_max if r_max > 0 else math.inf)


class SafetyCore:
    def __init__(self, params: SafetyParams) -> None:
        self.p = params  # checked when created
        p = params
        lin = p.v_max_fwd_mps * p.reaction_s + p.v_max_fwd_mps ** 2 / (2 * p.decel_mps2)
        self.horizon_m = lin + p.stop_margin_m + 0.5  # a little beyond the longest stop
        self.horizon_rad = min(math.pi, p.omega_max_radps * p.reaction_s
                               + p.omega_max_radps ** 2 / (2 * p.alpha_radps2)
                               + p.stop_margin_rad + 0.2)
        # No pose of any sweep puts the padded footprint beyond this distance from the axle:
        # points farther away cannot block, and dropping them first saves most of the work.
        self.reach_m = self.horizon_m + math.hypot(max(p.front_m, p.rear_m) + p.padding_m,
                                                   p.half_width_m + p.padding_m)
        self._outline_pad = rect_outline(p.front_m + p.padding_m, p.rear_m + p.padding_m,
                                         p.half_width_m + p.padding_m, 0.05)
        self._sectors: dict[tuple[str, float], BOOL | None] = {}
        self._fov: dict[tuple[float, float], tuple[float, float]] = {}
        self._unseen_bins: dict[tuple[float, float], BOOL] = {}

    # --- geometry ------------------------------------------------------------------------------
    def _penetration(self, pts: F64, x: F64, y: F64, th: F64, pad: float) -> F64:
        """(K, N): how deep each point is inside the rectangle at each pose (> 0 inside)."""
        p = self.p
        dx = pts[None, :, 0] - x[:, None]
        dy = pts[None, :, 1] - y[:, None]
        c, s = np.cos(th)[:, None], np.sin(th)[:, None]
        # min(front + pad − lx, lx + rear + pad, half + pad − |ly|) with lx = c·dx + s·dy,
        # ly = −s·dx + c·dy: the same operations in the same order, in place (this runs on
        # every scan at (poses × points); the temporaries cost more than the arithmetic).
        lx = c * dx
        lx += np.multiply(s, dy, out=(tmp := np.empty_like(dx)))
        ly = np.multiply(-s, dx, out=dx)
        ly += np.multiply(c, dy, out=tmp)
        out = np.subtract(p.front_m + pad, lx, out=tmp)
        lx += p.rear_m
        lx += pad
        np.minimum(out, lx, out=out)
        np.abs(ly, out=ly)
        np.subtract(p.half_width_m + pad, ly, out=ly)
        return np.minimum(out, ly, out=out)

    def _free(self, pts: F64, x: F64, y: F64, th: F64, steps: F64) -> float:
        """Free extent along poses (x, y, th)[k] reached after steps[k] (steps[0] = 0): the
        step before the first pose at which a point is inside the padded footprint (or, for a
        point already inside at pose 0, deeper inside).

        Coarse to fine, exactly equal to testing every pose (tests/test_safety_core.py):
        penetration is 1-Lipschitz in a point's position in the chair frame, so a pose within
        `half` steps of a window's centre pose moves any point that could be inside by at most
        `e`; only windows whose centre pose, with the footprint grown by `e`, takes a point
        deeper than it started can hold the first hit. Those are then tested pose by pose.
        """
        if pts.shape[0] == 0:
            return math.inf
        p, pad, k = self.p, self.p.padding_m, x.size
        start = self._penetration(pts, x[:1], y[:1], th[:1], pad)[0]
        floor = np.maximum(start, 0.0)
        half = _WINDOW // 2
        d = float(np.hypot(np.diff(x), np.diff(y)).max(initial=0.0))
        a = float(np.abs(np.diff(th)).max(initial=0.0))
        r0 = math.hypot(max(p.front_m, p.rear_m) + pad, p.half_width_m + pad)
        e = half * (d + a * r0) / (1.0 - math.sqrt(2.0) * half * a) + 1e-9
        centres = np.arange(0, k, _WINDOW)
        if k - 1 > centres[-1] + half:  # the last poses are nobody's window yet
            centres = np.append(centres, k - 1)
        grown = self._penetration(pts, x[centres], y[centres], th[centres], pad + e)
        for c in centres[np.flatnonzero((grown > floor[None, :]).any(axis=1))]:
            lo, hi = max(1, c - half), min(k, c + half + 1)
            if lo >= hi:
                continue
            pen = self._penetration(pts, x[lo:hi], y[lo:hi], th[lo:hi], pad)
            blocked = (pen > 0) & ((start <= 0)[None, :] | (pen > start[None, :] + 1e-9))
            hit = np.flatnonzero(blocked.any(axis=1))
            if hit.size:
                return float(steps[lo + hit[0] - 1])  # the last free step
        return math.inf

    def _arc(self, kappa: float, sign: float) -> tuple[F64, F64, F64, F64]:
        s = np.arange(0.0, self.horizon_m + self.p.step_m, self.p.step_m)
        d = sign * s
        if abs(kappa) < 1e-6:
            return d, np.zeros_like(d), np.zeros_like(d), s
        th = kappa * d
        return np.sin(th) / kappa, (1 - np.cos(th)) / kappa, th, s

    def _kappa(self, v: float, omega: float) -> float:
        p = self.p
        if abs(v) > p.moving_mps:
            return max(-p.kappa_max_per_m, min(p.kappa_max_per_m, omega / v))
        return 0.0

    def _paths(self, v: float, omega: float) -> dict[str, tuple[F64, F64, F64, F64]]:
        p = self.p
        kappa = self._kappa(v, omega)
        phi = np.arange(0.0, self.horizon_rad + p.step_rad, p.step_rad)
        zero = np.zeros_like(phi)
        return {"fwd": self._arc(kappa if v > 0 else 0.0, 1.0),
                "rev": self._arc(kappa if v < 0 else 0.0, -1.0),
                "ccw": (zero, zero, phi, phi), "cw": (zero, zero, -phi, phi)}

    def sector(self, x: F64, y: F64, th: F64) -> BOOL | None:
        """The bearings (a mask over SECTOR_BINS, laser frame) at which the laser looks into
        the region that the footprint newly occupies along poses (x, y, th): the padded
        footprint at each pose minus the one at pose 0. None if it occupies nothing new.

        The far end of a ray's stretch through that region lies on the outline of some pose,
        so the bearings of the outline pieces outside the first footprint are the sector.
        """
        p = self.p
        k = np.unique(np.append(np.arange(0, x.size, 2), x.size - 1))  # ~4 cm / 0.04 rad
        o = self._outline_pad
        c, s = np.cos(th[k])[:, None], np.sin(th[k])[:, None]
        wx = x[k][:, None] + c * o[None, :, 0] - s * o[None, :, 1]  # (poses, outline)
        wy = y[k][:, None] + s * o[None, :, 0] + c * o[None, :, 1]
        pad = p.padding_m
        outside = np.minimum(np.minimum(p.front_m + pad - wx, wx + p.rear_m + pad),
                             p.half_width_m + pad - np.abs(wy)) < -1e-9
        lx, ly, lyaw = p.mount
        b = np.arctan2(wy - ly, wx - lx) - lyaw
        b2 = np.roll(b, -1, axis=1)  # each outline piece: from a point to the next
        seg = outside | np.roll(outside, -1, axis=1)
        if not seg.any():
            return None
        d = np.mod(b2 - b + math.pi, TWO_PI) - math.pi  # pieces subtend the short way
        lo = np.where(d >= 0, b, b2)[seg]
        return cover_bins(lo, np.abs(d)[seg])

    def _sector_of(self, name: str, kappa: float, path: tuple[F64, F64, F64, F64]
                   ) -> BOOL | None:
        key = (name, kappa)
        if key not in self._sectors:
            if len(self._sectors) > 512:
                self._sectors.clear()
            self._sectors[key] = self.sector(*path[:3])
        return self._sectors[key]

    def fov_swing(self, fov: tuple[float, float]) -> tuple[float, float]:
        """Cached `unseen_swing` for a field of view (start, width)."""
        key = (round(fov[0], 6), round(fov[1], 6))
        if key not in self._fov:
            if len(self._fov) > 64:
                self._fov.clear()
            self._fov[key] = unseen_swing(self.p, fov)
        return self._fov[key]

    def unseen_bins(self, fov: tuple[float, float]) -> BOOL:
        """Cached mask of the bins not wholly within a field of view (start, width): a
        laser's is the same scan after scan."""
        if fov not in self._unseen_bins:
            if len(self._unseen_bins) > 64:
                self._unseen_bins.clear()
            self._unseen_bins[fov] = ~fov_bins(*fov)
        return self._unseen_bins[fov]

    # --- bounds --------------------------------------------------------------------------------
    def limit(self, pts: F64, v: float, omega: float) -> Limit:
        """Bounds for chair-frame scan points `pts` (N, 2) while moving at (v, ω), from the
        geometry alone (no beam validity, no field of view: see `assess`)."""
        return self._limit(pts, v, omega, None)

    def assess(self, scan: Scan, v: float, omega: float, frame_id: str = "laser",
               unseen: F64 | None = None) -> Limit:
        """Bounds for a whole scan: rejected if absurd, blind sectors blocked, |ω| capped by the
        unseen footprint swing, autonomy reverse 0 unless the rear is seen or allowed.
        `unseen`: chair-frame points (N, 2) of obstacles the laser cannot see (keep-out zones),
        judged like the scan's own."""
        kind, why = check_scan(scan, frame_id, self.p)
        if kind:
            return stop_limit(f"scan rejected: {why}", rejected=kind)
        valid = scan.valid()
        pts = scan_points(scan.ranges, scan.angle_min, scan.angle_inc, scan.range_min,
                          scan.range_max, self.p.mount)
        if unseen is not None and unseen.shape[0]:
            pts = np.concatenate((pts, unseen))
        return self._limit(pts, v, omega, (scan, valid))

    def _limit(self, pts: F64, v: float, omega: float, beams: tuple[Scan, BOOL] | None
               ) -> Limit:
        p = self.p
        close = pts[np.hypot(pts[:, 0], pts[:, 1]) <= self.reach_m]
        paths = self._paths(v, omega)
        free = {name: self._free(close, *path) for name, path in paths.items()}
        geometric = dict(free)
        fractions: list[float | None] = [None] * 4
        blind: list[str] = []
        omega_cap, radius, rear_seen = math.inf, 0.0, False
        if beams is not None:
            scan, valid = beams
            angles = scan.angles()
            # Each beam stands for ±half an increment around its bearing.
            fov = (scan.angle_min - scan.angle_inc / 2, scan.ranges.size * scan.angle_inc)
            whole = float(valid.mean())
            kappa = self._kappa(v, omega)
            keys = {"fwd": kappa if v > 0 else 0.0, "rev": kappa if v < 0 else 0.0}
            bins = bearing_bins(angles)
            for i, (name, path) in enumerate(paths.items()):
                mask = self._sector_of(name, keys.get(name, 0.0), path)
                if mask is None:
                    continue
                sel = mask[bins]
                n = int(sel.sum())
                if name == "rev":
                    rear_seen = not (mask & self.unseen_bins(fov)).any()
                    if not rear_seen:
                        n = 0  # the rear is (partly) unseen: see below
                # A sector the laser does not wholly see behind the chair is judged by the whole
                # scan: reversing there is attended only (autonomy may not reverse blind), and
                # the few beams at the edge of the view often look down a corridor (hallway:
                # 1 % of reversing arcs had < 34 % valid). A wholly blind laser blocks it too.
                frac = float(valid[sel].sum()) / n if n else whole
                fractions[i] = frac
                if frac < p.min_valid_fraction:
                    free[name] = 0.0
                    blind.append(f"blind {_WORDS[name]}: {100 * frac:.0f} % valid beams"
                                 + ("" if n else " (rear unseen: whole scan)"))
            radius, omega_cap = self.fov_swing(fov)
        v_fwd = min(p.v_max_fwd_mps, stop_speed(free["fwd"], p.decel_mps2, p.reaction_s,
                                                p.stop_margin_m))
        v_rev = min(p.v_max_rev_mps, stop_speed(free["rev"], p.decel_mps2, p.reaction_s,
                                                p.stop_margin_m))
        w_geo = min(p.omega_max_radps, stop_speed(min(free["ccw"], free["cw"]), p.alpha_radps2,
                                                  p.reaction_s, p.stop_margin_rad))
        w = min(w_geo, omega_cap)
        v_rev_auto = v_rev if rear_seen else min(p.blind_reverse_autonomy_mps, v_rev)
        nearest = math.inf
        if pts.shape[0]:
            nearest = max(0.0, -float(self._penetration(
                pts, np.zeros(1), np.zeros(1), np.zeros(1), 0.0).max()))
        # Could not stop even braking at estop_decel with no latency: a collision is imminent.
        # From what the laser sees only: a blind sector stops the chair by its bound, but is no
        # evidence of an obstacle.
        g = geometric["fwd"] if v > 0 else geometric["rev"]
        imminent = abs(v) > p.moving_mps and v * v > 2 * p.estop_decel_mps2 * g
        turn = min(free["ccw"], free["cw"])
        geo = ("clear" if min(free["fwd"], free["rev"]) == math.inf
               and w_geo >= p.omega_max_radps
               else f"free fwd {free['fwd']:.2f} m rev {free['rev']:.2f} m turn {turn:.2f} rad")
        return Limit(v_fwd=v_fwd, v_rev=v_rev, omega=w, free_fwd_m=free["fwd"],
                     free_rev_m=free["rev"], free_ccw_rad=free["ccw"], free_cw_rad=free["cw"],
                     nearest_m=nearest, imminent=imminent, reason="; ".join([*blind, geo]),
                     v_rev_autonomy=v_rev_auto, valid_fraction=tuple(fractions),
                     blind=tuple(blind), omega_unseen_cap=omega_cap, unseen_radius_m=radius,
                     rear_seen=rear_seen)


# --- the node's state --------------------------------------------------------------------------
class Fault(enum.Enum):
    """Why the monitor publishes a stop regardless of the scan's contents."""

    NO_SCAN = "no scan yet"
    STALE = "scan stale"
    REJECTED = "scan rejected"
    MOUNT = "laser mount mismatch"


class EStopAction(enum.Enum):
    NONE = "none"
    ASSERT = "assert"  # EStopAssert(active=True) on keys.ESTOP_ASSERT
    CLEAR = "clear"  # EStopAssert(active=False) on keys.ESTOP_CLEAR


@dataclass
class MonitorState:
    """The monitor's fault and e-stop state, pure: `now` is monotonic seconds, passed in.

    Faults: no scan (accepted or rejected) for `stale_s`; the latest scan rejected; the laser
    mount in tf_static disagreeing with [chair]. E-stop: assert on every scan while a collision
    is imminent; once it is not, clear on every scan for `clear_hold_s`, and likewise for the
    first `clear_hold_s` of scans after start (a restarted monitor clears a cause it left).
    """

    stale_s: float
    clear_hold_s: float = 1.0
    scan_t: float = -math.inf  # latest scan, accepted or rejected
    rejected: str = ""  # the latest scan's rejection, "scan rejected: why" ("" = accepted)
    mount_error: str = ""  # "" = tf_static agrees with [chair] (or none received yet)
    tf_seen: bool = False
    blind: tuple[str, ...] = ()  # directions the latest scan left blind ("fwd", ...)
    imminent: bool = False
    clear_until: float | None = None  # None: not started; set by the first scan
    reported: tuple[Fault, ...] = field(default=(Fault.NO_SCAN,))

    def on_scan(self, now: float, rejected: str) -> None:
        self.scan_t, self.rejected = now, rejected

    def source_lost(self) -> None:
        """The lidar ingest's token vanished (it died): stale now, not after `stale_s`."""
        self.scan_t = -math.inf

    def on_blind(self, directions: tuple[str, ...]) -> bool:
        """Record which directions the latest scan left blind; True when that changed."""
        changed, self.blind = directions != self.blind, directions
        return changed

    def on_mount(self, error: str) -> bool:
        """Record a tf_static check; True when agreement changed."""
        changed = (not self.tf_seen) or bool(error) != bool(self.mount_error)
        self.tf_seen, self.mount_error = True, error
        return changed

    def stale(self, now: float) -> bool:
        return now - self.scan_t > self.stale_s

    def faults(self, now: float) -> tuple[Fault, ...]:
        out: list[Fault] = []
        if self.stale(now):
            out.append(Fault.NO_SCAN if self.scan_t == -math.inf else Fault.STALE)
        if self.rejected:
            out.append(Fault.REJECTED)
        if self.mount_error:
            out.append(Fault.MOUNT)
        return tuple(out)

    def reason(self, now: float) -> str:
        """Why the monitor stops regardless of the scan ("" = no fault)."""
        parts = []
        for f in self.faults(now):
            if f is Fault.REJECTED:
                parts.append(self.rejected)
            elif f is Fault.MOUNT:
                parts.append(f"laser mount mismatch: {self.mount_error}")
            else:
                parts.append("scan stale")  # none yet, or none lately: the same to the chair
        return "; ".join(parts)

    def poll(self, now: float) -> tuple[tuple[Fault, ...], bool]:
        """The current faults and whether they changed since the last poll."""
        faults = self.faults(now)
        changed, self.reported = faults != self.reported, faults
        return faults, changed

    def estop(self, imminent: bool, now: float) -> tuple[EStopAction, bool]:
        """What to publish for this scan, and whether `imminent` changed."""
        was, self.imminent = self.imminent, imminent
        if imminent:
            return EStopAction.ASSERT, not was
        if was or self.clear_until is None:
            self.clear_until = now + self.clear_hold_s
        return (EStopAction.CLEAR if now <= self.clear_until else EStopAction.NONE), was
