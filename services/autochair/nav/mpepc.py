"""MPEPC: model-predictive equilibrium-point control (Park, Johnson & Kuipers, IROS 2012). PURE.

The planner chooses z = (r, θ, δ, vmax): the graceful law's target pose relative to the chair
(distance r, target heading θ and chair heading δ against the line of sight) and its speed. Each
candidate is forward-simulated over the horizon with the same law the 50 Hz loop runs
(control/law.py: curvature, v(κ), ω floor, slowdown, in-place turn inside the capture radius)
and a comfort-limited model of the drive chain, and scored by

    J = Σ p_s(k)·Δφ(k)  +  c1·|final heading error|  +  c2·Σ p_c(k)·dt  +  Σ (c3·v² + c4·ω²)·dt
        + hit_cost if any predicted pose touches an obstacle

φ the navigation function (nav/field.py), p_c = exp(−d²/σ²) with d the least clearance of the
footprint outline (σ 0.1 m static, 0.2 m for people, who are predicted at constant velocity
and turned back where that walks them into a wall, `wall_turn`),
p_s(k) the survival probability up to step k. Unlike the paper's Π(1 − p_c) we take
p_s(k) = 1 − max_{j≤k} p_c(j): what p_c models (the tracking and map error of one trajectory)
is the same from step to step, not independent per 0.2 s step; the product made any 0.9 m
doorway (0.1 m each side → p_c 0.37 per step) look fatal, and depended on the step length.
The final heading error is against −∇φ, or against the
goal's yaw once the prediction ends within `goal_blend_m` of the goal.

Optimiser (differs from the reference, which ran NLopt DIRECT then BOBYQA one evaluation at a
time): every candidate of a round is simulated at once with numpy — a fixed quasi-random global
set plus seeds (previous optimum, stop, the goal itself, in-place turns), then rounds of
shrinking Gaussian samples around the best. In Python one sequential evaluation costs ~1 ms, so
DIRECT's 250 + BOBYQA's 75 would take ~0.3 s a cycle; batched, ~400 evaluations take a few tens
of ms (bench/nav_eval.py reports the per-cycle time).
"""

from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt
from scipy.stats import qmc

from autochair.control.law import Gains, heads_for
from autochair.control.limits import AxisState, ComfortLimiter, SCurveAxis
from autochair.geometry import along_lateral

from .field import (
    BATCH_POINTS,
    COARSE_SPACING_M,
    LINE_UP_M,
    NARROW_M,
    Contact,
    CostToGo,
    Footprint,
    NavField,
    heading_through,
    passages,
    place_xy,
    walked_to,
)
from .lattice import HeadingField

F64 = npt.NDArray[np.float64]
ALIGNED_RAD = 0.05  # an in-place turn is done within this heading error (then it may go)
LIMITER_LOOKAHEAD_S = ComfortLimiter().lookahead_s  # ControlConfig.law does not pass it


@dataclass(frozen=True)
class Person:
    """A moving obstacle: a disc, predicted at constant velocity and, where that walks them
    into what the map shows occupied, also turned back off it there (`wall_turn`)."""

    x_m: float
    y_m: float
    vx_mps: float = 0.0
    vy_mps: float = 0.0
    radius_m: float = 0.25
    # How far (s) they were moved on at their velocity from where they were seen (the core's
    # `ahead`): their walk is checked against the map from there (they may have turned in it).
    ahead_s: float = 0.0


@dataclass(frozen=True)
class WallTurn:
    """Where a person's walk meets what the map shows occupied: at `t_s` from now (< 0: while
    they were moved on `ahead_s`), at (x, y), where they turn to walk off at (vx, vy); or
    earlier, from `from_s` on (they turn before they touch the wall, when is not known)."""

    t_s: float
    x_m: float
    y_m: float
    vx_mps: float
    vy_mps: float
    from_s: float

    def span(self, person: Person, t: F64) -> tuple[F64, F64, F64, F64]:
        """At times `t` (≥ from_s) the segment (ax, ay) → (bx, by) they are on if they turned:
        from turning at `from_s` to turning at `t_s` (or walking on still, before it)."""
        ta = self.from_s
        tb = np.minimum(t, self.t_s)
        ax = person.x_m + person.vx_mps * ta + self.vx_mps * (t - ta)
        ay = person.y_m + person.vy_mps * ta + self.vy_mps * (t - ta)
        bx = person.x_m + person.vx_mps * tb + self.vx_mps * (t - tb)
        by = person.y_m + person.vy_mps * tb + self.vy_mps * (t - tb)
        return ax, ay, bx, by


def wall_turn(person: Person, fld: NavField, upto_s: float) -> WallTurn | None:
    """Where `person`, walking on at their velocity from where they were seen, first comes
    within their radius of an occupied cell (within half their clearance when seen, if that
    is less: someone seen beside a wall may walk along it), within `upto_s` s of now; their
    velocity is then mirrored off it (the normal: from the nearest occupied cell's square),
    so someone walking into a wall head-on turns back and someone grazing it walks on along
    it (one turn: what they meet after it is not looked for). People turn short of a wall:
    anywhere from touching it to a radius short of it (not before they were seen). Measured
    (nav_eval --monitor "person: to the side", whose person turns a radius short): predicted
    turning only on touching it, the return was 0.7 s late and the chair still crossed into
    it; allowed up to MpepcParams.react_s (1 s) short, the windows to cross in narrowed so
    much that the chair, hesitating, lost one case (no progress) and parked in the lane in
    another (walked into). A person turning farther out is seen turning at the next plan.

    Why: constant velocity walked people on through walls, so someone turning back at the end
    of a dead end was predicted walking away, and the chair set off across the line they came
    back along (H65). People stop or turn there; turning back is the one of the two that
    reaches the chair. This is the planner's, not the tracker's (people/core.py reports where
    people are and how they move, not where they will be): it needs the map the chair plans
    on and the horizon it predicts over, and the simulator's people (nav_eval) reach the
    planner without the tracker. Reads ~200 clearances per person (half-cell steps)."""
    speed = math.hypot(person.vx_mps, person.vy_mps)
    span = person.ahead_s + upto_s
    if speed < 1e-3 or span <= 0.0:
        return None
    back = person.ahead_s
    sx, sy = person.x_m - person.vx_mps * back, person.y_m - person.vy_mps * back
    tau = np.linspace(0.0, span, math.ceil(span * speed / (fld.map.resolution_m / 2)) + 1)
    c = fld.clearance_xy(sx + person.vx_mps * tau, sy + person.vy_mps * tau)
    limit = min(person.radius_m, float(c[0]) / 2)  # (seen in an occupied cell: 0, never)
    k = int(np.argmax(c < limit))
    if not c[k] < limit:
        return None
    f = (c[k - 1] - limit) / (c[k - 1] - c[k])  # (k ≥ 1: c[0] ≥ limit)
    tw = float(tau[k - 1] + f * (tau[k] - tau[k - 1]))
    wx, wy = sx + person.vx_mps * tw, sy + person.vy_mps * tw
    ob = fld.nearest_obstacle(wx, wy)
    if ob is None:
        return None
    h = fld.map.resolution_m / 2  # (from the nearest point of that cell's square, not its centre)
    nx = wx - min(max(wx, ob[0] - h), ob[0] + h)
    ny = wy - min(max(wy, ob[1] - h), ob[1] + h)
    norm = math.hypot(nx, ny)
    if norm < 1e-9:
        return None
    nx, ny = nx / norm, ny / norm
    dot = person.vx_mps * nx + person.vy_mps * ny
    if dot >= 0.0:  # (walking away from the nearest occupied cell: not into it)
        return None
    return WallTurn(tw - back, wx, wy, person.vx_mps - 2 * dot * nx,
                    person.vy_mps - 2 * dot * ny, max(tw - person.radius_m / speed, 0.0) - back)


class ChainAxisLike(Protocol):
    """One axis of the core's drive-chain model (control/core.py ChainAxis, which imports this
    module): the command delayed by `delay`, then two equal lags `lag`; `future` is its output
    (the chair's mean velocity per step) if no further command came."""

    delay: float
    lag: float

    def future(self, h: float, n: int) -> list[float]: ...


@dataclass(frozen=True)
class Chain:
    """The core's chain predictor when the plan was asked for: the chair's pose now (the
    odometry moved on to now, where the predictor integrates from) and its two axes, holding
    the commands already sent. MPEPC plans from the pose they come to rest at; what the body
    sweeps on the way there and through the committed motion is this chain's response to the
    commands (Mpepc.chain_sweep)."""

    pose: tuple[float, float, float]
    v: ChainAxisLike
    omega: ChainAxisLike
    tick_s: float  # the core's command period (what each command in the chain is held for)


@functools.lru_cache(maxsize=16)
def chain_response(delay: float, lag: float, h: float, n: int) -> F64:
    """(n, n) Toeplitz: [k, j] the chain's (dead time `delay`, two equal lags `lag`) mean output
    over step j of h for a unit command held over step k (ChainAxis's exact lags, continuous
    in time): the integral of the lags' step response is S(t) = t − 2τ + (2τ + t)·e^(−t/τ)."""
    t = np.asarray(np.arange(n + 1) * h - delay, dtype=np.float64)

    def integral(t: F64) -> F64:
        t = np.maximum(t, 0.0)
        if lag <= 0.0:
            return t
        return np.asarray(t - 2 * lag + (2 * lag + t) * np.exp(-t / lag), dtype=np.float64)

    s = integral(t)  # ∫ of the response to a unit step begun at 0, at the step boundaries
    s_late = integral(np.asarray(t - h, dtype=np.float64))  # ... to one begun at h
    g = (np.diff(s) - np.diff(s_late)) / h  # mean output per step of a pulse over [0, h)
    k = np.arange(n)
    lag_steps = k[None, :] - k[:, None]
    out = np.where(lag_steps >= 0, g[np.clip(lag_steps, 0, n - 1)], 0.0)
    out.setflags(write=False)
    return np.asarray(out, dtype=np.float64)


class LawParams(Gains, frozen=True, kw_only=True):
    """The graceful law (its gains) and the comfort limits the 50 Hz loop runs with. Made by
    ControlConfig.law, the one source of these values: no defaults here (a second copy went
    stale: the planner predicted with 0.6 m/s² while the limiter ran at 1.0)."""

    omega_floor_radps: float
    a_mps2: float  # the limiter's planning limits
    omega_max_radps: float
    omega_acc_radps2: float
    align_brake_radps2: float
    align_gain_1ps: float
    capture_m: float
    tolerance_m: float  # the goal's position tolerance (capture_m is a fraction of it)
    # The rest of the comfort limiter (control/limits.py): jerk bounds and the turn-rate
    # look-ahead of its curvature keeping. An acceleration-only model stops ~0.5 m short of the
    # S-curve when braking begins while the chair still accelerates (measured, 1 m/s).
    jerk_mps3: float
    omega_jerk_radps3: float
    # The plan period: a chosen motion is followed this long before the next plan can brake.
    commit_s: float
    # The core's final approach once the goal itself is the target: v also ≤ the braking curve
    # at brake_fraction of a and jerk, and ≤ approach_rate·r (ControlConfig).
    brake_fraction: float
    approach_rate_1ps: float
    lookahead_s: float = LIMITER_LOOKAHEAD_S  # (the limiter's own, not a copy)


@dataclass(frozen=True)
class MpepcParams:
    horizon_s: float = 5.0
    dt_s: float = 0.2  # the paper's step
    # The first fine_s are simulated in substeps (the 50 Hz loop re-evaluates the law; at
    # 0.2 s steps the predicted heading after one plan period was off by up to 14°, measured).
    fine_s: float = 1.0
    fine_substeps: int = 2
    # The motion a plan commits the chair to (its first `commit_s`) and the stop after it are
    # what the collision check must get right: they are simulated at `exact_dt_s` with v's jerk
    # limit, as the core's limiter runs them. Coarser, the stop erred by 3° of yaw braking a
    # turn (the S-curve at 0.1 s steps) and a braking chair was predicted 0.1–0.2 m short (no
    # jerk), which let a plan start a turn whose real stop swung into the bench (nav_eval
    # seed 1, "past the bench"; measured).
    exact_dt_s: float = 0.05
    # v's jerk limit in the predicted motions (the stop after commit_s always has it). Off:
    # with it MPEPC slowed to 0.13 m/s at intermediate waypoints (tests/test_control.py), as
    # the law's slowdown towards a target then predicts an overshoot the core never drives.
    v_jerk: bool = False
    # Predict the core's final approach (braking curve) for the goal itself as target. Off:
    # on, 2 of 40 obstacle-free goals (tests/test_control.py grid) got an ω reversal near the
    # goal; it mattered (the dead end) only with v's jerk on.
    final_approach: bool = False
    r_max_m: float = 8.0
    theta_max_rad: float = math.pi
    delta_max_rad: float = 1.8
    v_min_mps: float = 0.15
    # r below this: turn in place to heading yaw + θ − δ, then (vmax > v_min) drive straight
    # on along it: the paper's targets cannot express "turn here first", which a chair
    # entering a side door from a corridor needs (its body swings 1 m round the axle).
    in_place_r_m: float = 0.1
    sigma_static_m: float = 0.1
    sigma_moving_m: float = 0.2
    stay_weight: float = 0.5  # weight of "the person turns round" (see evaluate)
    react_s: float = 1.0  # a person may be anywhere they can walk to in this time
    c_heading: float = 0.2
    c_collision: float = 1.0
    c_v: float = 0.2
    c_omega: float = 0.1
    hit_cost: float = 10.0
    contact_m: float = 0.05  # a predicted clearance below this counts as a hit
    brake_clear_m: float = 0.05  # least clearance of the stop after `commit_s` (else a hit)
    # ... from every start pose within this timing error of the one planned from. That pose
    # is the core's chain prediction (where the chair stands once the commands sent have
    # acted); a chain model off by δ puts the chair δ·v further on, or back, along its
    # present motion, and all it is committed to with it (the same commands from a moved
    # start: the sweep moved rigidly). A fixed margin does not scale with that: at 1.15 m/s
    # a 10 ms misfit is 1.2 cm, and nav_eval lost cases to ±10 ms (predict_s 0.66/0.68).
    # 30 ms: three times that, ~5 % of the chain's 0.67 s mean lag (tests/test_nav_stop.py).
    # Heading errors are not covered. One turns the whole sweep about its start, so metres
    # away it moves by cm (1.5° at 0.9 rad/s and 30 ms): a band of 30 ms on ω cost nav_eval's
    # door cases 2–6 s and aborted one (seed 7, office A's far corner: MPEPC crept after a
    # spin), 20 ms still 12 s on it, 10 ms 2.2–3 s on room B's corner, while ±10 ms of
    # predict_omega_s changed no nav_eval case (docs/experiments/pid-planned-stream-v4.md).
    stop_timing_s: float = 0.03
    # The committed sweep's poses are read at most this far apart in the outline's travel
    # where it could come under the margin (stop_clearance): as the outline's own points.
    between_m: float = 0.05
    # ... and the body's poses through the drive chain (Mpepc.chain_sweep) kept this far apart
    # in the outline's travel (the fixed ~0.1 s of the rollout's own: 12 cm at 1.2 m/s)
    keep_m: float = 0.12
    goal_blend_m: float = 1.0
    # Inside the heading-aware window, a state from which the lattice has no way to the goal
    # costs this much more than the 2-D field says (nav/lattice.py).
    no_way_cost: float = 1.0
    # Progress on the heading-aware lattice near the goal (nav/lattice.py), where the map has
    # obstacles and the chair is not already at the goal (planner.compute). Session 6, with
    # the prediction that follows the core: nav_eval seed 7 29/32 arrive against 27/32 without
    # (the store room, the L's corner: goals that need the right heading in a tight spot).
    # Also used at the goal itself it made 30/32, but there it takes the chair round a post
    # the other way instead of refusing the blocked final turn (tests/test_control.py).
    # `python -m bench.nav_eval --no-lattice` compares.
    heading_lattice: bool = True
    lattice_within_m: float = 2.0  # ... within this (2-D costs-to-go) of the goal
    lined_up_m: float = 0.3  # see Mpepc.lined_up
    progress_ahead_m: float = 0.0
    goal_slack: float = 0.5  # the goal is taken when it costs at most this much more
    # Within this of the goal, a chair not translating that no plan hands the goal to is given
    # the final manoeuvre directly (Mpepc.final_heading): the lattice's last "drive a few cm,
    # turn in place" needs the chair on one exact 5 cm state, and the law creeps towards
    # targets that close (v ≤ vmax·r/r_thresh); the chair stood 5–10 cm off two tight goals.
    final_move_m: float = 0.3
    # ... whose straight passes within this fraction of the position tolerance of the goal
    # (the capture radius, half of it, left no heading with room at those goals; measured).
    final_line: float = 0.8
    # ... from this many tolerances out: nearer, the manoeuvre's turn, begun just outside the
    # tolerance, was handed over mid-swing as the goal's own turn once the chair stood inside
    # it, the core's straight final drove on while the body still swung, 3 cm past the goal,
    # and its turn there touched office B's desk (nav_eval seed 7; measured).
    final_from: float = 1.5
    # The last turn is checked this far past the point the straight lands on too (a margin;
    # 2 cm left no heading behind the cabinet).
    final_overshoot_m: float = 0.01
    # The in-place turn the core makes onto the goal's yaw once it has the goal is checked
    # before it is handed over (Mpepc.goal_turn_clearance), its sweep sampled this finely at
    # the body's far corners: at 5 cm steps a corner passing an obstacle's corner between two
    # samples is missed by up to 1.3 cm (office B's desk: the 28° turn at the goal sampled
    # at 0.045 m, 0.032 m at 1°; truth 0.017 m; measured).
    goal_turn_step_m: float = 0.01
    # A chair stopped, blocked, where the lattice still has a way (a tight goal's multi-stage
    # way in: "turn to 113°, drive 0.1 m, turn to 45°, drive 0.14 m, turn to 0°"; the law
    # creeps towards targets that close and MPEPC's predictions of it end a cm or two off
    # the lattice's one exact state) is given the way's next stage directly (Mpepc.stage):
    # an in-place turn onto a heading within `stage_turn_deg`, or a straight move of at most
    # `stage_straight_m` along its own heading, that the core executes without the law.
    # (And where no stage nor turn does: the law towards a target just beyond the lattice's
    # way, Mpepc.along_lattice.)
    stages: bool = True
    stage_turn_deg: float = 90.0
    stage_straight_m: float = 0.5
    stage_gain_m: float = 0.05  # a stage must lower the lattice's costs-to-go by this
    stage_final_tries: int = 12  # landings tried for the final manoeuvre (~5 ms each)
    # Where no single stage does, ways of up to this many stages (Mpepc.stage_way), the
    # `stage_beam` most promising landings at each depth tried (~10–25 ms each).
    stage_depth: int = 3
    stage_beam: int = 4
    # A chair at rest this near a door on its way (along the way to its narrowest point; the
    # goal's line-up poses are placed only farther out, field.door_approaches) and not on a
    # clear straight through it turns onto one, then drives it (Mpepc.through_door): the
    # 2-D field's descent bows round the door's frame, the law's arc along it left the chair
    # 0.24 m off the door's line, facing it, with no way through (office A, facing in, to
    # office B: blocked till aborted, nav_eval and live).
    door_ahead_m: float = 1.8
    door_turn_step_deg: float = 1.0  # the straights' headings tried (Mpepc.through_door)
    # ... if it faces away from the way through the door by more than this, or has just
    # turned (a stage): nearer its heading MPEPC's own arc through is left as it was (at 17°,
    # a straight after a turn cost the cluttered room's far side 7 s; measured)
    door_away_rad: float = 0.5 * math.pi
    n_global: int = 128  # rounded to a power of 2 (Sobol)
    n_local: int = 64
    local_rounds: int = 3
    seed: int = 7  # of the local sampler (bench nav_eval --seed: how much outcomes depend on it)

    def __post_init__(self) -> None:
        # Mpepc.chain_sweep takes the committed motion's commands (whole plan steps of dt_s)
        # at steps of exact_dt_s: else the core's chain would go unused, silently (the
        # rollout's own sweep instead: H50's weaker check).
        k = round(self.dt_s / self.exact_dt_s)
        if k < 1 or abs(k * self.exact_dt_s - self.dt_s) > 1e-9:
            raise ValueError(f"dt_s ({self.dt_s:g}) must be a whole number of exact_dt_s "
                             f"({self.exact_dt_s:g})")


