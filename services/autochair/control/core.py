"""Goal manager: waypoints → Park–Kuipers law → comfort limiter → (v, ω). PURE, time passed in.

Waypoints are driven in order; intermediate ones are passed through without stopping (switch to
the next once within `pass_radius_m`, no slowdown towards them); the last one is approached with
the paper's slowdown, then, inside the capture radius, the chair turns in place to the goal yaw
(see law.py). Additions for the final goal (reasons at the ControlConfig fields and in README):
reverse for goals close behind, a pre-turn in place for goals far off the heading, and a
straight final (no steering, braking curve only) once the chair points at the goal. Stale
odometry aborts the goal and brakes through the limiter.
"""

from __future__ import annotations

import itertools
import math
from collections import deque
from dataclasses import dataclass

import msgspec

from autochair.geometry import wrap_angle as wrap
from autochair_msgs import GoalReply, GoalRequest, Pose2D

from .law import Gains, align_omega, braking_speed, egocentric, park_kuipers
from .limits import ComfortLimiter, ComfortLimits

IDLE, ACTIVE, ARRIVED, ABORTED, CANCELLED = "idle", "active", "arrived", "aborted", "cancelled"


class ControlConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """[control] section. SI units."""

    rate_hz: float = 50.0  # command rate while a goal is active (≥ 20)
    status_rate_hz: float = 5.0
    stop_burst_s: float = 0.5  # zeros published after the chair has been braked to rest
    # Park & Kuipers gains (thesis values)
    k1: float = 1.5
    k2: float = 3.0
    beta: float = 0.4
    lam: float = 2.0
    vmax_mps: float = 1.2
    r_thresh_m: float = 1.2
    # comfort limits
    a_max_mps2: float = 1.0
    jerk_max_mps3: float = 2.0
    omega_max_radps: float = 0.9
    omega_acc_max_radps2: float = 2.8
    omega_jerk_max_radps3: float = 7.7
    # The limiter plans at this fraction of the limits above: the drive chain (PID, chair
    # controller) overshoots smooth ramps, and the limits are for the chair, not the command.
    chain_margin: float = 0.6
    # The same for the turn axis (ω, ω̇, ω̈): the angular chain overshoots less (measured).
    chain_margin_omega: float = 0.6
    # beyond the paper
    predict_s: float = 0.7  # drive-chain lag compensated by predicting the pose; 0 = off
    omega_floor_radps: float = 0.5  # min |ω| on tight curves (law.py); 0 = the paper's v(κ)
    # v ≤ rate·r near the goal: the paper's slowdown (vmax/r_thresh = 1/s) gives a heading loop
    # faster than the comfort-limited turn rate can follow (it oscillated); ≥ 1 = the paper's.
    approach_rate_1ps: float = 0.6
    brake_fraction: float = 0.6  # goal braking curve planned at this fraction of a and jerk max
    # Straight final: within this distance, once the chair points at the goal so closely that
    # driving straight on misses it by ≤ capture radius, steering stops (ω = 0) and v brakes
    # onto the along-track distance; the in-place turn then fixes the yaw. The law's κ ~ 1/r
    # otherwise needs v ≤ c·r (an exponential crawl) to stay stable. 0 = off.
    straight_radius_m: float = 1.5
    # Reverse: a final goal within this distance behind the chair is approached backwards
    # when that is cheaper (distance/speed + turning) — the law on the mirrored chair. 0 = off.
    reverse_max_m: float = 2.5
    reverse_vmax_mps: float = 0.5  # backwards speed cap (the laser cannot see behind)
    # Pre-turn: a goal starting more than this far off the chair's (chosen) heading is first
    # faced by turning in place; the law, moving forward only, would drive a loop, and its
    # heading overshoot is an ω reversal near the goal. π = off.
    pre_turn_min_rad: float = 1.0
    pass_radius_m: float = 0.4  # intermediate waypoint counts as passed within this distance
    capture_fraction: float = 0.5  # stop translating at this fraction of the position tolerance
    align_gain_1ps: float = 1.5  # linear tail of the in-place turn
    align_brake_fraction: float = 0.5  # in-place turn brakes at this fraction of ω̇ max
    max_waypoints: int = 1000
    max_goal_distance_m: float = 50.0  # every waypoint within this distance of the chair
    # Abort when the chair does not follow: commanded to move, measured at rest this long
    # (a safety stop, a refusing PID, a blocked wheel). The drive chain responds in ~0.7 s.
    follow_timeout_s: float = 2.0
    # Abort when the remaining distance (+ 0.5 m per rad of yaw error) has not dropped by
    # 5 cm for this long, whatever the chair does (a person must not watch a frozen ETA).
    no_progress_s: float = 15.0
    rest_mps: float = 0.01  # |v| (m/s) and |ω| (rad/s) of the measured chair counted as at rest

    def check(self) -> None:
        if not self.rate_hz >= 20.0:
            raise ValueError(f"rate_hz must be >= 20, not {self.rate_hz}")
        for name in ("status_rate_hz", "k1", "k2", "vmax_mps", "r_thresh_m",
                     "a_max_mps2", "jerk_max_mps3", "omega_max_radps", "omega_acc_max_radps2",
                     "omega_jerk_max_radps3", "pass_radius_m", "align_gain_1ps",
                     "approach_rate_1ps", "max_goal_distance_m", "follow_timeout_s",
                     "no_progress_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be > 0, not {value}")
        for name in ("capture_fraction", "align_brake_fraction", "brake_fraction",
                     "chain_margin", "chain_margin_omega"):
            if not 0 < getattr(self, name) <= 1:
                raise ValueError(f"{name} must be in (0, 1]")
        for name in ("straight_radius_m", "reverse_max_m", "reverse_vmax_mps",
                     "pre_turn_min_rad"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be >= 0, not {value}")

    @property
    def gains(self) -> Gains:
        return Gains(self.k1, self.k2, self.beta, self.lam, self.vmax_mps, self.r_thresh_m)

    @property
    def limits(self) -> ComfortLimits:
        m, mw = self.chain_margin, self.chain_margin_omega
        return ComfortLimits(self.vmax_mps, m * self.a_max_mps2, m * self.jerk_max_mps3,
                             mw * self.omega_max_radps, mw * self.omega_acc_max_radps2,
                             mw * self.omega_jerk_max_radps3)


@dataclass(frozen=True)
class OdomSample:
    x: float
    y: float
    yaw: float
    v: float
    omega: float
    t: float  # receive time, monotonic s


@dataclass(frozen=True)
class Status:
    goal_id: int
    state: str
    waypoint_index: int
    waypoint_count: int
    distance_left_m: float
    eta_s: float
    reason: str


def validate(req: GoalRequest, cfg: ControlConfig, x: float = 0.0, y: float = 0.0) -> str:
    """'' if the request is usable from the chair at (x, y), else a one-line reason."""
    if not req.waypoints:
        return "no waypoints"
    if len(req.waypoints) > cfg.max_waypoints:
        return f"{len(req.waypoints)} waypoints (max {cfg.max_waypoints})"
    for i, p in enumerate(req.waypoints):
        if not all(math.isfinite(c) for c in (p.x_m, p.y_m, p.yaw_rad)):
            return f"waypoint {i} is not finite: ({p.x_m}, {p.y_m}, {p.yaw_rad})"
        d = math.hypot(p.x_m - x, p.y_m - y)
        if d > cfg.max_goal_distance_m:
            return (f"waypoint {i} is {d:.1f} m away (max_goal_distance_m "
                    f"{cfg.max_goal_distance_m:g})")
    if not (math.isfinite(req.tolerance_m) and req.tolerance_m > 0):
        return f"tolerance_m must be > 0, not {req.tolerance_m}"
    if not (math.isfinite(req.tolerance_rad) and 0 < req.tolerance_rad < math.pi):
        return f"tolerance_rad must be in (0, π), not {req.tolerance_rad}"
    if req.vmax_mps is not None:
        if not (math.isfinite(req.vmax_mps) and req.vmax_mps > 0):
            return f"vmax_mps must be > 0, not {req.vmax_mps}"
        if req.vmax_mps > cfg.vmax_mps:
            return f"vmax_mps {req.vmax_mps} exceeds the configured {cfg.vmax_mps}"
    return ""


class ControlCore:
    def __init__(self, cfg: ControlConfig | None = None, odom_timeout_s: float = 0.3) -> None:
        """`odom_timeout_s`: older odometry aborts the goal ([stale] odometry_s in the node)."""
        self.cfg = cfg or ControlConfig()
        self.cfg.check()
        if not odom_timeout_s > 0:
            raise ValueError(f"odom_timeout_s must be > 0, not {odom_timeout_s}")
        self.odom_timeout_s = odom_timeout_s
        self.gains = self.cfg.gains
        self.limiter = ComfortLimiter(self.cfg.limits)
        self.goal_id = 0
        self.state = IDLE
        self.reason = ""
        self.waypoints: list[Pose2D] = []
        self.index = 0
        self.tol_m = 0.05
        self.tol_rad = math.radians(3)
        self.vmax = self.cfg.vmax_mps
        self.aligning = False
        self.straight = False  # straight final engaged (see ControlConfig.straight_radius_m)
        self.reverse: bool | None = None  # direction for the final goal, chosen once
        self.pre_turn = False  # turning in place to face the goal first
        self.odom: OdomSample | None = None
        # What the node learns from the rest of the stack (see the on_* methods).
        self.estop_latched = False
        self.owner = "autonomy"
        self.reverse_allowed = True  # False while the safety monitor forbids blind reversing
        self._still_since: float | None = None  # commanded to move, measured at rest, since
        self._best_left = math.inf  # least remaining cost seen, and when
        self._best_t = 0.0
        self._last_t: float | None = None
        self._ended_t = -math.inf
        self.counters: dict[str, int] = {}
        self._history: deque[tuple[float, float, float]] = deque()  # (dt, v, ω) sent

    # --- inputs -----------------------------------------------------------------------------
    def on_odom(self, odom: OdomSample) -> None:
        if not all(math.isfinite(c) for c in (odom.x, odom.y, odom.yaw, odom.v, odom.omega)):
            self._count("rejected_odom")
            return
        self.odom = odom

    def on_estop(self, latched: bool, now: float) -> None:
        self.estop_latched = latched
        if latched and self.state == ACTIVE:
            self._stopped(ABORTED, "e-stop latched", now)

    def on_owner(self, owner: str, now: float) -> None:
        self.owner = owner
        if owner != "autonomy" and self.state == ACTIVE:
            self._stopped(ABORTED, f"drive handed to {owner}", now)

    def on_limit(self, v_rev_autonomy: float, omega_max: float) -> None:
        """The safety monitor's bounds: no reverse approach when autonomy may not reverse
        (nothing senses behind), and turns planned within its |ω| bound (the unseen swing of
        the footprint, obstacles): the limiter then keeps the path and slows v with ω."""
        self.reverse_allowed = v_rev_autonomy > 0.0
        self.limiter.cap_omega(omega_max)  # (the PID clamps the command to it anyway)

    def set_goal(self, req: GoalRequest, now: float) -> GoalReply:
        o = self.odom
        error = validate(req, self.cfg, *((o.x, o.y) if o is not None else (0.0, 0.0)))
        if not error and (o is None or now - o.t > self.odom_timeout_s):
            error = "no fresh odometry: is the odometry service up?"
        if not error and self.estop_latched:
            error = "the e-stop is latched: release it first (autochair release)"
        if not error and self.owner != "autonomy":
            error = f"the drive is handed to {self.owner}: hand it back first"
        if error:
            self._count("rejected_goals")
            return GoalReply(ok=False, error=error)
        assert o is not None
        if self.state != ACTIVE:
            # Start from what the chair does now (at rest, or teleop), never from what an
            # earlier goal last commanded: nothing lunges.
            self.limiter.reset(o.v, o.omega)
        self.goal_id += 1
        self.waypoints = [Pose2D(p.x_m, p.y_m, wrap(p.yaw_rad)) for p in req.waypoints]
        self.index = 0
        self.tol_m, self.tol_rad = req.tolerance_m, req.tolerance_rad
        self.vmax = req.vmax_mps or self.cfg.vmax_mps
        self.aligning = self.straight = False
        self.reverse, self.pre_turn = None, False
        self.state, self.reason = ACTIVE, ""
        self._still_since, self._best_left, self._best_t = None, math.inf, now
        self._count("goals")
        return GoalReply(ok=True, goal_id=self.goal_id)

    def cancel(self, now: float) -> GoalReply:
        if self.state != ACTIVE:
            return GoalReply(ok=True, goal_id=0, error="no active goal")
        self._end(CANCELLED, "cancelled by request", now)
        return GoalReply(ok=True, goal_id=self.goal_id)

    # --- the loop ---------------------------------------------------------------------------
    def step(self, now: float) -> tuple[float, float] | None:
        """(v, ω) to publish now, or None when idle and at rest (leave the chair to others)."""
        dt = 0.0 if self._last_t is None else min(max(now - self._last_t, 0.0), 0.1)
        self._last_t = now
        v_des = w_des = 0.0
        if self.state == ACTIVE:
            if self.odom is None or now - self.odom.t > self.odom_timeout_s:
                age = math.inf if self.odom is None else now - self.odom.t
                self._count("stale_odom_aborts")
                self._end(ABORTED, f"stale odometry ({age:.2f} s > "
                          f"{self.odom_timeout_s} s)", now)
            else:
                v_des, w_des = self._desired(self._predicted(self.odom), now)
                self._watch_progress(self.odom, now)
        if self.state != ACTIVE and self.limiter.at_rest \
                and now - self._ended_t > self.cfg.stop_burst_s:
            return None
        v, w = self.limiter.step(v_des, w_des, dt)
        self._history.append((dt, v, w))
        while len(self._history) > 1 and sum(h[0] for h in self._history) > \
                self.cfg.predict_s + dt:
            self._history.popleft()
        if self.state != ACTIVE and not self.limiter.at_rest:
            self._ended_t = now  # the zero burst starts once braked to rest
        return v, w

    def _watch_progress(self, o: OdomSample, now: float) -> None:
        """Abort a goal the chair does not follow, or that makes no progress."""
        cfg = self.cfg
        moving_cmd = abs(self.limiter.v.value) > 0.05 or abs(self.limiter.w.value) > 0.05
        at_rest = abs(o.v) < cfg.rest_mps and abs(o.omega) < cfg.rest_mps
        if not (moving_cmd and at_rest):
            self._still_since = None
        elif self._still_since is None:
            self._still_since = now
        elif now - self._still_since > cfg.follow_timeout_s:
            self._stopped(ABORTED, f"the chair does not follow: commanded to move, at rest for "
                                   f"{cfg.follow_timeout_s:g} s (a safety stop, a stopped "
                                   "drive chain or a blocked wheel?)", now)
            return
        goal = self.waypoints[-1]
        left = self.status().distance_left_m + 0.5 * abs(wrap(goal.yaw_rad - o.yaw))
        if left < self._best_left - 0.05:
            self._best_left, self._best_t = left, now
        elif now - self._best_t > cfg.no_progress_s:
            self._stopped(ABORTED, f"no progress for {cfg.no_progress_s:g} s "
                                   f"({self.status().distance_left_m:.2f} m left)", now)

    def _stopped(self, state: str, reason: str, now: float) -> None:
        """End the goal for a stop the chair did not ask for: the command restarts from the
        measured velocity, so a later goal never continues an old ramp."""
        self._end(state, reason, now)
        if self.odom is not None:
            self.limiter.reset(self.odom.v, self.odom.omega)
        self._count("stopped_" + state)

    def _predicted(self, o: OdomSample) -> OdomSample:
        """The pose once the commands already sent (last `predict_s`) have acted: the drive
        chain (joystick controller delay, PID, inertia) lags by about that much, and a feedback
        law acting on the lagging pose overshoots, above all near the goal where κ ~ 1/r."""
        x, y, yaw = o.x, o.y, o.yaw
        for dt, v, w in self._history:
            yaw_mid = yaw + 0.5 * w * dt
            x += v * math.cos(yaw_mid) * dt
            y += v * math.sin(yaw_mid) * dt
            yaw += w * dt
        return OdomSample(x, y, wrap(yaw), o.v, o.omega, o.t)

    def _desired(self, o: OdomSample, now: float) -> tuple[float, float]:
        cfg = self.cfg
        while self.index < len(self.waypoints) - 1:
            wp = self.waypoints[self.index]
            if math.hypot(wp.x_m - o.x, wp.y_m - o.y) > cfg.pass_radius_m:
                out = park_kuipers(o.x, o.y, o.yaw, wp.x_m, wp.y_m, wp.yaw_rad, self.gains,
                                   self.vmax, slowdown=False,
                                   omega_floor=cfg.omega_floor_radps)
                return out.v_mps, out.omega_radps
            self.index += 1
        goal = self.waypoints[-1]
        r = math.hypot(goal.x_m - o.x, goal.y_m - o.y)
        flip = 0.0
        if self.reverse is None:
            self.reverse = self._choose_reverse(o, goal, r)
            flip = math.pi if self.reverse else 0.0
            delta = egocentric(o.x, o.y, wrap(o.yaw + flip), goal.x_m, goal.y_m, goal.yaw_rad)[2]
            self.pre_turn = abs(o.v) < 0.1 and abs(delta) > cfg.pre_turn_min_rad
        flip = math.pi if self.reverse else 0.0  # reverse = the law on the mirrored chair
        sign = -1.0 if self.reverse else 1.0
        vmax = min(self.vmax, cfg.reverse_vmax_mps) if self.reverse else self.vmax
        capture = self.tol_m * cfg.capture_fraction
        if r <= capture:
            self.aligning = True
        elif r > self.tol_m:
            self.aligning = False  # drifted out: approach again
        if self.pre_turn and not self.aligning:
            delta = egocentric(o.x, o.y, wrap(o.yaw + flip), goal.x_m, goal.y_m, goal.yaw_rad)[2]
            if r * abs(math.sin(delta)) > 0.5 * capture or abs(delta) > math.pi / 2:
                lim = self.limiter.lim
                return 0.0, align_omega(-delta, lim.omega_max_radps, cfg.align_brake_fraction
                                        * lim.omega_acc_max_radps2, cfg.align_gain_1ps)
            self.pre_turn = False  # facing it: drive (straight final or the law)
        if not self.aligning:
            out = park_kuipers(o.x, o.y, wrap(o.yaw + flip), goal.x_m, goal.y_m,
                               wrap(goal.yaw_rad + flip), self.gains, vmax,
                               omega_floor=cfg.omega_floor_radps)
            along = r * math.cos(out.delta_rad)
            lateral = abs(r * math.sin(out.delta_rad))
            if not self.straight and r <= cfg.straight_radius_m and along > 0.0 \
                    and lateral <= capture:
                self.straight = True
            elif self.straight and lateral > self.tol_m:
                self.straight = False  # pushed off the line: steer again
            if self.straight and along <= capture:
                self.aligning = True  # stopped beside the goal, within tolerance
                return self._align(goal, o, now)
            dist = along if self.straight else r
            # Braking curve, evaluated where the chair will be once the limiter has swung its
            # acceleration round to braking (it may still be accelerating now).
            f = cfg.brake_fraction
            ax = self.limiter.v
            swing = max(sign * ax.rate + f * ax.amax, 0.0) / ax.jmax
            r_eff = dist - max(sign * ax.value, 0.0) * swing
            v = braking_speed(r_eff, f * ax.amax, f * ax.jmax)
            if self.straight:  # no steering, so no slowdown needed: the braking curve alone
                return sign * min(vmax, v), 0.0
            v = min(v, out.v_mps, cfg.approach_rate_1ps * r)
            return sign * v, out.kappa_1pm * v
        return self._align(goal, o, now)

    def _choose_reverse(self, o: OdomSample, goal: Pose2D, r: float) -> bool:
        """Backwards if the goal is close behind and that is cheaper: distance at each
        direction's speed plus the turning the law has to do (|θ| + |δ| at the floor rate)."""
        cfg = self.cfg
        if r > cfg.reverse_max_m or cfg.reverse_vmax_mps <= 0.0 or abs(o.v) > 0.1 \
                or not self.reverse_allowed:
            return False  # never reverse out of motion (a stop and a direction change)

        def cost(flip: float, vmax: float) -> float:
            _, theta, delta = egocentric(o.x, o.y, wrap(o.yaw + flip), goal.x_m, goal.y_m,
                                         wrap(goal.yaw_rad + flip))
            return r / vmax + (abs(theta) + abs(delta)) / cfg.omega_floor_radps

        return cost(math.pi, min(self.vmax, cfg.reverse_vmax_mps)) < cost(0.0, self.vmax)

    def _align(self, goal: Pose2D, o: OdomSample, now: float) -> tuple[float, float]:
        cfg = self.cfg
        e = wrap(goal.yaw_rad - o.yaw)
        # Turn down to the capture band, then brake; arrived once braked to rest in tolerance.
        if abs(e) <= self.tol_rad * cfg.capture_fraction or (
                abs(e) <= self.tol_rad and self.limiter.at_rest):
            # Arrived once the chair itself is at rest, not just the command: the drive chain
            # still coasts for ~0.5 s after the last non-zero command.
            a = self.odom
            if self.limiter.at_rest and a is not None and abs(a.v) < cfg.rest_mps \
                    and abs(a.omega) < cfg.rest_mps \
                    and math.hypot(goal.x_m - a.x, goal.y_m - a.y) <= self.tol_m:
                self._end(ARRIVED, "", now)
            return 0.0, 0.0
        lim = self.limiter.lim
        w = align_omega(e, lim.omega_max_radps, cfg.align_brake_fraction
                        * lim.omega_acc_max_radps2, cfg.align_gain_1ps)
        return 0.0, w

    def _end(self, state: str, reason: str, now: float) -> None:
        self.state, self.reason = state, reason
        self._ended_t = now
        self._count(state)

    def _count(self, name: str) -> None:
        self.counters[name] = self.counters.get(name, 0) + 1

    # --- status -----------------------------------------------------------------------------
    def status(self) -> Status:
        dist = eta = 0.0
        o = self.odom
        if self.waypoints and o is not None and self.state == ACTIVE:
            wps = self.waypoints[self.index:]
            dist = math.hypot(wps[0].x_m - o.x, wps[0].y_m - o.y) + sum(
                math.hypot(b.x_m - a.x_m, b.y_m - a.y_m) for a, b in itertools.pairwise(wps))
            eta = self.eta(dist, wrap(self.waypoints[-1].yaw_rad - o.yaw))
        return Status(self.goal_id, self.state, self.index, len(self.waypoints), dist, eta,
                      self.reason)

    def eta(self, dist: float, yaw_error: float) -> float:
        """Rough time left from the law's own speed profile: cruise at vmax, then the
        exponential slowdown v = vmax·r/r_thresh down to the capture radius, then the turn."""
        capture = self.tol_m * self.cfg.capture_fraction
        rt = self.cfg.r_thresh_m
        t = max(dist - rt, 0.0) / self.vmax
        if dist > capture:
            t += rt / self.vmax * math.log(min(dist, rt) / capture)
        return t + abs(yaw_error) / self.cfg.omega_max_radps if dist <= self.tol_m else t