@dataclass(frozen=True)
class Plan:
    z: tuple[float, float, float, float]  # r, θ, δ, vmax
    target: tuple[float, float, float]  # the law's target, world frame (x, y, yaw)
    vmax_mps: float
    cost: float
    progress_m: float  # φ(start) − φ(end of the prediction)
    survival: float
    min_clearance_m: float  # least clearance of the footprint along the prediction
    path: F64  # (T, 3) predicted x, y, yaw
    is_goal: bool  # the target is the goal itself
    # least clearance predicted towards the goal itself and braking from the present motion
    # (nan: the goal is out of reach of this plan)
    goal_clearance_m: float
    stop_cost: float  # the cost of braking to a stand-still (blocked: nothing beats it)
    evaluations: int
    # The in-place turn of the final manoeuvre (Mpepc.final_heading): it makes no progress on
    # the costs-to-go, but it is not blocked.
    final_turn: bool = False
    # > 0: drive straight this far along the chair's heading onto `target` and stop (a stage
    # of a manoeuvre: Mpepc.stage); the core moves there without steering (its straight final).
    straight_m: float = 0.0
    # A stage's turn (final_turn): where its straight lands (x, y), driven next from rest
    # (the planner continues the stage rather than look again from the turned chair, where
    # MPEPC's small turns towards the lattice's heading undid it: nav_eval seed 1).
    then: tuple[float, float] | None = None
    # The turn is Mpepc.turn_first's (`then` the chair's own point): carried on only while the
    # half-turned chair's own plan is blocked, and not a stage's turn (through_door's `turned`)
    turn_first: bool = False
    # The goal was not handed over only because the core's turn onto its yaw would not keep
    # `contact_m` (Mpepc.goal_turn_clearance); planner.compute hands it over after all where
    # the chair is otherwise blocked (the check must not make a goal unreachable).
    goal_withheld: bool = False
    # The goal's own motion (row 0: the law towards it, as the core drives its final approach)
    # keeps `brake_clear_m` over what it commits the chair to and the stop after it
    # (`stop_clearance`, its timing band included); True where the goal is out of reach.
    goal_stop_clear: bool = True
    # The chair stood under its margin and this motion gets it out by MPEPC's escape rule
    # (Mpepc.escapes): its least clearance is under contact_m, yet it is not a contact.
    escape: bool = False
    # The door's sight rule where it was planned (Mpepc.sight_cap; inf: none binds): every
    # candidate's vmax, the goal's own approach (row 0) too, was at most this, so the core's
    # own final approach drives no faster (control/core.py _desired)
    sight_mps: float = math.inf
    # A door's crossing straight (Mpepc.door_crossing): the rest of it under way is rechecked
    # at the speed it was given only (stage_plan's `crossing`), not from the least speed up:
    # crossing a person's way, slower is not safer (a crawl is still in it when they come).
    crossing: bool = False
    # ... set off this long after the plan takes effect (standing till then): the crossing's
    # start timed within the plan period (Mpepc.door_crossing)
    start_s: float = 0.0
    # The chair stands for people at a door (Mpepc.through_door's line-up, door_crossing):
    # blocked, the door looked at again at the next plan (the core keeps its line-up's door)
    hold: bool = False


# A stage's straight is evaluated at this many speeds, the least to the top (Mpepc._one_stage):
# one batch of rows, ~1 ms more than the least speed alone
STAGE_SPEEDS = 6
# The core drops the goal on its own final approach where Plan.goal_clearance_m is under this
# (control/core.py): the lowest margin the prediction's clearance is compared with.
GOAL_DROP_M = 0.02
# A chair within a margin already may read this much closer (deeper) than it stands at any
# point of its outline (Mpepc.escapes: the map's noise, not a motion; H57).
TOUCH_M = 0.005
# A door's straight taken moving (a chair reaching its line-up: through_door's `lined`) keeps
# the bare footprint this much more than `contact_m` clear, else the chair brakes there and
# takes the clearest straight from rest (H79): the safety monitor pads the footprint by 0.05 m
# (as contact_m) and its laser reads ranges with σ 0.01 m, so a straight under 3σ more passes a
# jamb's end that a scan may read inside the padded sweep: a stop, or at speed an e-stop.
# Crossings of the 0.9 m door at 0.45 m/s, headings 0–3° (docs/experiments/scripts/
# h79_cross.py), e-stopped at a bare clearance of 0.055 m in 20–80 %, 0.065 m 5 %,
# 0.069–0.075 m 2 of 520, 0.08 m none of 440. (From rest the straight clearest of the laser's
# points is taken, DOOR_GAIN_M: the live map's jambs, grown by the noise, can leave none at this.)
DOOR_NOISE_M = 0.03
# Lined up at a door at rest, the chair turns onto the straight through it that keeps clearest
# of the laser's points unless its own keeps within this of it (Mpepc.through_door, H79): a
# scan's nearest point reads a few mm either way from one scan to the next.
DOOR_GAIN_M = 0.01
# How fast a footprint reading can fall as the outline moves (per m): the bilinear reading of
# a distance field, each partial derivative within ±1 (NavField.clearance_at).
SLOPE = math.sqrt(2.0)


# In-place candidates (indices), whether each turns only (no go after it), the ω axis they
# turn by in their committed motion and each one's state on it (Mpepc.spin_step)
Spin = tuple[npt.NDArray[np.intp], npt.NDArray[np.bool_], SCurveAxis, list[AxisState]]


def wrap(a: F64) -> F64:
    return np.remainder(a + np.pi, 2 * np.pi) - np.pi


def clip(a: F64, lo: F64 | float, hi: F64 | float) -> F64:
    """np.clip's values, without its per-call overhead (~7 µs: the prediction calls it ~10⁵
    times a goal; profiled)."""
    return np.minimum(np.maximum(a, lo), hi)


def braking_speed(d: F64, a: float, j: float) -> F64:
    """control/law.py braking_speed, batched."""
    d = np.maximum(d, 0.0)
    v = np.power(d * math.sqrt(j), 2.0 / 3.0)
    c = a * a / j
    return np.where(v <= c, v, 0.5 * (-c + np.sqrt(c * c + 8.0 * a * d)))


def stop_m(v: float, a: float, j: float) -> float:
    """How far a chair at v (not accelerating) travels braking to rest at deceleration a and
    jerk j: the inverse of braking_speed."""
    c = a * a / j
    return v * math.sqrt(v / j) if v <= c else v * (v + c) / (2.0 * a)


def sight_speed(d: float, a: float, j: float, react_s: float, vmax: float) -> float:
    """The largest speed (≤ vmax) from which the chair, after `react_s`, brakes to rest at a
    and j within d (0: none)."""
    if d <= 0.0:
        return 0.0
    lo, hi = 0.0, vmax
    if hi * react_s + stop_m(hi, a, j) <= d:
        return hi
    for _ in range(40):  # (monotone in v: bisection, to ~1e-12 m/s)
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if mid * react_s + stop_m(mid, a, j) <= d else (lo, mid)
    return lo


def scurve(value: F64, rate: F64, target: F64, vmax: float | F64, amax: float | F64,
           jmax: float | F64, dt: float | F64) -> tuple[F64, F64]:
    """control/limits.py SCurveAxis.step, batched: (value, rate) after one step of dt (the
    limits may be columns: one axis a row; dt may be per candidate)."""
    target = clip(target, -vmax, vmax)
    e = target - value
    jd = jmax * dt
    land = e / dt
    snap = (np.abs(land) <= jd) & (np.abs(land - rate) <= jd)
    m = np.floor(-0.5 + np.sqrt(0.25 + 2.0 * np.abs(e) / (jd * dt)) + 1e-9)
    want = np.sign(e) * np.minimum(amax, m * jd)
    r = clip(rate + clip(want - rate, -jd, jd), -amax, amax)
    v = clip(value + r * dt, -vmax, vmax)
    return np.where(snap, target, v), np.where(snap, land, r)


def move(x: F64, y: F64, yaw: F64, v_old: F64, w_old: F64, st: F64, dt: float | F64
         ) -> tuple[F64, F64, F64]:
    """The pose after a step of dt from the limiter's (v, ω) before it to st's after it, by
    the step's mean v and ω."""
    v, w = 0.5 * (v_old + st[0]), 0.5 * (w_old + st[2])
    mid = yaw + 0.5 * w * dt
    return x + v * np.cos(mid) * dt, y + v * np.sin(mid) * dt, wrap(yaw + w * dt)


def spread(yaw: float, offs: F64, spare: float) -> F64:
    """Headings (O, 3) of stages turning by `offs`: ψ and ψ ± spare (a turn ends a degree or
    two off); the chair's own yaw exactly (no turn)."""
    side: F64 = np.where(offs == 0.0, 0.0, spare)[:, None] * np.array([-1.0, 0.0, 1.0])
    psi: F64 = yaw + offs[:, None] + side
    return psi


def rests_within(info: dict[str, F64], n: int) -> npt.NDArray[np.bool_]:
    """Of the first `n` rollouts in `_costs`' `info`, those that end at rest within the
    horizon (their last step moves < 1 mm): beyond it the prediction says nothing."""
    return np.asarray(np.hypot(info["x"][:n, -1] - info["x"][:n, -2],
                               info["y"][:n, -1] - info["y"][:n, -2]) < 1e-3)


def points_clearance(pts: F64, at: tuple[float, float], psi: F64, ends: F64,
                       fp: Footprint) -> F64:
    """(N,): the least distance from points `pts` (M, 2; NaN rows skipped) to the bare
    footprint swept straight from `at` along each heading psi[n] for ends[n] m: a box from
    `rear_m` behind the start to `front_m` past the end, `half_width_m` either side (negative
    depth not told: a point inside reads 0; one farther than 0.2 m from every sweep may read
    inf)."""
    q = pts[np.isfinite(pts).all(1)] - np.asarray(at)
    # (a point farther than this from `at` is over 0.2 m from every sweep: not a door's jamb)
    reach = float(ends.max(initial=0.0)) + fp.reach_m + 0.2
    q = q[np.hypot(q[:, 0], q[:, 1]) <= reach]
    if q.shape[0] == 0:
        return np.full(psi.shape, math.inf)
    c, s = np.cos(psi)[:, None], np.sin(psi)[:, None]
    lx = c * q[None, :, 0] + s * q[None, :, 1]  # (N, M) along each heading
    ly = np.abs(c * q[None, :, 1] - s * q[None, :, 0])
    ex = np.maximum(np.maximum(lx - (ends[:, None] + fp.front_m), -fp.rear_m - lx), 0.0)
    return np.asarray(np.hypot(ex, np.maximum(ly - fp.half_width_m, 0.0)).min(1))


class Mpepc:
    def __init__(self, field: NavField, law: LawParams, params: MpepcParams | None = None) -> None:
        self.field, self.law = field, law
        self.p = p = params or MpepcParams()
        self.steps = round(p.horizon_s / p.dt_s)
        unit = qmc.Sobol(4, scramble=True, seed=12).random_base2(
            max(1, round(math.log2(p.n_global))))
        lo, hi = self.bounds()
        self._global = lo + unit * (hi - lo)
        self._rng = np.random.default_rng(p.seed)
        self._free: tuple[Chain, dict[float, tuple[F64, F64]]] | None = None
        self._at_pose: dict[tuple[bytes, tuple[Any, ...]], float] = {}

    def bounds(self) -> tuple[F64, F64]:
        p = self.p
        return (np.array([0.0, -p.theta_max_rad, -p.delta_max_rad, p.v_min_mps]),
                np.array([p.r_max_m, p.theta_max_rad, p.delta_max_rad, self.law.vmax_mps]))

    # --- targets ------------------------------------------------------------------------------
    @staticmethod
    def targets(pose: tuple[float, float, float], z: F64) -> F64:
        """World target poses (N, 3) of candidates z (N, 4) from the chair at `pose`."""
        x, y, yaw = pose
        alpha = yaw - z[:, 2]
        return np.stack([x + z[:, 0] * np.cos(alpha), y + z[:, 0] * np.sin(alpha),
                         wrap(alpha + z[:, 1])], 1)

    @staticmethod
    def relative(pose: tuple[float, float, float], target: tuple[float, float, float]) -> F64:
        """z's (r, θ, δ) of a world target pose."""
        x, y, yaw = pose
        r = math.hypot(target[0] - x, target[1] - y)
        alpha = math.atan2(target[1] - y, target[0] - x) if r > 1e-9 else yaw
        return np.array([r, float(wrap(np.array(target[2] - alpha))),
                         float(wrap(np.array(yaw - alpha)))])

    def in_place_targets(self, pose: tuple[float, float, float], z: F64) -> F64:
        """(N, 3) targets of turn-in-place candidates: the heading yaw + θ − δ, at the chair
        (turn only, vmax = v_min) or r_max ahead along it (turn, then go)."""
        psi = wrap(pose[2] + z[:, 1] - z[:, 2])
        go = np.where(z[:, 3] > self.p.v_min_mps + 0.01, self.p.r_max_m, 0.0)
        return np.stack([pose[0] + go * np.cos(psi), pose[1] + go * np.sin(psi), psi], 1)

    # --- prediction ---------------------------------------------------------------------------
    def limiter(self, st: F64, vd: F64, wd: F64, dt: float | F64, v_jerk: bool = True,
                jerk_from: int | None = None) -> None:
        """One step of the comfort limiter (control/limits.py ComfortLimiter.step), batched:
        st = (v, a, ω, ω̇) rows, advanced in place; the curvature kept as it does. dt may be
        per candidate; `jerk_from`: v's jerk limit from this candidate on (else `v_jerk`)."""
        g = self.law
        avd = np.abs(vd)
        avd_ = np.maximum(avd, 1e-9)
        s = np.minimum(1.0, g.omega_max_radps / np.maximum(np.abs(wd), 1e-9))
        s = np.where(avd * s > g.vmax_mps, g.vmax_mps / avd_, s)
        moving = avd * s > 1e-3
        kappa = np.divide(wd, vd, out=np.zeros(vd.size), where=moving)  # (0 where not)
        reach = np.maximum(np.sign(wd) * st[2] + g.omega_acc_radps2 * g.lookahead_s, 0.0)
        s = np.where(kappa != 0.0, np.minimum(
            s, reach / np.maximum(np.abs(kappa), 1e-9) / avd_), s)
        vd, wd = vd * s, wd * s
        big = np.abs(vd) > 1e-3
        cut = (0 if v_jerk else vd.size) if jerk_from is None else jerk_from
        if cut < vd.size:  # v's jerk limit
            j = slice(cut, None)
            dj = dt[j] if isinstance(dt, np.ndarray) else dt
            st[0, j], st[1, j] = scurve(st[0, j], st[1, j], vd[j], g.vmax_mps, g.a_mps2,
                                        g.jerk_mps3, dj)
        if cut > 0:  # acceleration-limited only (see MpepcParams.v_jerk)
            a = slice(0, cut)
            da = dt[a] if isinstance(dt, np.ndarray) else dt
            dv = clip(vd[a] - st[0, a], -g.a_mps2 * da, g.a_mps2 * da)
            st[0, a], st[1, a] = st[0, a] + dv, dv / da
        wt = wd.copy()  # (where not big)
        np.divide(wd * st[0], vd, out=wt, where=big)
        st[2], st[3] = scurve(st[2], st[3], wt, g.omega_max_radps, g.omega_acc_radps2,
                              g.omega_jerk_radps3, dt)

    def simulate(self, pose: tuple[float, float, float], v0: float, w0: float,
                 z: F64, a0: float = 0.0, q0: float = 0.0,
                 goal: tuple[float, float, float] | None = None, last: bool = True,
                 chain: Chain | None = None, line: npt.NDArray[np.bool_] | None = None
                 ) -> tuple[F64, F64, F64, F64, F64, F64, tuple[float, float, float] | None]:
        """Predicted (x, y, yaw, v, ω), each (N, T), of candidates z (N, 4), from the limiter's
        state (v0, a0; ω0, ω̇0); and (3, N, B) poses of the motion committed to until
        `commit_s` (the earliest a next plan can stop the chair) and the stop after it
        (`committed`); and with `chain`, where the body stands before the new commands act
        (the sweeps' start, common to all; else None). Candidates targeting `goal`
        itself, if it is the `last` waypoint, are driven on the core's final approach.
        With the core's `chain`, the committed sweeps are the body's poses as that chain
        passes the committed motion's and the stop's commands on (chain_sweep). `line`: the
        candidates that are a stage's straight (law_step's)."""
        g, dt = self.law, self.p.dt_s
        n = z.shape[0]
        in_place = z[:, 0] < self.p.in_place_r_m
        # (column-major: law_step reads the targets' x, y and yaw columns every step)
        tgt = np.asfortranarray(np.where(in_place[:, None], self.in_place_targets(pose, z),
                                         self.targets(pose, z)))
        vmax = z[:, 3]
        x, y, yaw = np.full(n, pose[0]), np.full(n, pose[1]), np.full(n, pose[2])
        st = np.empty((4, n))
        st[0], st[1], st[2], st[3] = v0, a0, w0, q0
        turning, arrived = in_place.copy(), np.zeros(n, dtype=np.bool_)
        final = np.zeros(n, dtype=np.bool_)
        cap = goal if goal is not None and last else None  # (the core's cap: _law)
        if goal is not None and last and self.p.final_approach:  # targets = the last waypoint
            final = (np.abs(tgt[:, 0] - goal[0]) < 1e-6) \
                & (np.abs(tgt[:, 1] - goal[1]) < 1e-6) & ~in_place
        out = np.empty((5, n, self.steps))
        commit = min(self.steps, max(1, math.ceil(g.commit_s / dt - 1e-9)))
        on_final = final if final.any() else None  # (None: law_step skips that work)
        span = commit * dt
        n_c = max(1, math.ceil(span / self.p.exact_dt_s - 1e-9))  # the committed motion's steps
        fine = math.ceil(self.p.fine_s / dt - 1e-9)
        # The prediction's law steps: (their dt, the step of `out` each completes, else -1)
        sched = [(dt / n_sub, k if j == n_sub - 1 else -1) for k in range(self.steps)
                 for n_sub in [self.p.fine_substeps if k < fine else 1] for j in range(n_sub)]
        # The committed motion (its own steps, v's jerk on) and the stop after it are simulated
        # alongside the prediction, side by side in one batch of 2N: independent simulations
        # with the same numbers as one after the other, at half the numpy calls (their per-call
        # cost dominates at a few hundred candidates). The stop is the law step with vmax 0
        # (the law's v and ω 0: the limiter brakes, as `braking` does, the same numbers).
        both = np.concatenate([st, st], 1)
        xx, yy, ww = np.concatenate([x, x]), np.concatenate([y, y]), np.concatenate([yaw, yaw])
        tgt2, vmax2 = np.asfortranarray(np.concatenate([tgt, tgt])), np.concatenate([vmax, vmax])
        turning2, arrived2 = np.concatenate([turning, turning]), np.concatenate([arrived, arrived])
        final2 = None if on_final is None else np.concatenate([on_final, on_final])
        line2 = None if line is None else np.concatenate([line, line])
        dts = np.full(2 * n, span / n_c)  # (the prediction's half set per step)
        kept: list[F64] = []  # the committed motion's poses, then the stop's
        stop: list[F64] = []
        every = max(1, round(0.5 * dt / self.p.exact_dt_s))  # poses kept: ~0.1 s
        n_b, j_b = self.brake_steps(), -1  # the stop's steps, the one done (-1: not braking)
        m, stopped = len(sched), False  # the steps simulated side by side; the stop done
        # the commands of the committed motion and its stop, (v, ω) (2, N) after each step of
        # exact_dt_s, for chain_sweep
        cmds: list[F64] | None = [] if chain is not None else None
        # The rollout's own poses of the committed motion and its stop are its sweep only
        # without the chain: with it, chain_sweep makes the sweep from the commands.
        own = chain is None
        spin = self.spin(in_place, z, w0, q0)
        for j, (step_dt, k) in enumerate(sched):
            dts[:n] = step_dt
            yaw_was = ww[n:].copy() if j_b < 0 and spin is not None else None
            xx, yy, ww = self.law_step(xx, yy, ww, both, tgt2, vmax2, turning2, arrived2, final2,
                                       dts, jerk_from=0 if self.p.v_jerk else n,
                                       law_upto=None if j_b < 0 else n, cap=cap, line=line2)
            if yaw_was is not None and spin is not None:
                ww[n:] = self.spin_step(spin, yaw_was, ww[n:], both[:, n:], tgt, turning2[n:],
                                        span / n_c)
            if cmds is not None:
                cmds.append(both[0::2, n:].copy())
            if k >= 0:
                out[0, :, k], out[1, :, k], out[2, :, k] = xx[:n], yy[:n], ww[:n]
                out[3, :, k], out[4, :, k] = both[0, :n], both[2, :n]
            if j_b < 0:
                if own and ((j + 1) % every == 0 or j == n_c - 1):
                    kept.append(np.stack([xx[n:], yy[n:], ww[n:]]))
                if j == n_c - 1:  # committed: the stop from here
                    vmax2[n:], dts[n:], j_b = 0.0, self.p.exact_dt_s, 0
                continue
            done = not both[:, n:].any()  # (braking: every candidate at rest)
            if own and ((j_b + 1) % every == 0 or j_b == n_b - 1 or done):
                stop.append(np.stack([xx[n:], yy[n:], ww[n:]]))
            j_b += 1
            if done or j_b == n_b:
                m, stopped = j + 1, True
                break
        side = (xx[n:], yy[n:], ww[n:], both[:, n:].copy())
        sure = np.empty((3, n, 0))
        if j_b < 0:  # (the committed motion outlasts the prediction)
            sure = self.committed(*side, tgt, vmax, turning2[n:].copy(), arrived2[n:].copy(),
                                  on_final, span, m, kept, cmds, spin, cap, line)
        elif own:  # (the stop goes on alone where it outlasts the prediction)
            sure = np.concatenate([np.stack(kept, -1), np.stack(stop, -1) if stopped
                                   else self.braking(*side, j_b, stop, cmds)], -1)
        elif not stopped:  # (its commands only)
            self.braking(*side, j_b, stop, cmds, poses=False)
        origin = None
        if chain is not None and cmds:
            after = np.stack(cmds, -1)
            before = np.concatenate([np.broadcast_to(np.array([[[v0]], [[w0]]]), (2, n, 1)),
                                     after[:, :, :-1]], 2)
            sure, origin = self.chain_sweep(chain, 0.5 * (before + after))  # (steps' means)
        x, y, yaw, st = xx[:n], yy[:n], ww[:n], both[:, :n].copy()
        turning, arrived = turning2[:n].copy(), arrived2[:n].copy()
        for step_dt, k in sched[m:]:
            x, y, yaw = self.law_step(x, y, yaw, st, tgt, vmax, turning, arrived, on_final,
                                      step_dt, self.p.v_jerk, cap=cap, line=line)
            if k >= 0:
                out[0, :, k], out[1, :, k], out[2, :, k] = x, y, yaw
                out[3, :, k], out[4, :, k] = st[0], st[2]
        return out[0], out[1], out[2], out[3], out[4], sure, origin

    def committed(self, x: F64, y: F64, yaw: F64, st: F64, tgt: F64, vmax: F64,
                  turning: npt.NDArray[np.bool_], arrived: npt.NDArray[np.bool_],
                  final: npt.NDArray[np.bool_] | None, span_s: float, start: int = 0,
                  kept: list[F64] | None = None, cmds: list[F64] | None = None,
                  spin: Spin | None = None, cap: tuple[float, float, float] | None = None,
                  line: npt.NDArray[np.bool_] | None = None) -> F64:
        """(3, N, B) poses of what a plan commits the chair to: its first `span_s` as the
        core's limiter drives it (v's jerk on, steps of `exact_dt_s`), then braking to rest from
        there (from its step `start` on, the poses kept before it in `kept`: simulate runs the
        first steps alongside the prediction; in-place candidates turned by the core's own
        move, `spin`: spin_step; `cap`: law_step's). The drive chain's lag (dead time, the PID's
        prefilter: control/core.py ChainAxis) is in the start pose: the core plans from its
        chain predictor's pose (where the chair would stand once the commands already sent
        have acted), and what the chain passes on integrates to the commands, so the stop ends
        where the lagging chair comes to rest (measured 2 cm / 0.7° after a braked 35° swing)
        and the body's real sweep lies within 2.5 cm of the predicted one
        (tests/test_nav_stop.py), inside `brake_clear_m`."""
        h = self.p.exact_dt_s
        n = max(1, math.ceil(span_s / h - 1e-9))
        every = max(1, round(0.5 * self.p.dt_s / h))  # poses kept: the sweep at ~0.1 s
        kept = [] if kept is None else kept
        for k in range(start, n):
            yaw_was = yaw.copy()
            x, y, yaw = self.law_step(x, y, yaw, st, tgt, vmax, turning, arrived, final,
                                      span_s / n, True, cap=cap, line=line)
            if spin is not None:
                yaw = self.spin_step(spin, yaw_was, yaw, st, tgt, turning, span_s / n)
            if cmds is not None:
                cmds.append(st[0::2].copy())
            if (k + 1) % every == 0 or k == n - 1:
                kept.append(np.stack([x, y, yaw]))
        return np.concatenate([np.stack(kept, -1), self.braking(x, y, yaw, st, cmds=cmds)], -1)

    def spin(self, in_place: npt.NDArray[np.bool_], z: F64, w0: float, q0: float
             ) -> Spin | None:
        """The in-place candidates (indices), an ω axis and each one's state on it, at the
        limiter's (ω0, ω̇0), for their committed motion (spin_step); None if none."""
        idx = np.nonzero(in_place)[0]
        if idx.size == 0:
            return None
        g = self.law
        axis = SCurveAxis(g.omega_max_radps, g.omega_acc_radps2, g.omega_jerk_radps3)
        axis.reset(w0, q0)
        # (turn only: in_place_targets)
        return idx, z[idx, 3] <= self.p.v_min_mps + 0.01, axis, [axis.save()] * idx.size

    @staticmethod
    def spin_step(spin: Spin, yaw_was: F64, yaw: F64,
                  st: F64, tgt: F64, turning: npt.NDArray[np.bool_], dt: float) -> F64:
        """The step of dt just taken (law_step) redone for the in-place candidates' ω as the
        core turns them (control/core.py _follow_plan: while the turn is on, or the target
        is the chair's own point): the limiter's time-optimal move onto the heading at its
        full limits (limits.py SCurveAxis.move), not the align law, whose braking at a
        fraction of ω̇ max and linear tail turn more slowly: its committed sweep ended up to
        10° (12 cm at the body's corner) short of where the chair came to rest (blocked
        after one plan; tests/test_nav_stop.py). The yaw by the command held over the step,
        as the chain passes it on; v is the law's (0: braked). Only the committed motion:
        the prediction (a cost, not the check) keeps the align law. The yaws returned; st's
        ω, ω̇ set in place. Each candidate's move is stepped on the one axis, from its own
        state (the same numbers as an axis each, without making one each)."""
        idx, only, axis, states = spin
        on = np.nonzero(only | turning[idx])[0]
        if on.size == 0:
            return yaw
        i = idx[on]
        w, rate = [], []
        for k, d in zip(on.tolist(), wrap(tgt[i, 2] - yaw_was[i]).tolist(), strict=True):
            axis.load(states[k])
            w.append(axis.move(d, dt))
            rate.append(axis.rate)
            states[k] = axis.save()
        st[2, i], st[3, i] = w, rate
        yaw[i] = wrap(yaw_was[i] + np.array(w) * dt)
        return yaw

    def chain_sweep(self, chain: Chain, u: F64
                    ) -> tuple[F64, tuple[float, float, float]]:
        """(3, N, B) poses of the body, ~0.1 s apart, while the core's drive chain (`chain`:
        the commands already sent, and where the chair stands now) passes on the commands
        `u` (2, N, K): each step of `exact_dt_s`'s mean (v, ω) from now on, the committed
        motion's then its stop's, until it has come to rest; from the first step a new
        command can act in (before it every candidate's body moves alike). MPEPC's own
        rollout drives the commands as a unicycle from the pose the chain comes to rest at;
        the chain's axes lag differently (dead time v 0.37 s, ω 0.32 s: the chair turns
        before it has covered the distance the commands pair with each turn), and what is
        still in the chain is covered along the new turn, so the body's path runs off that
        rollout: braking a turn begun at 0.4–1.2 m/s, the body's outline strayed up to 4.9 cm
        (median 1.4) outside the rollout's sweep, 2.6 (1.05) outside this one (36 states,
        the chair behind ChainAxis driven by the core's limiter; the rest is the limiter's
        0.05 s steps; tests/test_nav_stop.py). And the body's pose just before a new command
        acts (the sweeps' common start)."""
        # On the sweep's own spacing (~0.1 s: each pair of steps' mean command; the chain's
        # response to commands held over a step is exact, chain_response), which halves the
        # work against the commands' own steps.
        every = max(1, round(0.5 * self.p.dt_s / self.p.exact_dt_s))
        h = every * self.p.exact_dt_s
        cv, cw = chain.v, chain.omega
        pad = (-u.shape[2]) % every  # (at rest after the stop: zeros)
        if pad:
            u = np.concatenate([u, np.zeros((2, u.shape[1], pad))], 2)
        u = u.reshape(2, u.shape[1], -1, every).mean(3)
        k = u.shape[2]
        lag, delay = max(cv.lag, cw.lag), max(cv.delay, cw.delay)
        m = k + math.ceil((delay + 8 * lag) / h)  # (to rest: the lags decay to < 0.4 %)
        fv, fw = self._chain_future(chain, h, m)
        vel = fv + u[0] @ chain_response(cv.delay, cv.lag, h, m)[:k]  # (N, m)
        w = fw + u[1] @ chain_response(cw.delay, cw.lag, h, m)[:k]
        yaw = chain.pose[2] + h * np.cumsum(w, 1)
        mid = yaw - 0.5 * h * w
        x = chain.pose[0] + h * np.cumsum(vel * np.cos(mid), 1)
        y = chain.pose[1] + h * np.cumsum(vel * np.sin(mid), 1)
        # Kept: from the first step a new command acts in, wherever the outline has moved
        # `keep_m` since the last pose kept (at speed every step; the poses between are read
        # where they could come under the margin: stop_clearance), and where the body rests.
        j0 = min(int(min(cv.delay, cw.delay) / h), m - 1)
        # (each step's travel of the outline, the most of any candidate: |v|·h + reach·|ω|·h)
        travel = h * np.max(np.abs(vel[:, j0:]) + self.field.footprint.reach_m
                            * np.abs(w[:, j0:]), axis=0)
        step = np.floor((np.cumsum(travel) - travel[0]) / self.p.keep_m)
        far = np.cumsum(travel[::-1])[::-1] - travel  # (what is still to come from each pose)
        new = np.concatenate([[True], step[1:] > step[:-1]]) & (far > 0.005)
        idx = list(j0 + np.nonzero(new)[0])
        idx.append(m - 1)
        origin = chain.pose if j0 == 0 else (float(x[0, j0 - 1]), float(y[0, j0 - 1]),
                                             float(yaw[0, j0 - 1]))
        return np.stack([x[:, idx], y[:, idx], yaw[:, idx]]), origin

    def _chain_future(self, chain: Chain, h: float, m: int) -> tuple[F64, F64]:
        """The chain's mean output over each of m steps of h with no new command, per plan:
        ChainAxis.future on the core's own tick (coarser, it holds one command of the
        several in each step), integrated to steps of h."""
        if self._free is None or self._free[0] is not chain:
            self._free = (chain, {})
        got = self._free[1].get(h)
        if got is None or got[0].size < m:
            # (once per plan: as long as the longest stop's sweep can be)
            big = max(m, math.ceil(self.brake_steps() * self.p.exact_dt_s / h) + 2 * math.ceil(
                (self.law.commit_s + max(chain.v.delay, chain.omega.delay)
                 + 8 * max(chain.v.lag, chain.omega.lag)) / h))
            tick = chain.tick_s
            n = math.ceil(big * h / tick - 1e-9)
            at = np.arange(big + 1) * h

            def resample(out: list[float]) -> F64:
                moved = np.concatenate([[0.0], np.cumsum(out) * tick])  # ∫ at the ticks
                return np.asarray(np.diff(np.interp(at, np.arange(n + 1) * tick, moved)) / h,
                                  dtype=np.float64)

            got = (resample(chain.v.future(tick, n)), resample(chain.omega.future(tick, n)))
            self._free[1][h] = got
        return got[0][:m], got[1][:m]

    def law_step(self, x: F64, y: F64, yaw: F64, st: F64, tgt: F64, vmax: F64,
                 turning: npt.NDArray[np.bool_], arrived: npt.NDArray[np.bool_],
                 final: npt.NDArray[np.bool_] | None, dt: float | F64, v_jerk: bool = False,
                 jerk_from: int | None = None, law_upto: int | None = None,
                 cap: tuple[float, float, float] | None = None,
                 line: npt.NDArray[np.bool_] | None = None) -> tuple[F64, F64, F64]:
        """The 50 Hz loop over dt (per candidate if an array): the law (or the in-place turn)
        towards the targets, then the limiter; `turning` and `arrived` are updated in place.
        `final`: the candidates on the core's final approach (None: none). `jerk_from`: v's
        jerk limit for the candidates from this index on only (else `v_jerk` for all).
        `law_upto`: the candidates from this index on brake (vmax 0; their law is not worked
        out, nor their `turning` and `arrived`: simulate's stops, side by side). `cap`: the
        last waypoint, towards which the core caps v (_law; None: not the last). `line`: the
        candidates that are a stage's straight, which the core drives by its time-optimal move
        onto the target's point without steering (_law; None: none)."""
        k = x.size if law_upto is None else law_upto
        vd, wd = self._law(x[:k], y[:k], yaw[:k], st[:, :k], tgt[:k], vmax[:k], turning[:k],
                           arrived[:k], None if final is None else final[:k], cap,
                           None if line is None else line[:k])
        if k < x.size:  # (the law's v and ω with vmax 0, as below: 0)
            rest = np.zeros(x.size - k)
            vd, wd = np.concatenate([vd, rest]), np.concatenate([wd, rest])
        return self.advance(x, y, yaw, st, vd, wd, dt, v_jerk, jerk_from)

    def _law(self, x: F64, y: F64, yaw: F64, st: F64, tgt: F64, vmax: F64,
             turning: npt.NDArray[np.bool_], arrived: npt.NDArray[np.bool_],
             final: npt.NDArray[np.bool_] | None, cap: tuple[float, float, float] | None = None,
             line: npt.NDArray[np.bool_] | None = None) -> tuple[F64, F64]:
        """law_step's desired (v, ω), before the limiter."""
        g = self.law
        tx, ty, tyaw = tgt[:, 0], tgt[:, 1], tgt[:, 2]
        dx, dy = tx - x, ty - y
        r = np.hypot(dx, dy)
        alpha = np.arctan2(dy, dx)
        # the three angle differences wrapped in one call (numpy's per-call cost dominates)
        diff = np.empty((3, x.size))
        np.subtract(tyaw, yaw, out=diff[0])
        np.subtract(tyaw, alpha, out=diff[1])
        np.subtract(yaw, alpha, out=diff[2])
        e, th, de = wrap(diff)
        # As the core's _follow_plan decides every tick (not once): an in-place candidate turns
        # while its yaw error is ≥ 2·ALIGNED_RAD, and the law stops translating only within the
        # capture radius of the target. A chair still rolling when it turned (or past the
        # target) gets the law towards a point behind it, which spins it round: predicted so
        # (a sticky "arrived" predicted a stop; the core's spin touched the bench, seed 1).
        # The core brakes instead where that spin's sweep has no room (H44): a plan that did
        # not happen, replanned from rest.
        arrived[:] = r < g.capture_m
        ae = np.abs(e)
        turning &= ae >= 2 * ALIGNED_RAD
        captured = turning | arrived
        k1t = g.k1 * th
        kappa = -(g.k2 * (de - np.arctan(-k1t)) + (1 + g.k1 / (1 + k1t * k1t)) * np.sin(de)) \
            / np.maximum(r, 1e-6)
        akappa = np.abs(kappa)
        vd = vmax / (1 + g.beta * akappa ** g.lam)
        vd = np.maximum(vd, np.minimum(vmax, g.omega_floor_radps / np.maximum(akappa, 1e-9)))

        def stop_within(d: F64, f: float = 1.0) -> F64:
            # v from which the limiter stops within d braking at f of its limits, from where it
            # will have swung its acceleration round to braking
            swing = np.maximum(st[1] + f * g.a_mps2, 0.0) / g.jerk_mps3
            return braking_speed(d - np.maximum(st[0], 0.0) * swing, f * g.a_mps2,
                                 f * g.jerk_mps3)

        slow = vmax * r / g.r_thresh_m
        if line is not None:  # (a stage's straight: control/core.py _follow_plan drives it by
            # the limiter's time-optimal move onto the target's point, at its full braking, not
            # the law's slowdown over r_thresh, which at the least speed predicted a 0.5 m
            # straight at under 0.06 m/s and so the chair far behind where it is driven)
            slow = np.where(line, stop_within(dx * np.cos(yaw) + dy * np.sin(yaw)), slow)
        vd = np.minimum(vd, slow)
        if cap is not None:  # (control/core.py _follow_plan: heading for the last waypoint, v
            # within a stop on it at the limiter's full braking; unpredicted, office B's door
            # was rolled into 6-9 cm further in 1 s than the core drove: tests/test_control.py)
            c, s = np.cos(yaw), np.sin(yaw)
            gx, gy = cap[0] - x, cap[1] - y
            along = gx * c + gy * s
            heads = heads_for(along, gy * c - gx * s, cap[2] - yaw, st[0], g.tolerance_m,
                              g.omega_acc_radps2)
            if line is not None:
                heads = heads & ~line  # (the core's cap is the law's, not its straight moves')
            if heads.any():
                vd = np.where(heads, np.minimum(vd, stop_within(along)), vd)
        if final is not None:  # (control/core.py _desired: its braking curve)
            vd = np.where(final, np.minimum.reduce(
                [vd, stop_within(r, g.brake_fraction), g.approach_rate_1ps * r]), vd)
        wd = kappa * vd if line is None else np.where(line, 0.0, kappa * vd)
        if captured.any():
            wa = np.sign(e) * np.minimum(np.minimum(g.omega_max_radps, np.sqrt(
                2 * g.align_brake_radps2 * ae)), g.align_gain_1ps * ae)
            vd, wd = np.where(captured, 0.0, vd), np.where(captured, wa, wd)
        # vmax 0 (only the stop seed; the search keeps vmax ≥ v_min): the law's v and ω are 0,
        # i.e. the limiter brakes (v, ω) to rest, as the core does when a plan is blocked.
        halt = vmax <= 0.0
        if halt.any():
            vd, wd = np.where(halt, 0.0, vd), np.where(halt, 0.0, wd)
        return vd, wd

    def advance(self, x: F64, y: F64, yaw: F64, st: F64, vd: F64, wd: F64, dt: float | F64,
                v_jerk: bool = True, jerk_from: int | None = None) -> tuple[F64, F64, F64]:
        """One step of dt: the limiter towards (vd, ωd), the pose by the step's mean v, ω."""
        v_old, w_old = st[0].copy(), st[2].copy()
        self.limiter(st, vd, wd, dt, v_jerk, jerk_from)
        return move(x, y, yaw, v_old, w_old, st, dt)

    def brake_steps(self) -> int:
        """The steps of `exact_dt_s` the longest stop takes."""
        g = self.law
        stop_s = g.vmax_mps / g.a_mps2 + 2 * g.a_mps2 / g.jerk_mps3
        return max(1, math.ceil(stop_s / self.p.exact_dt_s))

    def braking(self, x: F64, y: F64, yaw: F64, st: F64, start: int = 0,
                kept: list[F64] | None = None, cmds: list[F64] | None = None,
                poses: bool = True) -> F64:
        """(3, N, B) poses while the limiter brakes to rest (v, ω desired 0, as the core does
        when a plan says blocked) from state st, at `exact_dt_s` (kept every ~0.1 s), until
        every candidate is at rest; from its step `start` on (the poses kept before it in
        `kept`: simulate runs the first steps alongside the prediction). Without `poses`
        only the commands (`cmds`; chain_sweep makes the sweep from them): (3, N, 0)."""
        g, h = self.law, self.p.exact_dt_s
        steps = self.brake_steps()
        every = max(1, round(0.5 * self.p.dt_s / h))  # poses kept: the sweep at ~0.1 s
        kept = [] if kept is None else kept
        zero = np.zeros((2, x.size))
        # v's and ω's limits as columns: both axes in one call (the same numbers, half the
        # calls; numpy's per-call cost dominates at a few hundred candidates)
        lim = (np.array([[g.vmax_mps], [g.omega_max_radps]]),
               np.array([[g.a_mps2], [g.omega_acc_radps2]]),
               np.array([[g.jerk_mps3], [g.omega_jerk_radps3]]))
        vw, rates = st[0::2], st[1::2]  # views: (v, ω), (v̇, ω̇)
        for k in range(start, steps):
            # advance(…, zero, zero, h), less the limiter's curvature work, which leaves a
            # desired (0, 0) as it is: the same numbers, the planner's longest loop.
            old = vw.copy() if poses else None
            vw[...], rates[...] = scurve(vw, rates, zero, *lim, h)
            if old is not None:
                x, y, yaw = move(x, y, yaw, old[0], old[1], st, h)
            if cmds is not None:
                cmds.append(vw.copy())
            done = not st.any()  # every candidate at rest: the rest is where it stands
            if poses and ((k + 1) % every == 0 or k == steps - 1 or done):
                kept.append(np.stack([x, y, yaw]))
            if done:
                break
        return np.stack(kept, -1) if poses else np.empty((3, x.size, 0))

    # --- cost ---------------------------------------------------------------------------------
    def evaluate(self, pose: tuple[float, float, float], v0: float, w0: float, z: F64,
                 ctg: CostToGo, people: list[Person], a0: float = 0.0, q0: float = 0.0,
                 goal: tuple[float, float, float] | None = None, last: bool = True,
                 hf: HeadingField | None = None, chain: Chain | None = None,
                 line: npt.NDArray[np.bool_] | None = None) -> tuple[F64, dict[str, F64]]:
        p, dt, fld = self.p, self.p.dt_s, self.field
        xs, ys, yaws, vs, ws, brake, origin = self.simulate(pose, v0, w0, z, a0, q0, goal, last,
                                                            chain, line)
        t = np.asarray((np.arange(self.steps) + 1) * dt, dtype=np.float64)
        d0 = self.pose_clearance(pose)
        # A chair already within a margin (a noisy live map, a chair nudged to a wall, a cell
        # drawn under its front) would be blocked by every motion: what is a hit for it is
        # told by the escape rule instead (`escapes`, `stop_keeps`: getting out, on the
        # signed clearance, nothing deeper in nor nearer).
        touch = fld.contact(*pose, TOUCH_M) if d0 < self.escape_below else None
        # (poses read under both contact_m and the 0.02 m the core drops its own approach at,
        # Plan.goal_clearance_m, decide alike whatever the exact reading: left bilinear)
        d_static, to_people = self.outline_distances(
            xs, ys, yaws, people, t, min(p.contact_m, GOAL_DROP_M))  # (N, T)
        pc = np.exp(-(d_static / p.sigma_static_m) ** 2)
        hit = d_static < p.contact_m if touch is None else ~self.escapes(touch, xs, ys, yaws,
                                                                         d_static)
        # A motion is only as safe as the stop after it: the next plan can brake the chair
        # after `commit_s` at the earliest, so that stop must end clear too (else the chair
        # is committed to a contact by the time it sees one, as it was in the cluttered room).
        # Both that motion and its stop as the core's limiter really drives them (committed).
        # (read between its poses only where that can decide: not for a motion that is a hit
        # already, except row 0, the goal's own, which the core may be driving)
        between: npt.NDArray[np.bool_] = np.logical_not(hit.any(1))
        between[0] = True
        if touch is None:
            need = p.brake_clear_m
            stop_hit = self.stop_clearance(pose, v0, w0, brake, need, between,
                                           d0 if origin is None else None, origin) < need
        else:
            stop_hit = ~self.stop_keeps(pose, v0, w0, brake, touch, between, origin)
        hit[:, -1] |= stop_hit
        d_all = d_static
        for person, (to_path, to_here) in zip(people, to_people, strict=True):
            dp = to_path - person.radius_m
            hit |= dp < 0.0
            d_all = np.minimum(d_all, dp)
            pc = 1 - (1 - pc) * (1 - np.exp(-(np.maximum(dp, 0) / p.sigma_moving_m) ** 2))
            # People stop and turn round: the disc they can reach at their speed, whichever
            # way they turn, within `react_s` (the time the chair needs to stop at the comfort
            # limits) is off limits too, so it does not race past where they might step.
            reach = person.radius_m + math.hypot(person.vx_mps, person.vy_mps) * np.minimum(
                t, p.react_s)
            ds = to_here - reach[None, :]
            hit |= ds < 0.0
            pc = 1 - (1 - pc) * (1 - p.stay_weight * np.exp(
                -(np.maximum(ds, 0) / p.sigma_moving_m) ** 2))
        pc = np.where(hit, 1.0, pc)
        ps = 1 - np.maximum.accumulate(pc, axis=1)
        # Progress is measured at a point `progress_ahead_m` in front of the axle: the body
        # lies ahead of it, so the chair then leads with its front through doors and round
        # corners (the axle cuts inside, as a rear-axle vehicle's does).
        la = p.progress_ahead_m
        phi = ctg.at(fld.map, np.stack([xs + la * np.cos(yaws), ys + la * np.sin(yaws)], -1))
        phi0 = float(ctg.at(fld.map, np.array([pose[0] + la * math.cos(pose[2]),
                                               pose[1] + la * math.sin(pose[2])])))
        in_lattice: npt.NDArray[np.bool_] = np.zeros(len(z), dtype=np.bool_)
        if hf is not None and self.lattice_active(hf, pose, phi0):
            phi, phi0, in_lattice = self.heading_phi(hf, xs, ys, yaws, phi, pose, phi0)
        dphi = np.diff(phi, axis=1, prepend=phi0)
        progress = (ps * dphi).sum(1)
        end = np.stack([xs[:, -1], ys[:, -1]], -1)
        want = ctg.descent(fld.map, end)
        gx, gy = ctg.goal_xy
        near = np.hypot(end[:, 0] - gx, end[:, 1] - gy) < p.goal_blend_m
        heading = np.abs(wrap(yaws[:, -1] - want))
        cost = (progress + p.c_heading * heading + p.c_collision * (pc * dt).sum(1)
                + ((p.c_v * vs ** 2 + p.c_omega * ws ** 2) * dt).sum(1)
                + p.hit_cost * hit.any(1))
        return cost, {"phi_end": phi[:, -1], "phi0": np.full(len(z), phi0),
                      "survival": ps[:, -1], "clearance": d_all.min(1), "near": near,
                      "in_lattice": in_lattice.astype(np.float64),
                      "hit": hit.any(1).astype(np.float64),
                      "stop_hit": stop_hit.astype(np.float64),
                      "escape": (np.full(len(z), touch is not None) & ~hit.any(1)).astype(
                          np.float64),
                      "x": xs, "y": ys, "yaw": yaws}

    def stop_clearance(self, pose: tuple[float, float, float], v0: float, w0: float,
                       sweep: F64, need: float, between: npt.NDArray[np.bool_] | None = None,
                       start: float | None = None,
                       origin: tuple[float, float, float] | None = None) -> F64:
        """Least clearance (N,) of the committed sweeps (3, N, B) (`simulate`) from every
        start within `stop_timing_s` of `pose` along the present motion: the sweep as planned
        and moved with its start by ±δ·v0 along the heading. Exact against `need`; above it,
        a lower bound of what the band would give. Only poses that could fall below `need`
        are moved (each moves by δ·|v0|: the doorway's few, not every pose; the band cost
        30 % more planning time moving whole sweeps). At rest (v0 and ω0 ~0) the sweep as
        planned. Between two of the sweep's poses (kept ~0.1 s apart: 12 cm at 1.2 m/s) the
        body can pass closer than at either: a door frame's corner at the front corner read
        0.047 m there against 0.070 and 0.058 at the poses, and the chair passed it at 0.038 m
        (nav_eval seed 2, measured). So where the least a reading between a pair of poses can
        be (the outline moving from one to the other, the reading falls at most SLOPE per m)
        is under the band ((r_a + r_b − SLOPE·T) / 2 from readings r_a, r_b at the ends of a
        travel T), poses between are read too, the outline moving at most `between_m` from
        one to the next; for the sweeps `between` selects (default: all; the rest are read at
        their poses only). `start`: the start pose's footprint_clearance, if read already;
        `origin`: where the sweeps start if not at `pose` (chain_sweep's)."""
        fld, e = self.field, self.p.stop_timing_s
        rest = e <= 0.0 or (abs(v0) < 1e-3 and abs(w0) < 1e-3)
        band = need if rest else need + e * abs(v0) + 0.005  # (what a move could bring under)
        d = fld.footprint_clearance(sweep[0], sweep[1], sweep[2], need=need, upto=band)
        floor = fld.reading_floor(d, need, band)
        least = self._banded(pose, v0, sweep[0], sweep[1], sweep[2], d, need, band, rest).min(1)
        rows = np.nonzero((least >= need) & (True if between is None else between))[0]
        if not rows.size:
            return np.asarray(least, dtype=np.float64)
        # (x, y, yaw, a lower bound of the reading) of those sweeps' poses, from the start pose
        # on: the first pose kept is ~0.1 s into the motion
        o = pose if origin is None else origin
        lb0 = fld.reading_floor(np.array(self.pose_clearance(o, need=need, upto=band)), need,
                                band) if start is None else fld.reading_floor(np.array(start))
        q = np.concatenate([np.broadcast_to(np.array([*o, float(lb0)])[:, None, None],
                                            (4, rows.size, 1)),
                            np.concatenate([sweep[:, rows], floor[None, rows]])], 2)
        gap = self._travel(q[:, :, :-1], q[:, :, 1:])
        i, k = np.nonzero((0.5 * (q[3, :, :-1] + q[3, :, 1:] - SLOPE * gap) < band)
                          & (gap > self.p.between_m))
        if i.size:
            # (evenly between, in one batch: halving pair by pair read fewer poses, but its
            # rounds of small numpy calls cost more than the reading)
            a, b = q[:, i, k], q[:, i, k + 1]
            m = math.ceil(float(gap[i, k].max()) / self.p.between_m)
            f = np.arange(1, m) / m
            x = a[0, :, None] + (b[0] - a[0])[:, None] * f
            y = a[1, :, None] + (b[1] - a[1])[:, None] * f
            yaw = a[2, :, None] + wrap(b[2] - a[2])[:, None] * f  # (a 0.1 s arc: ~straight)
            dm = fld.footprint_clearance(x, y, yaw, need=need, upto=band)
            np.minimum.at(least, rows[i], self._banded(pose, v0, x, y, yaw, dm, need, band,
                                                       rest).min(1))
        return np.asarray(least, dtype=np.float64)

    def escapes(self, near: Contact, xs: F64, ys: F64, yaws: F64, d: F64
                ) -> npt.NDArray[np.bool_]:
        """(N, T): which predicted poses of a chair that stood under its margin at `near`
        are clear. Every pose keeps what it had (NavField.keeps, `contact_m`: no point of the
        outline closer, or deeper in, than it was but by TOUCH_M, nor under `contact_m` if
        it was not; nothing it overlaps deeper into the body), and the last gets out: its
        least reading TOUCH_M more than now (or `contact_m`). Standing still, or sliding
        along at the same depth, stays a hit (the chair is blocked, as before). H57: the
        unsigned clearance, 0 at and in an obstacle, could not tell moving out of one from
        moving in (a chair the map shows touching could not move at all); the footprint's
        least reading could not tell one obstacle from another (a turn keeping the deepest
        point's depth swept another part of the body into the next one). `d`: the poses'
        coarse readings (`outline_distances`); where one is half a cell (the most the
        bilinear reading is over the exact one) over √(contact_m² + (s/2)²), no point of the
        fine outline reads under contact_m (`NavField._refined`): not read again."""
        far = d >= math.hypot(self.p.contact_m, COARSE_SPACING_M / 2) \
            + self.field.map.resolution_m / 2
        ok = self.field.keeps(near, xs, ys, yaws, self.p.contact_m, far)
        out = min(self.p.contact_m, float(near.now.min()) + TOUCH_M)
        end = self.field.signed_xy(*place_xy(near.outline, xs[:, -1], ys[:, -1], yaws[:, -1]))
        ok[:, -1] &= end.min(-1) >= out
        return ok

    def stop_keeps(self, pose: tuple[float, float, float], v0: float, w0: float, sweep: F64,
                   near: Contact, rows: npt.NDArray[np.bool_],
                   origin: tuple[float, float, float] | None = None) -> npt.NDArray[np.bool_]:
        """(N,): whether the committed sweeps (3, N, B) of a chair that stood under its
        margin at `near` (`escapes`) keep what it had against `brake_clear_m`, read from
        the sweep's start (`origin`, else `pose`) at most 2·TOUCH_M of the outline's travel
        apart (a point's reading between two is then at most TOUCH_M under theirs), each
        also moved by ±stop_timing_s·v0 along the heading (stop_clearance's band). Only
        `rows` are read (the others: False)."""
        o = pose if origin is None else origin
        r = np.nonzero(rows)[0]
        q = np.concatenate([np.broadcast_to(np.array(o)[:, None, None], (3, r.size, 1)),
                            sweep[:, r]], 2)
        a, b = q[:, :, :-1].reshape(3, -1), q[:, :, 1:].reshape(3, -1)
        m = np.maximum(np.ceil(self._travel(a, b) / (2 * TOUCH_M)), 1).astype(np.intp)
        k = np.repeat(np.arange(m.size), m)  # (each pair's poses: from a on, b the next's)
        f = (np.arange(k.size) - np.repeat(np.cumsum(m) - m, m)) / m[k]
        x = a[0, k] + (b[0, k] - a[0, k]) * f
        y = a[1, k] + (b[1, k] - a[1, k]) * f
        yaw = a[2, k] + wrap(b[2, k] - a[2, k]) * f
        x, y, yaw = (np.concatenate([v, e]) for v, e in zip((x, y, yaw), q[:, :, -1], strict=True))
        row = np.concatenate([k // sweep.shape[2], np.arange(r.size)])
        ok = self.field.keeps(near, x, y, yaw, self.p.brake_clear_m)
        e = self.p.stop_timing_s
        if e > 0.0 and (abs(v0) >= 1e-3 or abs(w0) >= 1e-3):
            for ds in (e * v0, -e * v0):
                ok &= self.field.keeps(near, x + ds * math.cos(pose[2]),
                                       y + ds * math.sin(pose[2]), yaw, self.p.brake_clear_m)
        out = np.zeros(len(rows), dtype=np.bool_)
        out[r] = np.bincount(row, (~ok).astype(np.float64), r.size) == 0
        return out

    def _travel(self, a: F64, b: F64) -> F64:
        """How far any point of the outline moves from poses a to poses b (x, y, yaw, ...)."""
        return np.asarray(np.hypot(b[0] - a[0], b[1] - a[1]) + np.abs(wrap(b[2] - a[2]))
                          * self.field.footprint.reach_m, dtype=np.float64)

    def _banded(self, pose: tuple[float, float, float], v0: float, x: F64, y: F64, yaw: F64,
                d: F64, need: float, band: float, rest: bool) -> F64:
        """`d`, the clearances at poses (x, y, yaw), each under `band` also read moved by
        ±stop_timing_s·v0 along the start's heading (stop_clearance; in place)."""
        if rest:
            return d
        near = d < band
        if near.any():
            e, t0 = self.p.stop_timing_s, pose[2]
            xn, yn, yawn = x[near], y[near], yaw[near]
            # (both moves read in one call: the same numbers, pose by pose)
            moved = self.field.footprint_clearance(
                np.concatenate([xn + ds * math.cos(t0) for ds in (e * v0, -e * v0)]),
                np.concatenate([yn + ds * math.sin(t0) for ds in (e * v0, -e * v0)]),
                np.concatenate([yawn, yawn]), need=need)
            d[near] = np.minimum(np.minimum(d[near], moved[:xn.size]), moved[xn.size:])
        return d

    def pose_clearance(self, pose: tuple[float, float, float], **kw: Any) -> float:
        """NavField.footprint_clearance at one pose (with its keywords), kept: each of a
        planning cycle's evaluations reads the same start pose (~75 µs a reading)."""
        key = (np.array(pose, dtype=np.float64).tobytes(), tuple(sorted(kw.items())))
        got = self._at_pose.get(key)
        if got is None:
            if len(self._at_pose) >= 64:
                self._at_pose.clear()
            got = self._at_pose[key] = float(self.field.footprint_clearance(*pose, **kw))
        return got

    @property
    def escape_below(self) -> float:
        """A chair whose footprint reads under this stands within a margin: what is a hit for
        it is told by the escape rule (`escapes`)."""
        return max(self.p.contact_m, self.p.brake_clear_m) + TOUCH_M

    @property
    def predict_below(self) -> float:
        """Where the prediction's clearance is read exactly (NavField.outline_clearance):
        under `contact_m` and half a cell, the most the bilinear reading is over the exact
        one. A prediction pose within `contact_m` reads so wherever it is (its hit is
        truthful, H47); farther out its cost (σ 0.1 m) is read as before (bilinear), as
        H48 left it on the coarse outline: it is replanned every cycle, and what the chair
        is committed to is read exactly up to EXACT_BELOW_M (`stop_clearance`)."""
        return self.p.contact_m + self.field.map.resolution_m / 2

    def outline_distances(self, xs: F64, ys: F64, yaws: F64, people: list[Person], t: F64,
                          hit_under: float = 0.0) -> tuple[F64, list[tuple[F64, F64]]]:
        """At the predicted poses (N, T): the footprint's clearance on the coarse outline
        (NavField.footprint_clearance: the prediction's cost, replanned every cycle; what the
        chair is committed to, `stop_clearance`, is read on the fine one too) and per person
        the least distance of its outline to their centre predicted at constant velocity, or
        turned back short of where that meets a wall (`wall_turn`), at times `t`, and to
        where they stand now. In batches of candidates (field.BATCH_POINTS:
        the temporaries stay in cache), the same numbers. The clearance is read exactly under
        `predict_below` but not at poses read under `hit_under` (hits, and under every margin
        it is compared with, whatever it reads)."""
        fld = self.field
        if not people:
            return fld.footprint_clearance(xs, ys, yaws, fine=False, below=self.predict_below,
                                           decided=hit_under), []
        d = np.empty(xs.shape)
        near = [(np.empty(xs.shape), np.empty(xs.shape)) for _ in people]
        turns = [wall_turn(person, fld, float(t[-1])) for person in people]
        rows = max(1, BATCH_POINTS // (xs.shape[1] * len(fld.outline)))
        for i in range(0, xs.shape[0], rows):
            b = slice(i, i + rows)
            px, py = place_xy(fld.outline, xs[b], ys[b], yaws[b])  # (n, T, P)
            for person, turn, (to_path, to_here) in zip(people, turns, near, strict=True):
                cx, cy = person.x_m + person.vx_mps * t, person.y_m + person.vy_mps * t
                to_path[b] = np.hypot(px - cx[:, None], py - cy[:, None]).min(-1)
                to_here[b] = np.hypot(px - person.x_m, py - person.y_m).min(-1)
                if turn is not None:
                    # or turned back short of the wall: the nearer (the map may show a
                    # person's own trail or a door since opened as occupied: walking on is
                    # kept, nothing is checked less than before). To the segment of where
                    # they are, whenever they turned (WallTurn.span).
                    j = int(np.searchsorted(t, turn.from_s))
                    ax, ay, bx, by = (e[:, None] for e in turn.span(person, t[j:]))
                    dx, dy = bx - ax, by - ay
                    qx, qy = px[:, j:] - ax, py[:, j:] - ay
                    u = np.clip((qx * dx + qy * dy) / np.maximum(dx * dx + dy * dy, 1e-12),
                                0.0, 1.0)
                    np.minimum(to_path[b][:, j:], np.hypot(qx - u * dx, qy - u * dy).min(-1),
                               out=to_path[b][:, j:])
            d[b] = fld.outline_clearance(px, py, self.predict_below,
                                         hit_under)  # (last: px, py are its scratch)
        return d, near

    def lattice_active(self, hf: HeadingField, pose: tuple[float, float, float],
                       phi0: float) -> bool:
        """Progress is measured on the lattice in this cycle: the chair is within
        `lattice_within_m` of the goal (on the 2-D field) and on a state with a way there.
        Farther out the 2-D field's smooth descent is what the law follows best: the
        lattice's arcs (22.5° at 0.6 m) make S-bends cheap that the law cannot thread
        through a door (measured: 0.9 m door cases lost)."""
        if phi0 > self.p.lattice_within_m:
            return False
        return bool(hf.at(np.array(pose[0]), np.array(pose[1]), np.array(pose[2]))[1])

    def handover(self, pose: tuple[float, float, float], v0: float,
                 goal: tuple[float, float, float]) -> bool:
        """Whether the core's own final approach does what row 0 predicts. Beyond
        `in_place_r_m` it is the law towards the goal (predicted). Nearer, row 0 is an
        in-place turn, and the core turns in place only within its capture radius, or at rest
        within the position tolerance (twice that radius by default, ControlConfig
        .capture_fraction); elsewhere it runs the law, whose κ ~ 1/r spins the chair at the ω
        floor about a point off the axle (measured: 14° swung on beside office B's wall, 1 mm
        left). There MPEPC keeps the goal and plans the turn itself, unless the goal lies
        straight ahead within the capture radius of the chair's line: the core's straight final
        then drives onto it without steering (over a sweep checked here) and turns in place over
        its own checked sweep (a chair lined up 8 cm short otherwise stood there, measured)."""
        r = math.hypot(goal[0] - pose[0], goal[1] - pose[1])
        cap = self.law.capture_m
        if r >= self.p.in_place_r_m or r <= cap or (r <= 2 * cap and abs(v0) < 0.01):
            return True
        along, left = along_lateral(pose, goal[0], goal[1])
        if along <= 0.0 or abs(left) > cap:
            return False
        return self.field.straight_clearance(pose, np.linspace(0.0, 1.0, 5) * along) \
            >= self.p.contact_m

    def goal_turn_clearance(self, pose: tuple[float, float, float],
                            goal: tuple[float, float, float]) -> float:
        """Least clearance of the in-place turn onto the goal's yaw that the core makes once
        it has the goal (control/core.py, H40 checks it only by TURN_CLEARANCE_M): where the
        chair stands if it is within the tolerance, else where its straight final lands (the
        goal's along-track point, from the last capture radius before it on, as
        final_heading checks it) if the goal's line passes within `final_line` of the
        tolerance; inf where the core's approach is the law (its arrival heading is the
        law's, predicted by row 0)."""
        x, y, yaw = pose
        tol, cap = self.law.tolerance_m, self.law.capture_m
        r = math.hypot(goal[0] - x, goal[1] - y)
        if r <= tol:
            ls = np.zeros(1)
        else:
            along, left = along_lateral(pose, goal[0], goal[1])
            if r > self.p.final_move_m or along <= 0.0 \
                    or abs(left) > self.p.final_line * tol:
                return math.inf
            ls = np.linspace(max(along - cap, 0.0), along + self.p.final_overshoot_m, 5)
        e = float(wrap(np.array(goal[2] - yaw)))
        n = self.field.footprint.turn_samples(e, self.p.goal_turn_step_m)
        turn = yaw + np.linspace(0.0, e, n)
        c, s = math.cos(yaw), math.sin(yaw)
        return float(self.field.footprint_clearance(
            np.repeat(x + ls * c, n), np.repeat(y + ls * s, n), np.tile(turn, ls.size)).min())

    def final_heading(self, pose: tuple[float, float, float], goal: tuple[float, float, float],
                      turn: bool, straight: bool, step_deg: float = 1.0, max_deg: float = 90.0,
                      spare_deg: float = 2.0) -> float | None:
        """The final manoeuvre the core executes exactly, without the law: an in-place turn
        onto a heading ψ (if `turn`), the core's straight final along it onto the goal's
        along-track point (ψ passes within `final_line` of the tolerance), then its in-place
        turn onto the goal's yaw, each sweep keeping `contact_m` (as a predicted motion must;
        the core rechecks the last turn, H40). Returns the chair's own yaw if that needs no
        turn (and `straight`), else the ψ whose headings within `spare_deg` all do (the turn
        ends a degree or two off; the clearance there changes by cm per degree), keeping the
        most clearance; None if there is none."""
        x, y, yaw = pose
        reach, fld, contact = self.field.footprint.reach_m, self.field, self.p.contact_m
        line = self.p.final_line * self.law.tolerance_m

        def sweep(off: float) -> F64 | None:
            """(3, n) poses the manoeuvre via yaw + off sweeps; None: its line misses."""
            psi = yaw + off
            along, left = along_lateral((x, y, psi), goal[0], goal[1])
            if along <= 0.0 or abs(left) > line:
                return None
            c, s = math.cos(psi), math.sin(psi)
            # The last turn starts while the straight still lands (its last capture radius,
            # control/core.py _align): checked from there on (and `final_overshoot_m` past).
            far = along + self.p.final_overshoot_m
            ls = np.linspace(max(along - self.law.capture_m, 0.0), far, 5)
            k = np.linspace(0.0, 1.0, max(2, math.ceil(far / 0.02) + 1))
            e2 = float(wrap(np.array(goal[2] - psi)))
            n1 = max(2, math.ceil(abs(off) * reach / 0.05) + 1)
            n2 = max(2, math.ceil(abs(e2) * reach / 0.05) + 1)
            turn2 = psi + np.linspace(0.0, e2, n2)
            return np.stack([
                np.concatenate([np.full(n1, x), x + k * far * c, np.repeat(x + ls * c, n2)]),
                np.concatenate([np.full(n1, y), y + k * far * s, np.repeat(y + ls * s, n2)]),
                np.concatenate([yaw + np.linspace(0.0, off, n1), np.full(k.size, psi),
                                np.tile(turn2, ls.size)])])

        def clearance(offs: F64) -> F64:
            """Least clearance of each manoeuvre (−inf: its line misses), in one batch."""
            out = np.full(offs.size, -math.inf)
            sweeps = [(i, sw) for i, o in enumerate(offs) if (sw := sweep(float(o))) is not None]
            if sweeps:
                poses = np.concatenate([sw for _, sw in sweeps], 1)
                starts = np.cumsum([0] + [sw.shape[1] for _, sw in sweeps[:-1]])
                d = fld.footprint_clearance(poses[0], poses[1], poses[2])
                out[[i for i, _ in sweeps]] = np.minimum.reduceat(d, starts)
            return out

        if straight and clearance(np.zeros(1))[0] >= contact:
            return yaw
        if not turn:
            return None
        offs = np.radians(np.arange(-max_deg, max_deg + 0.5 * step_deg, step_deg))
        clear = clearance(offs)
        w = round(spare_deg / step_deg)
        robust = np.array([clear[max(0, i - w):i + w + 1].min() for i in range(offs.size)])
        robust[offs == 0.0] = -math.inf  # (no turn: see above)
        i = int(np.argmax(robust))
        return yaw + float(offs[i]) if robust[i] >= contact else None

    def landing(self, pose: tuple[float, float, float], goal: tuple[float, float, float]
                ) -> tuple[float, float] | None:
        """For a chair at rest just outside the goal's tolerance, nearer than `final_from`
        of it (where neither the core's own turn nor final_heading's manoeuvre takes over,
        and the law creeps: v ≤ vmax·r/r_thresh): a stage (ψ, d), turn in place onto ψ, then
        d straight, that lands within the tolerance (its line within `final_line` of it, as
        final_heading's), from where the core turns onto the goal's yaw itself. As a stage,
        not final_heading's manoeuvre: a stage's turn is carried on to its end
        (planner.compute), not handed over mid-swing as the goal's own turn (why
        `final_from` is 1.5). The sweeps as final_heading checks them
        (the turn onto ψ ± 2°, the straight, the last turn where the straight lands); any
        turn, the goal may be beside or behind the chair. None: no such stage."""
        psi = self.final_heading(pose, goal, turn=True, straight=True, max_deg=180.0)
        if psi is None:
            return None
        return psi, along_lateral((pose[0], pose[1], psi), goal[0], goal[1])[0]

    def _pairs(self, pose: tuple[float, float, float], turn_m_per_rad: float,
               step_deg: float = 5.0, step_m: float = 0.02, spare_deg: float = 2.0,
               spare_m: float = 0.01) -> tuple[F64, F64, F64, F64, F64, F64, F64]:
        """Every stage (ψ, d) from a chair at rest at `pose` (Mpepc.stage): the heading
        offsets ψ − yaw (O), the distances d (D), the straights (O, D) and the turns (O,)
        that sweep clear (as 1.0/0.0), the landings' x and y (O, D) and each pair's own cost
        (O, D)."""
        p, fld = self.p, self.field
        x, y, yaw = pose
        offs = np.radians(np.arange(-p.stage_turn_deg, p.stage_turn_deg + 0.5 * step_deg,
                                    step_deg))
        ds = np.arange(0.0, p.stage_straight_m + 0.5 * step_m, step_m)
        spare = math.radians(spare_deg)
        psi = spread(yaw, offs, spare)
        # the straights, every cm along each heading: clear up to each distance (prefix min)
        far = p.stage_straight_m + spare_m + p.final_overshoot_m
        k = np.arange(0.0, far + 0.005, 0.01)
        cs, sn = np.cos(psi)[..., None], np.sin(psi)[..., None]
        line = fld.footprint_clearance(x + k * cs, y + k * sn,
                                       np.broadcast_to(psi[..., None], cs.shape[:2] + k.shape))
        reach_clear = np.minimum.accumulate(line, axis=-1).min(1)  # (O, K)
        need = np.minimum(np.round((ds + spare_m + p.final_overshoot_m) / 0.01).astype(int),
                          k.size - 1)
        straight_ok = reach_clear[:, need] >= p.contact_m  # (O, D)
        # the turns onto ψ ± spare, in one batch
        reach = fld.footprint.reach_m
        n = np.maximum(2, np.ceil((np.abs(offs) + spare) * reach / 0.05).astype(int) + 1)
        ends = offs + np.sign(offs) * spare
        yaws = np.concatenate([yaw + np.linspace(0.0, e, m) for e, m in zip(ends, n,
                                                                               strict=True)])
        d = fld.footprint_clearance(np.full(yaws.size, x), np.full(yaws.size, y), yaws)
        turn_ok = np.minimum.reduceat(d, np.concatenate([[0], np.cumsum(n)[:-1]])) \
            >= p.contact_m
        turn_ok[offs == 0.0] = True
        move = turn_m_per_rad * np.abs(offs)[:, None] + ds[None, :]  # (O, D)
        lx0 = x + np.cos(yaw + offs)[:, None] * ds[None, :]
        ly0 = y + np.sin(yaw + offs)[:, None] * ds[None, :]
        return (offs, ds, straight_ok.astype(float), turn_ok.astype(float), lx0, ly0, move)

    def _last_stage(self, pose: tuple[float, float, float], goal: tuple[float, float, float],
                    pairs: tuple[F64, F64, F64, F64, F64, F64, F64]) -> tuple[int, int] | None:
        """Of `pairs` (Mpepc._pairs at `pose`), the least costly of the first
        `stage_final_tries` straights that land where the final manoeuvre (final_heading)
        has a way to the goal, as (ψ index, d index); None: none of those."""
        p = self.p
        offs, _, straight_ok, turn_ok, lx0, ly0, move = pairs
        clear = (straight_ok > 0.0) & (turn_ok[:, None] > 0.0)
        clear[:, 0] = False  # (a turn alone onto the final manoeuvre's ψ: final_heading's)
        r = np.hypot(goal[0] - lx0, goal[1] - ly0)
        band = clear & (r > p.final_from * self.law.tolerance_m) & (r <= p.final_move_m)
        order = np.argsort(np.where(band, move, math.inf), axis=None)
        for flat in order[:min(p.stage_final_tries, int(band.sum()))]:
            i, j = np.unravel_index(int(flat), band.shape)
            land = (float(lx0[i, j]), float(ly0[i, j]), pose[2] + float(offs[i]))
            if self.final_heading(land, goal, turn=True, straight=True, step_deg=2.0) \
                    is not None:
                return int(i), int(j)
        return None

    def stage(self, pose: tuple[float, float, float], goal: tuple[float, float, float],
              hf: HeadingField, step_deg: float = 5.0, step_m: float = 0.02,
              spare_deg: float = 2.0, spare_m: float = 0.01) -> tuple[float, float] | None:
        """The next stage of a manoeuvre from a chair at rest, executed without the law:
        (ψ, d) for "turn in place onto ψ (if ψ is not its yaw), then drive d straight along
        ψ". A pair counts only if the turn onto ψ ± `spare_deg` sweeps clear by `contact_m`
        (a turn ends a degree or two off), and the straight along those headings to d +
        `spare_m` + `final_overshoot_m` does too. Of those, in this order:
        - the least costly (the turn at the lattice's `turn_m_per_rad`, the straight its
          length) of the first `stage_final_tries` that land where the final manoeuvre
          (final_heading) has a way to the goal: the manoeuvre's last stage;
        - else the pair landing where the lattice's costs-to-go plus the pair's own cost are
          least, among those where at every landing within `spare_deg` and `spare_m` the
          lattice has a way on, at `stage_gain_m` less than from the chair (progress, never
          a cycle);
        - else the first stage of the shortest way of up to `stage_depth` such stages that
          ends in the final manoeuvre (Mpepc.stage_way).
        None if no pair does (or the chair's own state has no way). Only the pair's first
        part is driven (the caller: the turn, or with ψ = yaw the straight); the next plan
        looks again from where it ended."""
        p = self.p
        x, y, yaw = pose
        c0, ok0 = hf.at(np.array(x), np.array(y), np.array(yaw))
        if not bool(ok0):
            return None
        pairs = self._pairs(pose, hf.params.turn_m_per_rad, step_deg, step_m, spare_deg,
                            spare_m)
        offs, ds, straight_ok, turn_ok, _, _, move = pairs
        last = self._last_stage(pose, goal, pairs)
        if last is not None:
            return yaw + float(offs[last[0]]), float(ds[last[1]])
        # the landings within the spares: the lattice's costs-to-go there (the worst)
        psi = spread(yaw, offs, math.radians(spare_deg))
        dd = np.maximum(ds[:, None] + np.array([-spare_m, 0.0, spare_m]), 0.0)  # (D, 3)
        lx = x + np.cos(psi)[:, :, None, None] * dd  # (O, 3, D, 3)
        ly = y + np.sin(psi)[:, :, None, None] * dd
        cost, ok = hf.at(lx, ly, np.broadcast_to(psi[:, :, None, None], lx.shape))
        worst = np.where(ok, cost, math.inf).max(axis=(1, 3))  # (O, D)
        total = worst + move
        good = (straight_ok > 0.0) & (turn_ok[:, None] > 0.0) \
            & (worst <= float(c0) - p.stage_gain_m)
        good[offs == 0.0, 0] = False  # (no turn and no straight: no stage)
        for flat in np.argsort(np.where(good, total, math.inf), axis=None)[:int(good.sum())]:
            i, j = np.unravel_index(int(flat), good.shape)
            psi_ij, d = yaw + float(offs[i]), float(ds[j])
            if self.turn_on_clear(hf, (x + d * math.cos(psi_ij), y + d * math.sin(psi_ij),
                                       psi_ij)):
                return psi_ij, d
        return self.stage_way(pose, goal, hf, pairs)

    def turn_on_clear(self, hf: HeadingField, pose: tuple[float, float, float]) -> bool:
        """Whether the in-place turn the lattice's way from `pose` begins with (if any)
        sweeps clear by `contact_m` from the chair's own yaw there. The lattice checks its
        turns at its states and half steps only, by its own lower margin
        (LatticeParams.min_clear_m); a stage that lands where that turn does not keep
        MPEPC's margin leaves the chair where nothing moves on (office A's far corner: the
        turn from 90° at (5.68, 3.34) sweeps 0.048 m at 110°; nav_eval seed 7 at a 0.1 s
        plan latency stood there, blocked, till "no progress")."""
        e, yaw = 0.0, pose[2]
        for (_, _, heading), turned in hf.best_path(*pose, max_steps=hf.params.headings):
            if not turned:
                break
            e += float(wrap(np.array(heading - yaw)))
            yaw = heading
        if e == 0.0:
            return True
        return self.field.turn_clearance(pose, e) >= self.p.contact_m

    def stage_way(self, pose: tuple[float, float, float], goal: tuple[float, float, float],
                  hf: HeadingField, pairs: tuple[F64, F64, F64, F64, F64, F64, F64]
                  ) -> tuple[float, float] | None:
        """The first stage (ψ, d) of a way of 2 to `stage_depth` stages (Mpepc.stage: each
        sweep clear with its spares) whose last one lands where the final manoeuvre has a
        way (Mpepc._last_stage); the shortest first, None: none found. Where no single stage
        does either (the lattice's way passes a wall a cm or two closer than the chair's
        straights may: nav_eval seed 1's office A far corner), a way that first shifts the
        chair's line. A beam search, so bounded: at each depth the `stage_beam` landings
        (one per 2 cm and 5°) least in the stages' own costs plus the lattice's
        costs-to-go there are tried."""
        p = self.p
        # (cost so far, pose, the way's first stage (None: this is the chair), its pairs)
        level: list[tuple[float, tuple[float, float, float], tuple[float, float] | None,
                          tuple[F64, F64, F64, F64, F64, F64, F64]]] = [(0.0, pose, None,
                                                                         pairs)]
        for _ in range(p.stage_depth - 1):
            found: dict[tuple[int, int, int], tuple[float, tuple[float, float, float],
                                                    tuple[float, float]]] = {}
            for g, node, way, (offs, ds, straight_ok, turn_ok, lx, ly, move) in level:
                ok = (straight_ok > 0.0) & (turn_ok[:, None] > 0.0)
                ok[:, 0] = False  # (a turn alone: the next stage's own turn)
                heads = np.broadcast_to((node[2] + offs)[:, None], lx.shape)
                f = np.where(ok, g + move + self._landing_cost(hf, lx, ly, heads), math.inf)
                for flat in np.argsort(f, axis=None)[:int(np.isfinite(f).sum())]:
                    i, j = np.unravel_index(int(flat), f.shape)
                    land = (float(lx[i, j]), float(ly[i, j]), float(heads[i, j]))
                    key = (round(land[0] / 0.02), round(land[1] / 0.02),
                           round(math.degrees(land[2]) / 5.0))
                    if key in found and found[key][0] <= float(f[i, j]):
                        continue
                    found[key] = (float(f[i, j]), land,
                                  (land[2], float(ds[j])) if way is None else way)
            best = sorted(found.values(), key=lambda t: t[0])[:p.stage_beam]
            level = []
            for fl, land, way in best:
                pl = self._pairs(land, hf.params.turn_m_per_rad)
                if self._last_stage(land, goal, pl) is not None:
                    return way
                here = float(self._landing_cost(hf, np.array([land[0]]), np.array([land[1]]),
                                                np.array([land[2]]))[0])
                level.append((fl - here, land, way, pl))
        return None

    @staticmethod
    def _landing_cost(hf: HeadingField, x: F64, y: F64, yaw: F64) -> F64:
        """The lattice's least costs-to-go from positions after a turn of at most 90° from
        `yaw` onto one of its headings (their own states: interpolating between headings
        mixes in states with no way, which makes the costs jump by metres within cm);
        inf: none has a way."""
        step = hf.step
        heads = np.arange(hf.params.headings) * step
        turn = np.abs(wrap(heads - np.asarray(yaw)[..., None]))  # (..., K)
        xs = np.broadcast_to(np.asarray(x)[..., None], turn.shape)
        ys = np.broadcast_to(np.asarray(y)[..., None], turn.shape)
        cost, ok = hf.at(xs, ys, np.broadcast_to(heads, turn.shape))
        total = np.where(ok & (turn <= 0.5 * math.pi + 1e-9),
                         cost + hf.params.turn_m_per_rad * turn, math.inf)
        return np.asarray(total.min(-1), dtype=float)

    def door_far(self, path: F64, k: int) -> int:
        """The index of a door's far side on the way `path` (N, 2) whose narrowest point is k:
        the last point of the way within 1 cm of its narrowest clearance (a door leaf along a
        jamb narrows the way before the wall's line)."""
        clr = self.field.clearance_at(path[k:])
        return k + int(np.nonzero(clr <= clr[0] + 0.01)[0].max())

    def sight_top(self, far_m: float, chain: Chain | None) -> float:
        """The sight rule (H67): the fastest the chair may set off from where it stands, its
        axle `far_m` short of a door's far side, so that, reacting after the plan period and
        the drive chain's mean lag (`chain`; without it the plan period alone), it stops at
        the comfort deceleration and jerk with its front `brake_clear_m` short of that side
        (a person beside the door beyond it is hidden behind the jambs till they step out);
        never under `v_min_mps`."""
        g = self.law
        return max(sight_speed(far_m - self.field.footprint.front_m - self.p.brake_clear_m,
                               g.a_mps2, g.jerk_mps3, self.react_s(chain), g.vmax_mps),
                   self.p.v_min_mps)

    def react_s(self, chain: Chain | None) -> float:
        """How long before a plan can brake for what it sees: the plan period, and the drive
        chain's mean lag (v: dead time and its two lags; `chain`, else none)."""
        return self.law.commit_s + (0.0 if chain is None else chain.v.delay + 2 * chain.v.lag)

    def sight_cap(self, pose: tuple[float, float, float], ctg: CostToGo,
                  chain: Chain | None = None, v0: float = 0.0) -> float:
        """The top speed of MPEPC's own motions (and stages given none) from `pose` where the
        way to the goal runs through a narrow passage (a door: the axle's clearance under
        `NARROW_M`, as NavField.passage_ahead; not one the way ends in or runs on in) ahead:
        `sight_top` of the way's length to its far
        side, the rule a door's straight is given (through_door), applied again at every plan
        from where the chair then stands, or from the door's line-up (`LINE_UP_M` before its
        narrowest point) where it stands nearer. inf: no passage near enough to bind, or the
        chair's front is past its far side (what stepped out there is in the laser's view),
        or so near it that the chair, from its speed `v0` (the command's), could not reach
        the door's top before its front is past, at the comfort acceleration (H75: a chair
        stopped in a door, its front 5 cm short of the far side, was predicted at 0.54 m/s
        for the whole horizon, crawling through the room beyond: every way on was a hit
        against a person pacing there, and it stood in the door till the goal was aborted;
        the next plan, its front past, would have lifted the cap).
        Why (H67): MPEPC's own arcs through a door (no line-up: a start within 1.5 m of it,
        leaving office A, the store room) were driven at 0.93–1.15 m/s within 0.15 m of the
        jambs, at the law's top speed. Read on the costs-to-go's descent (~0.2 ms)."""
        fld, g = self.field, self.law
        # (beyond this the rule allows the top speed: the way's far side must lie nearer)
        reach = fld.footprint.front_m + self.p.brake_clear_m + g.vmax_mps * self.react_s(
            chain) + stop_m(g.vmax_mps, g.a_mps2, g.jerk_mps3)
        path = fld.descent_path(ctg, pose[0], pose[1], max_m=reach + 2.0)
        top = math.inf
        for j, k in passages(fld.clearance_at(path), NARROW_M):
            if j == len(path) or walked_to(path, k) > reach:
                break  # (the way ends in it or runs on beyond what was read; the rest is far)
            # (each one whose far side the front has still to pass: a jamb's end beside the
            # axle reads as a passage of its own, just before the door's)
            far = walked_to(path, self.door_far(path, k))
            # (nearer than the door's line-up, as fast as a chair that set off from there: its
            # straight keeps that speed through, and a chair slowed to a crawl in the door
            # turned in place in it, MPEPC's collision cost over time outweighing the progress)
            at = max(far, LINE_UP_M + far - walked_to(path, k))
            # (an upper bound of the speed at which the front passes the far side: the whole
            # comfort acceleration from now on, no jerk ramp)
            passing = math.sqrt(max(v0, 0.0) ** 2 + 2.0 * g.a_mps2 * max(
                far - fld.footprint.front_m, 0.0))
            if fld.footprint.front_m < far and at < reach \
                    and passing > (cap := self.sight_top(at, chain)):
                top = min(top, cap)
        return top

    def through_door(self, pose: tuple[float, float, float], goal: tuple[float, float, float],
                     ctg: CostToGo, hf: HeadingField | None, people: list[Person],
                     rates: tuple[float, float] = (0.0, 0.0), final: bool = True,
                     turned: bool = False, spare_deg: float = 2.0, spare_m: float = 0.01,
                     lined: bool = False, v0: float = 0.0, chain: Chain | None = None,
                     scan: F64 | None = None) -> Plan | None:
        """For a chair at rest within `door_ahead_m` of a door on its way (NavField
        .passage_ahead), the goal beyond it, that faces away from the way through the door by
        more than `door_away_rad` or has just turned a stage (`turned`; else None: MPEPC's own
        arc through is kept): the straight through the door along the chair's heading, to
        where the way leaves the door, if it sweeps clear by `contact_m` (to `spare_m` +
        `final_overshoot_m` past its end) and passes within 0.1 m of the door's narrowest point
        on the way; else an in-place turn (at most `stage_turn_deg`) towards the heading within
        30° of the way through the door whose straight does that with the most clearance, the
        way round whose whole turn onto it (`spare_deg` past) sweeps clear by `contact_m`.
        Stages (as Mpepc.stage_plan's), evaluated as MPEPC's candidates are (`_costs`: people,
        the stop after the plan period); the next plan from rest looks again. None: no door
        that near, no clear straight through it, or no clear turn onto one.

        `lined`: the chair has just reached a door's line-up pose (control/core.py), moving at
        `v0` or at rest, and the door is driven straight (κ 0) whatever the goal beyond: the
        safety monitor sweeps the padded footprint along the chair's present arc, and the
        law's small steering corrections inside a door frame met the jamb in that sweep (an
        e-stop entering office B's door, nav_eval --monitor seed 7; docs/experiments/
        monitor-envelope-s25.md). Moving, only the straight along its heading is offered; at
        rest, the straight with the most clearance (turned onto first where it is over a
        heading step off).

        The straight's top speed is sight-limited (H67): a person beside the door beyond it,
        behind its jambs, is hidden from the chair's laser until about the moment they step
        into its way, so the chair sets off through the door no faster than it could stop
        short of the door's far side (the end of its narrowest stretch on the way; its front,
        `brake_clear_m` short) after reacting
        (the plan period, `commit_s`, and the drive chain's mean lag: `chain`) at the
        comfort deceleration and jerk, from where it stands (sight_speed); never under
        `v_min_mps` (a chair already at the door's line creeps through at the least speed).
        That bounds how fast it meets someone stepping out; it does not stop it before them
        once it is in the door (no speed short of a crawl does: they are unseen till there).
        The rest of the straight keeps that speed as its top (stage_plan's `top`).

        `scan` (M, 2): the laser's points of the last scans (ControlCore.SCAN_WINDOW_S), in
        the frame the chair plans in; NaN rows: no return. Lined up at rest, the
        straights clear on the map are ranked by their clearance to those points, finer than
        the map's cells (H79): the live map's jambs, grown by the laser's noise, read up to 5
        cm off the truth, and the straight it ranked clearest passed 0.069 m from a jamb where
        one 2° round passed 0.094 (nav_eval --map scans seed 7, "into room B facing down");
        the safety monitor, padding the body by contact_m, reads the jamb through that noise.
        The chair turns onto the scan's clearest unless its own is within DOOR_GAIN_M of it."""
        p, fld = self.p, self.field
        x, y, yaw = pose
        found = fld.passage_ahead(ctg, x, y, p.door_ahead_m)
        if found is None or math.hypot(goal[0] - x, goal[1] - y) <= p.door_ahead_m:
            return None
        path, k, j = found
        if not lined and math.hypot(goal[0] - path[j, 0], goal[1] - path[j, 1]) < 1.0:
            return None  # (the goal just past the door: its own approach, the lattice's)
        way = heading_through(path, k)  # (path ends at j)
        if not (turned or lined) and abs(float(wrap(np.array(way - yaw)))) <= p.door_away_rad:
            return None
        moving = abs(v0) >= 0.01
        ranked = scan is not None and lined and not moving
        steps = np.arange(-30.0, 30.0 + 1e-9, p.door_turn_step_deg)
        if ranked:  # (finer where the scan can tell them apart)
            steps = np.union1d(steps, np.arange(-3.0, 3.0 + 1e-9, 0.25))
        psi = np.concatenate([[yaw], way + np.radians(steps)])
        c, s = np.cos(psi), np.sin(psi)
        along = (path[j, 0] - x) * c + (path[j, 1] - y) * s  # (N,) the straight's length
        lateral = np.abs((path[k, 1] - y) * c - (path[k, 0] - x) * s)
        ends = along + spare_m + p.final_overshoot_m
        ds = np.arange(0.0, float(ends.max()) + 0.005, 0.01)
        line = fld.footprint_clearance(x + ds * c[:, None], y + ds * s[:, None],
                                       np.broadcast_to(psi[:, None], (psi.size, ds.size)))
        clear = np.where(ds[None, :] <= ends[:, None], line, math.inf).min(1)
        need = p.contact_m + (DOOR_NOISE_M if moving else 0.0)  # (at rest: the clearest)
        ok = (clear >= need) & (lateral <= 0.1) & (along > 0.0)
        by_scan = ranked and bool(ok.any())
        rank = clear
        if by_scan:
            assert scan is not None
            rank = np.full(psi.shape, -math.inf)
            rank[ok] = points_clearance(scan, (x, y), psi[ok], ends[ok], fld.footprint)
        best_i = int(np.argmax(np.where(ok, rank, -math.inf)))
        keep = rank[0] >= rank[best_i] - DOOR_GAIN_M if by_scan else abs(float(wrap(
            np.array(psi[best_i] - yaw)))) <= math.radians(p.door_turn_step_deg)
        if ok[0] and (not lined or moving or turned or keep):
            d = float(along[0])  # on a clear straight through: drive it
            far = self.door_far(path, k)
            far_m = float((path[far, 0] - x) * c[0] + (path[far, 1] - y) * s[0])
            top = self.sight_top(far_m, chain)
            # (people about: judged whole, H75: a straight longer than its speed covers in
            # the horizon was judged on its first part only, and a crawl looked clear of a
            # person pacing across the door's exit that the rest of it ran into)
            return self._one_stage(pose, (d, 0.0), (x + d * c[0], y + d * s[0], yaw), False,
                                   ctg, people, goal, hf, rates, v0, final=final, top=top,
                                   whole=lined and bool(people))
        if moving or not ok.any():
            return None
        best = float(psi[best_i])
        e = float(wrap(np.array(best - yaw)))
        spare = math.radians(spare_deg)
        for turn in (e, e - math.copysign(2 * math.pi, e)):  # the short way round first
            if fld.turn_clearance(pose, turn + math.copysign(spare, turn)) < p.contact_m:
                continue
            step = math.copysign(min(abs(turn), math.radians(p.stage_turn_deg)), turn)
            # (`then`, the chair's own point: the turn is carried on through the planning
            # cycles while it runs, and from rest this looks again)
            return self._one_stage(pose, (0.0, step), (x, y, yaw + step), True, ctg, people,
                                   goal, hf, rates, final=final, then=(x, y))
        return None

    def standing(self, pose: tuple[float, float, float]) -> Plan:
        """A plan to stand where the chair is (a hold: the core stands while it is blocked;
        not the goal's approach: its clearance 0 drops the core's own, ControlCore.on_plan)."""
        return Plan((0.0, 0.0, 0.0, 0.0), pose, 0.0, 0.0, 0.0, 1.0,
                    self.pose_clearance(pose), np.array([pose], dtype=np.float64), False, 0.0,
                    0.0, 0, hold=True)

    def reach_gaps(self, px: F64, py: F64, people: list[Person]) -> F64:
        """(N, K): how far the body at each of N poses (its outline's points, (N, P)) keeps
        outside each person's reach (r + speed·react_s) wherever MPEPC predicts them over the
        horizon (`walk_points`); negative: within it."""
        horizon = np.asarray(np.arange(self.steps + 1) * self.p.dt_s, dtype=np.float64)
        out = np.empty((px.shape[0], len(people)))
        for i, q in enumerate(people):
            w = self.walk_points(q, horizon).reshape(-1, 2)
            d = np.hypot(px[:, :, None] - w[None, None, :, 0], py[:, :, None] - w[None, None, :, 1])
            out[:, i] = d.reshape(px.shape[0], -1).min(1) - (
                q.radius_m + math.hypot(q.vx_mps, q.vy_mps) * self.p.react_s)
        return out

    def people_about(self, pose: tuple[float, float, float], people: list[Person]) -> bool:
        """Whether anyone comes, wherever MPEPC predicts them over the horizon, within their
        reach plus the chair's length of its body at `pose` (`reach_gaps`): a creep from there
        could carry it into their way (H75)."""
        fp = self.field.footprint
        bx, by = place_xy(self.field.outline, pose[0], pose[1], pose[2])
        gaps = self.reach_gaps(bx.reshape(1, -1), by.reshape(1, -1), people)
        return bool((gaps < fp.front_m + fp.rear_m).any())

    def later_plans_clear(self, xs: F64, ys: F64, yaws: F64, people: list[Person]
                          ) -> npt.NDArray[np.bool_]:
        """(N,): whether every later plan along the predicted motions (N, T) finds the rest
        of it out of each person's reach disc (`evaluate`'s: r + speed·min(t, react_s) from
        where they stand then) with the people where MPEPC predicts them then
        (`walk_points`), at every step of the horizon (their phase against the plans' is
        not known; H75)."""
        p = self.p
        horizon = np.asarray(np.arange(self.steps + 1) * p.dt_s, dtype=np.float64)
        t = horizon[1:]
        later = t[:, None] > horizon[None, :]  # (T, T + 1): a plan at τ checks the poses after it
        px, py = place_xy(self.field.outline, xs, ys, yaws)  # (N, T, P)
        ok = np.ones(xs.shape[0], dtype=np.bool_)
        for q in people:
            w = self.walk_points(q, horizon)
            v = math.hypot(q.vx_mps, q.vy_mps)
            need = q.radius_m + v * np.clip(t[:, None] - horizon[None, :], 0.0, p.react_s)
            d = np.hypot(px[:, :, :, None, None] - w[None, None, None, :, :, 0],
                         py[:, :, :, None, None] - w[None, None, None, :, :, 1]).min((2, 4))
            ok &= ~((d < need[None]) & later[None]).any((1, 2))
        return ok

    def walk_points(self, person: Person, taus: F64) -> F64:
        """(T, M, 2): where MPEPC predicts `person` may be at times `taus` (s from now; sorted,
        within the horizon), as `outline_distances` does: walking on at their velocity, or
        turned back short of a wall (`wall_turn`: anywhere on its span, sampled)."""
        cv = np.stack([person.x_m + person.vx_mps * taus, person.y_m + person.vy_mps * taus], -1)
        out = np.repeat(cv[:, None, :], 6, axis=1)
        turn = wall_turn(person, self.field, float(taus[-1]))
        if turn is not None:
            after = taus >= turn.from_s
            if after.any():
                ax, ay, bx, by = turn.span(person, taus[after])
                f = np.linspace(0.0, 1.0, 5)
                out[after, 1:, 0] = ax[:, None] + (bx - ax)[:, None] * f
                out[after, 1:, 1] = ay[:, None] + (by - ay)[:, None] * f
        return out

    def door_crossing(self, pose: tuple[float, float, float], goal: tuple[float, float, float],
                      ctg: CostToGo, hf: HeadingField | None, people: list[Person],
                      rates: tuple[float, float] = (0.0, 0.0), final: bool = True,
                      chain: Chain | None = None) -> tuple[bool, Plan | None]:
        """H75: a chair at rest facing through a door on its way (within `door_ahead_m`),
        with people tracked: (True, a plan) or (True, None: stand, blocked, and wait), else
        (False, None: not this rule's).

        Short of the door (the sight rule binds): the straight into it, its front to the far
        side (see below). In it (from rest the sight rule cannot bind: `sight_cap` inf): the
        crossing, the straight along its heading out of the door to the first point at which
        the chair at rest is out of every person's reach (r + speed·react_s) wherever MPEPC
        predicts them over the horizon (`walk_points`), so that it does not stand in their
        way when they come back; driven at the fastest of STAGE_SPEEDS speeds that passes
        MPEPC's checks (`_costs`: people, the stop) and the check every later plan along it
        will make (`later_plans_clear`). So, as predicted, no plan finds the chair blocked
        half-way across their way and stops it there: a chair stopped in a person's lane is
        walked into (nav_eval --monitor seed 1: MPEPC's own way out of the door, slowed by the
        monitor's turn bound in the frame, blocked in the lane, −0.24 m). Its start is timed
        within the plan period (`start_s`); the rest of it under way is rechecked at its own
        speed (Plan.crossing). No steering: the monitor's turn bound in a door frame slowed
        MPEPC's arcs, unpredicted. A person who turns back unpredicted is seen at the next
        plan: the rest of the straight is then a hit and the chair brakes, as for any plan
        (the residual)."""
        p, fld = self.p, self.field
        x, y, yaw = pose
        if not people or not p.stages:
            return False, None
        found = fld.passage_ahead(ctg, x, y, p.door_ahead_m)
        if found is None or math.hypot(goal[0] - x, goal[1] - y) <= p.door_ahead_m:
            return False, None
        path, k, j = found
        c, s = math.cos(yaw), math.sin(yaw)
        if abs((path[k, 1] - y) * c - (path[k, 0] - x) * s) > 0.1:
            return False, None  # (not facing through it: MPEPC's, through_door's)
        out = float((path[j, 0] - x) * c + (path[j, 1] - y) * s)  # (to the door's exit)
        if out <= 0.0:
            return False, None
        if (top := self.sight_cap(pose, ctg, chain)) < math.inf:
            # Short of the door: into it first, its front to the door's far side (1 cm short
            # of where the sight rule's reading of the way has it: the rule then binds no
            # more, from rest), judged whole (it ends at rest within the horizon); else stand.
            # From farther out (a line-up) the crossing itself is too slow to clear the way of
            # a person pacing beyond (the sight-limited speed to the far side: ~4 s against
            # ~2.3 s of each 5.5 s walk out of their reach). Not `brake_clear_m` short of it,
            # where the rule stops a chair: there the monitor reads the padded front corners
            # beside the jambs' ends unable to turn (its |ω| bound ~0), and a chair brought to
            # a stand under it ends its goal (H73; nav_eval --monitor seeds 7, 2: aborted).
            far = self.door_far(path, k)
            d0 = float((path[far, 0] - x) * c + (path[far, 1] - y) * s) \
                - fld.footprint.front_m - p.brake_clear_m
            past = next((float(d) for d in np.arange(max(d0, 0.02), d0 + 0.2, 0.01)
                         if self.sight_cap((x + d * c, y + d * s, yaw), ctg, chain,
                                           self.law.vmax_mps) == math.inf), None)
            d_in = None if past is None else past - 0.01
            if d_in is not None and self.sight_cap((x + d_in * c, y + d_in * s, yaw), ctg,
                                                   chain) < math.inf:
                d_in = past
            if d_in is None or fld.straight_clearance(pose, np.arange(
                    0.0, d_in + 0.01 + p.final_overshoot_m + 0.005, 0.01)) < p.contact_m:
                return False, None  # (not a clear straight in: through_door's, MPEPC's)
            inside = self._one_stage(pose, (d_in, 0.0), (x + d_in * c, y + d_in * s, yaw),
                                     False, ctg, people, goal, hf, rates, final=final, top=top,
                                     whole=True)
            return True, inside
        spare = 0.01 + p.final_overshoot_m
        ds = np.arange(out, out + 4.0, 0.05)
        rest_x, rest_y = place_xy(fld.outline, x + ds * c, y + ds * s, np.full(ds.size, yaw))
        away = (self.reach_gaps(rest_x, rest_y, people) >= 0.0).all(1)
        if not away.any():
            return True, None
        dist = float(ds[int(np.argmax(away))])
        line = fld.straight_clearance(pose, np.arange(0.0, dist + spare + 0.005, 0.01))
        if line < p.contact_m:
            return False, None  # (not a clear straight out: MPEPC's)
        speeds = np.linspace(min(p.v_min_mps, self.law.vmax_mps), self.law.vmax_mps,
                             STAGE_SPEEDS)
        n = speeds.size
        zz = np.zeros((n + 1, 4))  # (the last row: braking to rest, the stop cost)
        zz[:n, 0], zz[:n, 3] = dist, speeds

        def crossing(wait: float) -> Plan | None:
            # (set off `wait` s later: as setting off now with the people moved on by as much,
            # as the core moves them on to where the plan takes effect)
            moved = [replace(q, x_m=q.x_m + q.vx_mps * wait, y_m=q.y_m + q.vy_mps * wait,
                             ahead_s=q.ahead_s + wait) for q in people]
            cost, info = self._costs(pose, 0.0, 0.0, zz, ctg, moved, goal, rates, final, hf,
                                     line=np.arange(n + 1) < n)
            # (ended at rest within the horizon: beyond it the prediction says nothing)
            ok = (info["hit"][:n] == 0.0) & rests_within(info, n)
            xs, ys, yaws = info["x"][:n], info["y"][:n], info["yaw"][:n]
            ok &= self.later_plans_clear(xs, ys, yaws, moved)
            if not ok.any():
                return None
            i = int(np.nonzero(ok)[0][-1])  # (the fastest: the most time to spare)
            return self._plan_of(pose, zz[i], float(cost[i]), {m: v[i] for m, v in info.items()},
                                 float(cost[n]), len(zz), (x + dist * c, y + dist * s, yaw),
                                 straight_m=dist, crossing=True, start_s=wait)

        # The start is timed finer than the plan period (a person's walk has no period the
        # plans keep step with): set off at the middle of the first run of start times, 0.1 s
        # apart, that cross (the most spare either way); a middle beyond the plan period is
        # left to the next plan, which sees the person anew.
        waits = np.arange(0.0, 2.0 * self.law.commit_s + 1e-9, 0.1)
        run: list[tuple[float, Plan]] = []
        for wait in waits:
            got = crossing(float(wait))
            if got is not None:
                run.append((float(wait), got))
            elif run:
                break
        if not run:
            return True, None
        wait, plan = run[(len(run) - 1) // 2]
        return True, (plan if wait < self.law.commit_s else None)

    def stage_plan(self, pose: tuple[float, float, float], goal: tuple[float, float, float],
                   ctg: CostToGo, hf: HeadingField | None, people: list[Person],
                   rates: tuple[float, float] = (0.0, 0.0),
                   straight_to: tuple[float, float] | None = None,
                   v0: float = 0.0, turn_to: float | None = None, land: bool = False,
                   anywhere: bool = False, top: float | None = None,
                   chain: Chain | None = None, crossing: bool = False) -> Plan | None:
        """A plan of one stage (Mpepc.stage) for a chair at rest that MPEPC left blocked; or,
        with `straight_to` (the landing of a straight stage under way, or of a stage's turn
        done), the rest of that straight if it still lies ahead on the chair's line and
        sweeps clear; or with `turn_to` as well (a stage's turn under way), the rest of that
        turn if it sweeps clear; or with `land`, the stage onto the goal of a chair at rest
        just outside its tolerance (Mpepc.landing). A stage is offered where the lattice is
        active (`lattice_active`), or with `anywhere` wherever the chair's state has a way on
        it (planner.compute's last resort). Each is also evaluated as MPEPC's
        candidates are (`_costs`: people, the stop after the plan period) and dropped if
        that predicts a hit; a straight's speed is the fastest clear up to `top` (_one_stage:
        the rest of a straight under way at most the speed it was given, so a door's
        sight-limited speed holds through it and the move is never sped up mid-way; a new
        straight given none, at most `sight_cap` from where it sets off, `chain` the core's;
        `crossing`: a door's crossing straight under way, rechecked at `top` only, H75).
        None: no stage."""
        x, y, yaw = pose
        c, s = math.cos(yaw), math.sin(yaw)
        if straight_to is not None and turn_to is not None:
            # (onto ψ and 2° past: the spare Mpepc.stage checked the turn with)
            e = float(wrap(np.array(turn_to - yaw)))
            spare = math.copysign(math.radians(2.0), e)
            if self.field.turn_clearance(pose, e + spare) < self.p.contact_m:
                return None
            psi, dist = yaw + e, math.hypot(straight_to[0] - x, straight_to[1] - y)
        elif straight_to is not None:
            along, left = along_lateral(pose, *straight_to)
            # (still moving at its end, or predicted just past it: the straight braked to rest
            # there, so that the next plan looks again from rest, as after every stage; handed
            # over at 0.05 m/s, MPEPC's plan from there differed by chance from the one from
            # rest and left the chair blocked beside office B's goal, nav_eval seed 7)
            moving = abs(v0) >= 0.01 and along > -0.02
            if (along <= 0.005 and not moving) or abs(left) > 0.02:
                return None
            along = max(along, 0.001)  # (a straight still: the core brakes it onto its point)
            if self.field.straight_clearance(pose, np.arange(
                    0.0, along + self.p.final_overshoot_m + 0.005, 0.01)) < self.p.contact_m:
                return None
            psi, dist = yaw, along
        else:
            if not self.p.stages:
                return None
            if land:
                got = self.landing(pose, goal)
            elif hf is None or not (anywhere or self.lattice_active(hf, pose, float(ctg.at(
                    self.field.map, np.array(pose[:2]))))):
                return None
            else:
                got = self.stage(pose, goal, hf)
            if got is None:
                return None
            psi, dist = got
        turn = psi != yaw
        # (the straight predicted as the law along the line; shorter than in_place_r_m it is
        # predicted standing: its sweep is checked above, people from where it stands)
        return self._one_stage(
            pose, (0.0, float(wrap(np.array(psi - yaw)))) if turn else (dist, 0.0),
            (x, y, psi) if turn else (x + dist * c, y + dist * s, yaw), turn, ctg, people,
            goal, hf, rates, v0, True,
            straight_to if straight_to is not None else
            (x + dist * math.cos(psi), y + dist * math.sin(psi)) if turn and dist > 0.0
            else None, top, chain, crossing and not turn)

    def _one_stage(self, pose: tuple[float, float, float], rz: tuple[float, float],
                   tgt: tuple[float, float, float], turn: bool, ctg: CostToGo,
                   people: list[Person], goal: tuple[float, float, float],
                   hf: HeadingField | None, rates: tuple[float, float] = (0.0, 0.0),
                   v0: float = 0.0, final: bool = True,
                   then: tuple[float, float] | None = None, top: float | None = None,
                   chain: Chain | None = None, crossing: bool = False,
                   whole: bool = False) -> Plan | None:
        """One stage as a plan: the law's target `rz` (r, θ; a turn in place: r 0), `tgt` its
        pose, `turn` whether it turns (else a straight of r), `then` where a turn's straight
        lands. Evaluated as MPEPC's candidates are (`_costs`: people, the stop after the plan
        period); None if that predicts a hit. A turn at the least speed (the core turns it in
        place, v 0). A straight is driven by the core's time-optimal move at the plan's
        `vmax_mps` (control/core.py _follow_plan): it is evaluated as that move (law_step's
        `line`) at STAGE_SPEEDS speeds from the least (v_min_mps, or `top` if less) to `top`
        (default the law's vmax), and given the fastest up to which every one is clear (the
        core may drive it slower than given: a short straight's peak, the goal's own top speed,
        the monitor's bound; H67: evaluated at the least speed only, stages were driven at up
        to 1.16 m/s). A straight given no `top` sets off at most at `sight_cap` (`chain`: the
        core's, for its reaction time). `crossing`: a door's crossing under way, evaluated at
        `top` alone (Plan.crossing); `whole`: only speeds at which the straight ends within the
        horizon count as clear (H75)."""
        vmin = self.p.v_min_mps
        if top is None and not turn:
            top = self.sight_cap(pose, ctg, chain, v0)
        hi = min(top, self.law.vmax_mps) if top is not None else self.law.vmax_mps
        lo = min(vmin, hi)
        # (a straight shorter than in_place_r_m is predicted standing, its sweep checked by the
        # caller: at the least speed, as before; a row over it would be "turn, then go on")
        short = not turn and rz[0] < self.p.in_place_r_m
        if crossing and not short:
            speeds = np.array([hi])
        elif turn or short or hi <= lo:
            speeds = np.array([vmin])
        else:
            speeds = np.linspace(lo, hi, STAGE_SPEEDS)
        k = speeds.size
        zz = np.zeros((k + 1, 4))  # (the last row: braking to rest, the stop cost)
        zz[:k, 0], zz[:k, 1], zz[:k, 3] = rz[0], rz[1], speeds
        line = None if turn else np.arange(k + 1) < k
        cost, info = self._costs(pose, v0, 0.0, zz, ctg, people, goal, rates, final, hf,
                                 line=line)
        clear = info["hit"][:k] == 0.0
        i0 = 0
        if whole:  # (`whole`: the speeds at which the straight ends within the horizon, from
            # the least of them up)
            ends = rests_within(info, k)
            if not ends.any():
                return None
            i0 = int(np.argmax(ends))
            clear = clear & ends
        if not clear[i0]:
            return None
        # (the last of the clear run)
        i = k - 1 if clear[i0:].all() else i0 + int(np.argmin(clear[i0:])) - 1
        plan = self._plan_of(pose, zz[i], float(cost[i]), {n: v[i] for n, v in info.items()},
                             float(cost[k]), len(zz), tgt, final_turn=turn,
                             straight_m=0.0 if turn else rz[0], then=then,
                             crossing=crossing and not short)
        if short:  # (a straight's last cm, braking: at most the speed it has, never sped up)
            plan = replace(plan, vmax_mps=max(vmin, min(abs(v0), hi)))
        return plan

    def _plan_of(self, pose: tuple[float, float, float], z: F64, cost: float,
                 row: dict[str, F64], stop_cost: float, evaluations: int,
                 tgt: tuple[float, float, float] | None = None, is_goal: bool = False,
                 goal_clearance_m: float = math.nan, **kw: Any) -> Plan:
        """The Plan of candidate `z` (r, θ, δ, vmax) as `_costs` evaluated it (`row`: its
        entries of `info`); `tgt` the law's target pose, by default z's from `pose`."""
        if tgt is None:
            t = (self.in_place_targets(pose, z[None, :]) if z[0] < self.p.in_place_r_m
                 else self.targets(pose, z[None, :]))[0]
            tgt = (float(t[0]), float(t[1]), float(t[2]))
        return Plan((float(z[0]), float(z[1]), float(z[2]), float(z[3])), tgt, float(z[3]),
                    cost, float(row["phi0"] - row["phi_end"]), float(row["survival"]),
                    float(row["clearance"]), np.stack([row["x"], row["y"], row["yaw"]], -1),
                    is_goal, goal_clearance_m, stop_cost, evaluations,
                    escape=bool(row["escape"]), **kw)

    def turn_first(self, pose: tuple[float, float, float], goal: tuple[float, float, float],
                   ctg: CostToGo, people: list[Person], final: bool,
                   hf: HeadingField | None, progress_m: float, gain: float) -> Plan | None:
        """For a chair at rest that no plan moves on (blocked) where the lattice has no stage:
        an in-place turn onto a heading from which a plan does make progress (at least
        `progress_m`, and `gain` cheaper than standing there), judged by MPEPC's own seeds
        from the turned chair. The candidates cannot express a small exact turn: an in-place
        candidate turns only from 2·ALIGNED_RAD on, the law's heading correction towards a far
        target takes metres, and 0.24 m before a 0.9 m door a chair 4° off the door's axis
        had every way through touch its frame (nav_eval seed 7 at a 0.1 s plan latency:
        blocked till aborted, 1.2 m before the door). The headings tried: down the
        navigation function and towards points along its descent. None: no such turn."""
        x, y, yaw = pose
        want = [float(ctg.descent(self.field.map, np.array([x, y])))]
        want += [math.atan2(py - y, px - x) for px, py, _ in self.descent_path(pose, ctg, goal)]
        offs: list[float] = []
        for w in want:
            e = float(wrap(np.array(w - yaw)))
            if abs(e) >= ALIGNED_RAD and all(abs(e - o) > 0.5 * ALIGNED_RAD for o in offs):
                offs.append(e)
        # Both steps against standing here: progress from here (near the goal, on the
        # lattice, a turn onto a worse heading "progressed" by turning back: a limit cycle,
        # 48° to 80° and back in office A, nav_eval seed 2), the turned plan's cost with
        # the turn's own change of the costs-to-go added.
        stop, here = self._costs(pose, 0.0, 0.0, np.zeros((1, 4)), ctg, people, goal,
                                 final=final, heading=hf)
        phi = float(here["phi0"][0])
        best: tuple[float, float] | None = None  # (cost of turning, then the plan; turn)
        for e in offs:
            turned = (x, y, float(wrap(np.array(yaw + e))))
            rows, _ = self.seeds(turned, goal, None, ctg, hf)
            cost, info = self._costs(turned, 0.0, 0.0, rows, ctg, people, goal, final=final,
                                     heading=hf)
            total = cost + info["phi0"] - phi
            ok = (info["hit"] == 0.0) & (phi - info["phi_end"] >= progress_m) \
                & (total < float(stop[0]) - gain)
            if ok.any() and (best is None or float(total[ok].min()) < best[0]):
                best = (float(total[ok].min()), e)
        if best is None:
            return None
        e = best[1]
        # (`then`, the chair's own point: looked at again half-way round, every way on read
        # blocked and the chair turned back, 25° to 86° and back before office A's door till
        # "no progress"; planner.compute carries the turn on while that is so)
        plan = self._one_stage(pose, (0.0, e), (x, y, float(wrap(np.array(yaw + e)))), True,
                               ctg, people, goal, hf, final=final, then=(x, y))
        return None if plan is None else replace(plan, turn_first=True)

    def along_lattice(self, pose: tuple[float, float, float], goal: tuple[float, float, float],
                      ctg: CostToGo, people: list[Person], final: bool, hf: HeadingField,
                      progress_m: float, gain: float, rates: tuple[float, float] = (0.0, 0.0),
                      chain: Chain | None = None) -> Plan | None:
        """For a chair at rest that nothing else moves on (blocked; no stage, no turn): the
        law's target a little beyond the poses along the lattice's best way (0.2–1.5 m on;
        0–0.2 m further along its heading, ±4 cm beside it, ±10° off it) at low speeds, the
        best one that is clear, progresses at least `progress_m` and costs `gain` less than
        standing. The lattice's way there is arcs the law cannot follow onto its exact poses
        and the stages' turns and straights do not reproduce; a target just beyond one, at
        the right speed, is a curve the law does drive, but MPEPC's sampler seldom offers
        one that narrow (nav_eval seed 1 at a 0.1 s plan latency, office A's far corner:
        2 of these 675 targets from (5.38, 2.63, 44°), none of the sampler's in 12 s,
        blocked till aborted). Evaluated as the candidates are (`_costs`). None: none."""
        vmax = self.law.vmax_mps
        rows: list[list[float]] = []
        travelled, last = 0.0, (pose[0], pose[1])
        for (x, y, yaw), turned in hf.best_path(*pose):
            travelled += math.hypot(x - last[0], y - last[1])
            last = (x, y)
            if travelled > 1.5:
                break
            if turned or travelled < 0.2:
                continue
            c, s = math.cos(yaw), math.sin(yaw)
            for a, lat, off in itertools.product((0.0, 0.05, 0.1, 0.15, 0.2), (-0.04, 0.0, 0.04),
                                                 np.radians((-10.0, 0.0, 10.0))):
                zz = self.relative(pose, (x + a * c - lat * s, y + a * s + lat * c, yaw + off))
                if zz[0] >= self.p.in_place_r_m and abs(zz[2]) <= self.p.delta_max_rad:
                    rows += [[*zz, v] for v in (self.p.v_min_mps, vmax / 5, vmax / 3)]
        if not rows:
            return None
        z = self.capped(np.array([[0.0, 0.0, 0.0, 0.0], *rows]),  # (row 0: braking, standing)
                        self.sight_cap(pose, ctg, chain))
        cost, info = self._costs(pose, 0.0, 0.0, z, ctg, people, goal, rates, final, hf, chain)
        ok = (info["hit"] == 0.0) & (info["phi0"] - info["phi_end"] >= progress_m) \
            & (cost < float(cost[0]) - gain)
        ok[0] = False
        if not ok.any():
            return None
        i = int(np.argmin(np.where(ok, cost, math.inf)))
        return self._plan_of(pose, z[i], float(cost[i]), {k: v[i] for k, v in info.items()},
                             float(cost[0]), len(z))

    def wide_line_clear(self, pose: tuple[float, float, float], v0: float, w0: float,
                        goal: tuple[float, float, float]) -> bool:
        """From rest within `final_move_m` the core drives its straight final wherever the
        goal's line passes within `final_line` of the tolerance (control/core.py), not only
        within the capture radius: a goal handed over there must have that manoeuvre clear."""
        r = math.hypot(goal[0] - pose[0], goal[1] - pose[1])
        if abs(v0) >= 0.01 or abs(w0) >= 0.01 or not self.law.tolerance_m < r \
                <= self.p.final_move_m:
            return True
        along, left = along_lateral(pose, goal[0], goal[1])
        if along <= 0.0 or not self.law.capture_m < abs(left) \
                <= self.p.final_line * self.law.tolerance_m:
            return True
        return self.final_heading(pose, goal, turn=False, straight=True) is not None

    def lined_up(self, pose: tuple[float, float, float], ctg: CostToGo,
                 hf: HeadingField | None) -> bool:
        """The goal may be handed to the core's own final approach (a straight final, then
        an in-place turn) only where the lattice needs no manoeuvre from the chair's state:
        its costs-to-go within `lined_up_m` of the 2-D field's. Else the core drove in
        straight and was left beside the goal, turned 30–90° off, with no room to turn."""
        if hf is None or math.hypot(pose[0] - hf.goal[0], pose[1] - hf.goal[1]) \
                < self.p.in_place_r_m:  # at the goal: only its in-place turn is left
            return True
        phi0 = float(ctg.at(self.field.map, np.array(pose[:2])))
        if not self.lattice_active(hf, pose, phi0):
            return True
        c, _ = hf.at(np.array(pose[0]), np.array(pose[1]), np.array(pose[2]))
        return float(c) - phi0 <= self.p.lined_up_m

    def heading_phi(self, hf: HeadingField, xs: F64, ys: F64, yaws: F64, phi: F64,
                    pose: tuple[float, float, float], phi0: float
                    ) -> tuple[F64, float, npt.NDArray[np.bool_]]:
        """Progress measured on the heading-aware costs-to-go (nav/lattice.py) where they are
        defined, on the 2-D field + their offset outside the window, and that + a penalty on
        states inside it from which the lattice has no way (a corner the chair cannot turn
        out of). Returns φ (N, T), φ at the start, and which predictions end on the lattice."""
        p3, ok = hf.at(xs, ys, yaws)
        inside = hf.inside(xs, ys)
        fallback = phi + hf.offset + np.where(inside, self.p.no_way_cost, 0.0)
        q0, ok0 = hf.at(np.array(pose[0]), np.array(pose[1]), np.array(pose[2]))
        if bool(ok0):
            start = float(q0)
        else:
            start = phi0 + hf.offset + (self.p.no_way_cost if bool(
                hf.inside(np.array(pose[0]), np.array(pose[1]))) else 0.0)
        return np.where(ok, p3, fallback), start, ok[:, -1]

    # --- optimisation -------------------------------------------------------------------------
    def seeds(self, pose: tuple[float, float, float], goal: tuple[float, float, float],
              previous: tuple[float, float, float, float] | None, ctg: CostToGo,
              hf: HeadingField | None = None) -> tuple[F64, bool]:
        """Seed candidates; row 0 is the goal itself when it is within the bounds (→ True)."""
        vmax = self.law.vmax_mps
        rows = []
        r_goal, th, de = self.relative(pose, goal)
        if r_goal < self.p.in_place_r_m:
            # A goal within in_place_r_m: turn there onto its yaw (θ − δ), do not drive on. Its
            # line of sight (δ) means nothing this close: a goal 1 cm behind the axle was out
            # of δ's bounds, never offered, and the chair stood 8° off it, "blocked" (measured).
            th, de = float(wrap(np.array(goal[2] - pose[2]))), 0.0
        has_goal = r_goal <= self.p.r_max_m and abs(de) <= self.p.delta_max_rad
        if has_goal:
            rows.append([r_goal, th, de,
                         vmax if r_goal >= self.p.in_place_r_m else self.p.v_min_mps])
        rows.append([0.0, 0.0, 0.0, 0.0])  # brake to rest (row `has_goal`; vmax 0: law_step)
        if has_goal and r_goal >= self.p.in_place_r_m:
            rows.append([r_goal, 0.0, de, vmax])  # to the goal's position, facing it
        want = float(ctg.descent(self.field.map, np.array(pose[:2])))
        for heading in (want, goal[2]):
            turn = float(wrap(np.array(heading - pose[2])))
            rows += [[0.0, turn, 0.0, vmax], [0.0, turn, 0.0, self.p.v_min_mps]]
        if previous is not None:
            rows.append(list(previous))
        if self.pose_clearance(pose) < self.escape_below:
            # (the escape rule's: the way out is often a small turn in place alone, which the
            # quasi-random set rarely lands on: 1 in 80 of its targets turns in place)
            rows += [[0.0, a, 0.0, self.p.v_min_mps] for a in (
                0.05, -0.05, 0.1, -0.1, 0.2, -0.2, 0.4, -0.4, 0.8, -0.8)]
        # Points down the navigation function, heading along it: in clutter and doorways the
        # quasi-random set rarely lands on the narrow band of targets that threads a gap.
        for x, y, heading in self.descent_path(pose, ctg, goal):
            z = self.relative(pose, (x, y, heading))
            if abs(z[2]) <= self.p.delta_max_rad:
                rows += [[*z, vmax], [*z, 0.5 * vmax]]
        if hf is not None and self.lattice_active(
                hf, pose, float(ctg.at(self.field.map, np.array(pose[:2])))):
            rows += self.lattice_seeds(pose, hf)
        return np.array(rows), has_goal

    def lattice_seeds(self, pose: tuple[float, float, float], hf: HeadingField,
                      at_m: tuple[float, ...] = (0.4, 0.8, 1.2, 1.6, 2.0, 3.0, 4.0)
                      ) -> list[list[float]]:
        """Candidates along the lattice's best way: an in-place turn it starts with (turn
        only, and turn then go), the poses `at_m` along it, and each place where it turns in
        place later, at the heading it arrives with (the next plan then turns there)."""
        vmax, vmin = self.law.vmax_mps, self.p.v_min_mps
        path = hf.best_path(*pose)
        rows: list[list[float]] = []
        if not path:
            return rows
        i = 0
        while i < len(path) and path[i][1]:
            i += 1
        if i:
            turn = float(wrap(np.array(path[i - 1][0][2] - pose[2])))
            rows += [[0.0, turn, 0.0, vmin], [0.0, turn, 0.0, vmax]]
        travelled, j, last = 0.0, 0, (pose[0], pose[1])
        prev_turn, prev_yaw = True, path[i - 1][0][2] if i else pose[2]
        for (x, y, yaw), turned in path[i:]:
            travelled += math.hypot(x - last[0], y - last[1])
            last = (x, y)
            picks = []
            if j < len(at_m) and travelled >= at_m[j] - 1e-9:
                picks.append((x, y, yaw))
                j += 1
            if turned and not prev_turn and travelled > 0.3:
                picks.append((x, y, prev_yaw))
            prev_turn, prev_yaw = turned, yaw
            for tgt in picks:
                zz = self.relative(pose, tgt)
                if abs(zz[2]) <= self.p.delta_max_rad and zz[0] >= self.p.in_place_r_m:
                    rows += [[*zz, vmax], [*zz, 0.5 * vmax]]
        return rows

    def descent_path(self, pose: tuple[float, float, float], ctg: CostToGo,
                     goal: tuple[float, float, float], step_m: float = 0.1,
                     at_m: tuple[float, ...] = (0.6, 1.0, 1.5, 2.0, 3.0, 4.0, 5.5)
                     ) -> list[tuple[float, float, float]]:
        """Poses `at_m` along the steepest descent of φ from the chair (stopping at the goal)."""
        gm = self.field.map
        x, y = pose[0], pose[1]
        out: list[tuple[float, float, float]] = []
        travelled, i = 0.0, 0
        while i < len(at_m) and travelled < at_m[-1] + 1e-9:
            if math.hypot(goal[0] - x, goal[1] - y) < step_m:
                break
            heading = ctg.descent_xy(gm, x, y)
            x, y = x + step_m * math.cos(heading), y + step_m * math.sin(heading)
            travelled += step_m
            if travelled >= at_m[i] - 1e-9:
                out.append((x, y, heading))
                i += 1
        return out

    def plan(self, pose: tuple[float, float, float], v0: float, w0: float,
             goal: tuple[float, float, float], ctg: CostToGo, people: list[Person] | None = None,
             previous_target: tuple[float, float, float, float] | None = None,
             rates: tuple[float, float] = (0.0, 0.0), final: bool = True,
             heading: HeadingField | None = None, goal_turn: bool = True,
             chain: Chain | None = None, on_line: bool = False) -> Plan:
        """The best z from the chair at `pose` (v0, ω0: the command it is tracking; `rates`:
        the limiter's dv/dt and dω/dt; `final`: `goal` is the last waypoint, which the core
        approaches on its braking curve once it is the target; an intermediate one it passes).
        `previous_target`: the last plan's world target + vmax, re-expressed as a seed.
        The goal itself wins over a slightly cheaper target near it when its prediction is
        clear and ends on it (the final approach is then the control law's own), and, with
        `goal_turn`, the core's turn onto the goal's yaw keeps `contact_m`
        (goal_turn_clearance). `chain`: the core's drive chain, through which the committed
        sweeps are checked (chain_sweep). `on_line`: the core drives its straight final onto
        the goal (no steering), which row 0, the law's approach, does not predict."""
        people = people or []
        lo, hi = self.bounds()
        prev = None
        if previous_target is not None:
            rel = self.relative(pose, previous_target[:3])
            if rel[0] <= self.p.r_max_m and abs(rel[2]) <= self.p.delta_max_rad:
                prev = (float(rel[0]), float(rel[1]), float(rel[2]), previous_target[3])
        seeds, has_goal = self.seeds(pose, goal, prev, ctg, heading)
        top = self.sight_cap(pose, ctg, chain, v0)
        z = self.capped(np.concatenate([seeds, self._global]), top)
        cost, info = self._costs(pose, v0, w0, z, ctg, people, goal, rates, final,
                                  heading, chain)
        evals = len(z)
        i = int(np.argmin(cost))
        best_z, best_c, best = z[i].copy(), float(cost[i]), {k: v[i] for k, v in info.items()}
        scale = (hi - lo) * 0.15
        for _ in range(self.p.local_rounds):
            cand = self.capped(np.clip(best_z + self._rng.normal(size=(self.p.n_local, 4))
                                       * scale, lo, hi), top)
            c2, inf2 = self._costs(pose, v0, w0, cand, ctg, people, goal, rates, final,
                                   heading, chain)
            evals += len(cand)
            j = int(np.argmin(c2))
            if c2[j] < best_c:
                best_z, best_c, best = cand[j].copy(), float(c2[j]), {k: v[j]
                                                                     for k, v in inf2.items()}
            scale *= 0.5
        is_goal, goal_clear, withheld = False, math.nan, False
        r_goal = math.hypot(goal[0] - pose[0], goal[1] - pose[1])
        # (row 0 predicts the core's approach only beyond in_place_r_m: handover)
        goal_stop_clear = not has_goal or r_goal < self.p.in_place_r_m \
            or float(info["stop_hit"][0]) == 0.0
        turn_ok = not (final and goal_turn) or \
            self.goal_turn_clearance(pose, goal) >= self.p.contact_m
        if has_goal:
            # What the core's own final approach relies on (it drops the goal and stands when
            # this is < 2 cm): the way to the goal, and braking from the chair's present
            # motion. The core's approach is not what row 0 predicts (near the goal it may
            # turn in place the other way); a chair already turning into an obstacle must
            # not be left to it, nor one for which every motion touches (contacts with the
            # bench, measured).
            # While the core drives its straight final, the way is that straight, not row 0:
            # the law from 0.6 m out at 0.77 m/s swung to 0.004 m in the L's corner where the
            # straight keeps 0.18; the goal handed back there, braked while the law turned
            # the chair, stood 7 cm / 18° off, blocked (nav_eval seed 7 at a 0.1 s plan
            # latency). The straight is checked, people and the stop too, as the law along
            # the line (as final_heading's straight below).
            way = float(info["clearance"][0])
            if on_line:
                along = max(along_lateral(pose, goal[0], goal[1])[0], 0.0)
                vmax = min(max(abs(v0), self.p.v_min_mps), float(hi[3]))
                _, line = self._costs(pose, v0, w0, np.array([[along, 0.0, 0.0, vmax]]), ctg,
                                      people, goal, rates, final, heading, chain)
                way = float(line["clearance"][0])
            goal_clear = min(way, float(info["clearance"][1]),
                             float(best["clearance"]))  # (< contact_m: every motion touches)
            ends = math.hypot(float(info["x"][0, -1]) - goal[0], float(info["y"][0, -1]) - goal[1])
            # In the position tolerance only the goal's turn is left: it is taken whenever its
            # sweep is clear, whatever it costs against standing still (which never arrives;
            # the collision cost of a turn beside a wall outweighed its heading term, and the
            # chair stood 83° off office B's desk, "blocked"; measured). The core checks the
            # sweep again before it turns (H40).
            there = final and r_goal <= self.law.tolerance_m
            # The slack is not for a goal still beyond goal_blend_m whose way passes an obstacle
            # closer than 2σ (where p_c starts to count: e^-4) while the best plan keeps that
            # clear: the law's line to the goal ignores obstacles, and the chair took it past
            # the L corridor's pillar at 1.2 m/s, 0.12 m off, with a centred way 0.16 cheaper
            # (nav_eval seed 7; measured). Nearer, a tight goal's own turn needs the slack
            # (office B's desk: blocked 5 cm short without it; measured).
            slack = 0.0 if final and r_goal > self.p.goal_blend_m and float(
                info["clearance"][0]) < 2 * self.p.sigma_static_m <= float(best["clearance"]) \
                else self.p.goal_slack
            # Never where it is a hit (a person's reach, the stop after the plan period), even
            # where every other motion is one too and it is within the slack of the best: in
            # the cluttered room's gap the law's approach at 1.08 m/s, its stop a hit, was
            # handed over; dropped 0.5 s later at 1.19 m/s, the chair braked 0.3 m past the
            # goal, its front 0.19 m into the end wall (a rejected planner change, seed 7).
            if float(info["clearance"][0]) >= self.p.contact_m and ends < 0.3 \
                    and float(info["hit"][0]) == 0.0 \
                    and (there or float(cost[0]) <= best_c + slack) \
                    and self.lined_up(pose, ctg, heading) \
                    and (not final or (self.handover(pose, v0, goal)
                                       and self.wide_line_clear(pose, v0, w0, goal))):
                if turn_ok:
                    best_z, best_c, best = z[0].copy(), float(cost[0]), {
                        k: v[0] for k, v in info.items()}
                    is_goal = True
                else:
                    withheld = True
        final_turn = False
        if has_goal and final and not is_goal \
                and self.p.final_from * self.law.tolerance_m < r_goal <= self.p.final_move_m:
            # (a turn only from rest or on from a turn under way; the straight final not
            # during a turn: its swing as it brakes would put the chair off the line)
            psi = self.final_heading(pose, goal, turn=abs(v0) < 0.01,
                                     straight=abs(w0) < 0.01 and turn_ok)
            if psi is not None:  # lined up: the core's straight final, else turn onto ψ
                # (checked for people and the stop as the law along the line: the straight)
                along = along_lateral((pose[0], pose[1], psi), goal[0], goal[1])[0]
                zz = np.array([[along, 0.0, 0.0, self.p.v_min_mps] if psi == pose[2] else
                               [0.0, float(wrap(np.array(psi - pose[2]))), 0.0,
                                self.p.v_min_mps]])
                c3, inf3 = self._costs(pose, v0, w0, zz, ctg, people, goal, rates, final,
                                       heading, chain)
                if float(inf3["hit"][0]) == 0.0:
                    is_goal, final_turn = psi == pose[2], psi != pose[2]
                    best_z, best_c, best = (z[0] if is_goal else zz[0]).copy(), float(c3[0]), {
                        k: v[0] for k, v in inf3.items()}
                    goal_clear = float(inf3["clearance"][0]) if is_goal else goal_clear
        return self._plan_of(pose, best_z, best_c, best, float(cost[int(has_goal)]), evals,
                             is_goal=is_goal, goal_clearance_m=goal_clear, final_turn=final_turn,
                             goal_withheld=withheld and not is_goal and not final_turn,
                             goal_stop_clear=goal_stop_clear, sight_mps=top)

    def capped(self, z: F64, top: float) -> F64:
        """Candidates z (N, 4) with vmax at most `top` (sight_cap; the core drives a plan at
        most at its vmax, so the prediction stays the core's motion). A turn-then-go row stays
        one (in_place_targets tells it by vmax over v_min + 0.01: at least v_min + 0.02)."""
        if top >= self.law.vmax_mps:
            return z
        z = z.copy()
        go = (z[:, 0] < self.p.in_place_r_m) & (z[:, 3] > self.p.v_min_mps + 0.01)
        z[:, 3] = np.where(go, np.maximum(np.minimum(z[:, 3], top), self.p.v_min_mps + 0.02),
                           np.minimum(z[:, 3], top))
        return z

    def _costs(self, pose: tuple[float, float, float], v0: float, w0: float, z: F64,
               ctg: CostToGo, people: list[Person], goal: tuple[float, float, float],
               rates: tuple[float, float] = (0.0, 0.0), final: bool = True,
               heading: HeadingField | None = None, chain: Chain | None = None,
               line: npt.NDArray[np.bool_] | None = None) -> tuple[F64, dict[str, F64]]:
        cost, info = self.evaluate(pose, v0, w0, z, ctg, people, *rates, goal, final, heading,
                                   chain, line)
        # Final-heading term: the turn still to make where the prediction ends. Away from the
        # goal, to face down −∇φ; within goal_blend_m, to the goal's yaw (the law curves onto
        # it). Within half that (no room to curve: the chair is 1.2 m long) a forward-only
        # chair must turn to face the goal, drive, then turn to its yaw: that sum, blended into
        # |goal yaw − yaw| over the last in_place_r_m. Without it a goal just behind or beside
        # the chair at its own yaw looked reached in heading, standing still was the best plan
        # and the goal ended "blocked" in open space.
        end = np.stack([info["x"][:, -1], info["y"][:, -1]], -1)
        yaw_end = info["yaw"][:, -1]
        desc = ctg.descent(self.field.map, end)
        d = np.hypot(end[:, 0] - goal[0], end[:, 1] - goal[1])
        face = np.abs(wrap(yaw_end - desc))
        at_goal = np.abs(wrap(goal[2] - yaw_end))
        tdt = face + np.abs(wrap(goal[2] - desc))
        blend = self.p.goal_blend_m
        u = np.clip(2.0 - 2.0 * d / blend, 0.0, 1.0)  # 1 within blend/2, 0 from blend on
        w = np.clip(d / self.p.in_place_r_m, 0.0, 1.0)
        h = np.where(d < blend, at_goal + u * w * (tdt - at_goal), face)
        # On the heading-aware lattice the costs-to-go count the turns still to make.
        h = np.where(info["in_lattice"] > 0.5, 0.0, h)
        return cost + self.p.c_heading * (h - face), info
