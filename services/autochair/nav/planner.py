"""One MPEPC planning cycle as a pure function of a snapshot, so the control node can run it
outside its lock (it takes tens of ms) while the 50 Hz law keeps running. PURE.

The goal manager (control/core.py) takes a `PlanRequest` under its lock, `compute` runs
without it, and the core applies the `PlanResult` if the goal is still the same.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from dataclasses import field as dc_field

import numpy as np

from autochair.safety.core import SafetyTuning

from . import lattice
from .field import F64, CostToGo, Footprint, GridMap, NavField
from .lattice import HeadingField
from .mpepc import Chain, LawParams, Mpepc, MpepcParams, Person, Plan


@dataclass(frozen=True)
class PlanRequest:
    goal_id: int
    index: int  # waypoint planned to
    pose: tuple[float, float, float]
    v: float
    omega: float
    goal: tuple[float, float, float]
    field: NavField
    ctg: CostToGo | None  # None: (re)compute from `field`
    previous: tuple[float, float, float, float] | None  # last target (x, y, yaw) + vmax
    law: LawParams  # ControlConfig.law: the limits the core really runs with
    people: list[Person] = dc_field(default_factory=list)
    rates: tuple[float, float] = (0.0, 0.0)  # the limiter's dv/dt, dω/dt (its S-curve state)
    final: bool = True  # `goal` is the last waypoint (approached on the braking curve)
    straight: bool = False  # the core drives a straight stage onto `previous` (Mpepc.stage_plan)
    # the core turned (or turns) in place as a stage whose straight lands here (Plan.then)
    then: tuple[float, float] | None = None
    given_up: GridMap | None = None  # cells given up for this waypoint (PlanResult.given_up)
    approaching: bool = False  # the core is on its own final approach (ControlCore.final)
    # the core's drive chain (its pose predictor's), through which the committed sweeps are
    # checked (Mpepc.chain_sweep); None: as the rollout drives them from `pose`
    chain: Chain | None = None
    straight_final: bool = False  # the core drives its straight final (ControlCore.straight)
    turn_first: bool = False  # the turn under way (`then`) is Mpepc.turn_first's (Plan's)
    # The chair has just reached a door's line-up pose: the door is driven straight
    # (Mpepc.through_door's `lined`); the core brakes until a stage takes it through
    door: bool = False
    # Look for a door to line up at on the way to `goal` (PlanResult.lineup): the map has
    # changed since the goal's route was checked (ControlCore: on the first leg only)
    seek_lineup: bool = False
    # The straight under way (`straight`) is a door's crossing (Plan.crossing): its rest is
    # rechecked at its own speed only
    crossing: bool = False
    # At a door's line-up, the laser's points of the last scans (odom, (M, 2)): the door's
    # straight from rest is ranked by them (Mpepc.through_door's `scan`, H79); None: by the map
    scan: F64 | None = None
    # The resting chair was read standing in a door (PlanResult.in_door) and has not moved
    # since (ControlCore): it still is, whatever the map says now (standing with the laser in
    # the door's plane, its beams along the wall's line cleared the jambs off the live map)
    in_door: bool = False


@dataclass(frozen=True)
class PlanResult:
    goal_id: int
    index: int
    field: NavField
    ctg: CostToGo | None
    plan: Plan | None
    error: str = ""  # no path: why
    blocked_by: str = ""  # why the plan makes no progress ("blocked by …"); "" if it does
    # Cells the chair cannot get to (give_up), kept out of the costs-to-go to this waypoint
    # (the core hands them back with every request; on a new map they are applied again).
    given_up: GridMap | None = None
    # The goal's lattice's cost-to-go at the request's pose (None: no lattice there): progress
    # as the chair manoeuvres (ControlCore._watch_progress)
    lattice_left: float | None = None
    # A pose to line up at before a door on the way (NavField.door_approaches), if asked
    # (PlanRequest.seek_lineup) and one is found
    lineup: tuple[float, float, float] | None = None
    # The chair at rest stands in a narrow passage (`in_door`)
    in_door: bool = False


_planners: dict[int, tuple[NavField, Mpepc]] = {}


def planner_for(fld: NavField, law: LawParams, params: MpepcParams | None = None) -> Mpepc:
    """One Mpepc per field (its candidate set is built once)."""
    key = id(fld)
    hit = _planners.get(key)
    if hit is None or hit[0] is not fld or hit[1].law != law:
        # The newest two: the control node's map thread makes a new field's (`warm`) while
        # a planning cycle may still be on the one before, which must not drop it.
        for k in list(_planners)[:-1]:  # (list(): one step, thread-safe)
            _planners.pop(k, None)
        hit = (fld, Mpepc(fld, law, params))
        _planners[key] = hit
    return hit[1]


_lattices: dict[tuple[int, tuple[float, float, float]],
                tuple[NavField, HeadingField | None]] = {}


def lattice_for(fld: NavField, goal: tuple[float, float, float], ctg: CostToGo,
                start: tuple[float, float, float] | None = None) -> HeadingField | None:
    """The heading-aware costs-to-go to `goal` (nav/lattice.py), built once per field and
    goal (~0.05–0.2 s; its window reaches towards where the chair is then); None where the
    goal region has no free state."""
    key = (id(fld), goal)
    hit = _lattices.get(key)
    if hit is None or hit[0] is not fld:
        if len(_lattices) >= 4:
            _lattices.clear()
        hit = (fld, lattice.build(fld, goal, ctg.phi, start=start))
        _lattices[key] = hit
    return hit[1]


def uses_lattice(fld: NavField, goal: tuple[float, float, float],
                 pose: tuple[float, float, float], final: bool, mp: MpepcParams) -> bool:
    """Whether a planning cycle from `pose` plans on the goal's lattice (`compute`): for the
    last waypoint only (line-up poses before doors are passed within 0.2 m / 0.3 rad, which
    the lattice's exact goal pose does not express; measured: door cases lost); only where
    there is something to manoeuvre round (in free space, no map yet, the 2-D field's descent
    is the way, and the free field's 0.1 m cells are too coarse for it); and not once at the
    goal, where only the final turn is left (see MpepcParams)."""
    return mp.heading_lattice and final and bool(fld.map.occupied.any()) and math.hypot(
        goal[0] - pose[0], goal[1] - pose[1]) >= mp.in_place_r_m


def prepare(fld: NavField, goal: tuple[float, float, float], ctg: CostToGo,
            start: tuple[float, float, float], params: MpepcParams | None = None) -> None:
    """Build the goal's lattice (`lattice_for`) when the goal is accepted, from `start` (where
    its first planning cycle on it begins), rather than in that cycle: 50-140 ms of a cycle
    budgeted at 100 ms, where acceptance has a second (nav_eval reports both)."""
    if uses_lattice(fld, goal, start, True, params or MpepcParams()):
        lattice_for(fld, goal, ctg, start)


def free_field(points: list[tuple[float, float]], footprint: Footprint,
               margin_m: float = 3.0, resolution_m: float = 0.1) -> NavField:
    """A field without obstacles around `points` (used before any map has arrived)."""
    xy = np.array(points, dtype=np.float64)
    lo, hi = xy.min(0) - margin_m, xy.max(0) + margin_m
    w, h = np.ceil((hi - lo) / resolution_m).astype(int)
    gm = GridMap(np.zeros((h, w), dtype=np.bool_), resolution_m, float(lo[0]), float(lo[1]),
                 "map")
    return NavField(gm, footprint)


# A goal pose is reachable when a forward-only way leads into it (nav/lattice.py: straight
# 5 cm steps, arcs and in-place turns over 16 headings) along which the footprint keeps this
# clear of obstacles. Less than MPEPC's own margin (`MpepcParams.contact_m`, 5 cm), so that
# the lattice's coarser motions do not refuse what the planner can do (measured: at 4 cm the
# cluttered room's far corner, which the chair reaches, had no way in).
REACH_CLEAR_M = 0.02


def path_error(fld: NavField, ctg: CostToGo | None, pose: tuple[float, float, float],
               goal: tuple[float, float, float], way_in: bool = True,
               monitor: SafetyTuning | None = None) -> str:
    """'' if the chair can get to `goal` from `pose`, else why not: no path for the axle
    (the 2-D field), or (`way_in`, the goal's own heading) no forward-only way into the goal
    pose. Autonomy may not reverse blind, so a pose the chair could only back into (behind a
    pillar, beside a plant: turning there sweeps the body into it) is refused at once rather
    than driven at and aborted. With the safety `monitor` (its tuning), a way in counts only
    if each of its forward moves ends where the monitor still lets the chair move forward
    (lattice.monitor_ahead): a goal every way into which ends in its forward stop margin
    was driven at and lost to a latched safety stop ~40 s later (behind the cluttered room's
    cabinet: its only ways in turn onto the goal's heading facing a wall within the margin)."""
    if ctg is None:
        return (f"no path: the goal ({goal[0]:.2f}, {goal[1]:.2f}) is closer than "
                f"{fld.pass_m:.2f} m to an obstacle or outside the map")
    if not math.isfinite(fld.start_cost(ctg, pose[0], pose[1])):
        return (f"no path from ({pose[0]:.2f}, {pose[1]:.2f}) to ({goal[0]:.2f}, "
                f"{goal[1]:.2f}) that the chair fits through")
    if not way_in:
        return ""

    def has_way(ahead: Footprint | None) -> bool:
        hf = lattice.build(fld, goal, None, lattice.LatticeParams(
            min_clear_m=REACH_CLEAR_M, tight_factor=0.0, goal_turn_clear_m=-math.inf,
            ahead=ahead), start=pose, costs=False)
        return hf is not None and hf.way_in(*pose)

    # (the monitor's strip only takes moves away: a way it lets through is a way, so a goal
    # taken needs one lattice; the plain one only says which refusal it is)
    if monitor is not None and has_way(lattice.monitor_ahead(fld, monitor)):
        return ""
    if not has_way(None):
        return (f"no forward way into ({goal[0]:.2f}, {goal[1]:.2f}, "
                f"{math.degrees(goal[2]):.0f}°): the chair cannot turn onto that heading "
                f"there with {REACH_CLEAR_M:.2f} m to spare, and it may not reverse blind")
    if monitor is not None:
        return (f"no forward way into ({goal[0]:.2f}, {goal[1]:.2f}, "
                f"{math.degrees(goal[2]):.0f}°) that the safety monitor lets through: "
                "each ends facing an obstacle within its forward stop margin")
    return ""


def blocker(fld: NavField, ctg: CostToGo, pose: tuple[float, float, float],
            people: list[Person]) -> str:
    """Why the chair cannot progress, naming only what is really there: the nearest person
    within 3 m, else the obstacle nearest to the chair or to the way down the navigation
    function (2 m ahead) if the body could touch it (within its turning reach + 0.2 m). With
    nothing that close, the planner found no motion that makes progress and says so."""
    x, y, _ = pose
    near = [(math.hypot(p.x_m - x, p.y_m - y), p) for p in people]
    near = [n for n in near if n[0] < 3.0]
    if near:
        d, p = min(near, key=lambda n: n[0])
        return f"blocked by a person at ({p.x_m:.2f}, {p.y_m:.2f}), {d:.1f} m away"
    pts, px, py = [(x, y)], x, y
    for _ in range(20):
        heading = ctg.descent_xy(fld.map, px, py)
        px, py = px + 0.1 * math.cos(heading), py + 0.1 * math.sin(heading)
        pts.append((px, py))
    arr = np.array(pts)
    clr = fld.clearance_at(arr)
    i = int(np.argmin(clr))
    ob = fld.nearest_obstacle(float(arr[i, 0]), float(arr[i, 1]))
    if ob is None or clr[i] > fld.footprint.reach_m + 0.2:
        return ("no motion found that makes progress (nothing within "
                f"{fld.footprint.reach_m + 0.2:.1f} m of the way)")
    return f"blocked by an obstacle at ({ob[0]:.2f}, {ob[1]:.2f})"


def give_up(fld: NavField, ctg: CostToGo, pose: tuple[float, float, float],
            goal: tuple[float, float, float], min_clear_m: float, ahead_m: float = 2.0
            ) -> tuple[CostToGo, GridMap] | None:
    """The costs-to-go without the cells round the chair that it cannot get to forward-only
    from where it stands (lattice.unreachable, its states clear by `min_clear_m`: MPEPC's
    contact margin), and those cells; None unless the way down the present costs-to-go (its
    first `ahead_m`) runs through them and a way is left. Unseen cells count as free (the
    chair must plan into what it has not seen), so at the closed end of a corridor the way
    may run back round an unseen wall end behind the chair, where it can neither turn nor
    reverse blind: it stood "blocked" there (the L corridor, README, navigation)."""
    closed = lattice.unreachable(fld, pose, params=lattice.LatticeParams(
        min_clear_m=min_clear_m, tight_factor=0.0))
    if closed is None:
        return None
    way = [fld.cell(float(x), float(y)) for x, y in fld.descent_path(ctg, pose[0], pose[1],
                                                                      max_m=ahead_m)]
    if not any(c is not None and closed[c] for c in way):
        return None
    ctg2 = fld.cost_to_go(goal[0], goal[1], closed=closed)
    if ctg2 is None or not math.isfinite(fld.start_cost(ctg2, pose[0], pose[1])):
        return None
    gm = fld.map
    return ctg2, GridMap(closed, gm.resolution_m, gm.origin_x_m, gm.origin_y_m, gm.frame_id)


def costs_to_go(fld: NavField, goal: tuple[float, float, float],
                pose: tuple[float, float, float], given_up: GridMap | None
                ) -> tuple[CostToGo | None, GridMap | None]:
    """The costs-to-go to `goal` without the cells given up, and those cells; on this map they
    may close the way from `pose`: then they are dropped."""
    if given_up is not None:
        ctg = fld.cost_to_go(goal[0], goal[1], closed=fld.cells_of(given_up))
        if ctg is not None and math.isfinite(fld.start_cost(ctg, pose[0], pose[1])):
            return ctg, given_up
    return fld.cost_to_go(goal[0], goal[1]), None


@dataclass(frozen=True)
class Warmed:
    """A new field's costs-to-go for `req` (its goal, waypoint and cells given up), made
    before its first planning cycle (`warm`)."""

    req: PlanRequest
    ctg: CostToGo
    given_up: GridMap | None


def warm(req: PlanRequest, params: MpepcParams | None = None) -> Warmed | None:
    """What the first `compute` on a new field (`req.field`) would build, built beforehand:
    its costs-to-go (returned), the goal's lattice and the planner (into their caches). The
    live map changes about once a second, and each new field made the next planning cycle
    rebuild them (hallway, quiet: ~20 + ~80 + 1 ms); two in three live cycles were such
    (docs/experiments/scripts/live_plan.py). The control node warms them on its map thread.
    None where there is no path (`compute` says why)."""
    ctg, given_up, error, _ = _setup(req, params or MpepcParams())
    if error or ctg is None:
        return None
    planner_for(req.field, req.law, params)
    return Warmed(req, ctg, given_up)


def _setup(req: PlanRequest, mp: MpepcParams
           ) -> tuple[CostToGo | None, GridMap | None, str, HeadingField | None]:
    """What a planning cycle plans on (`compute`; `warm` makes it beforehand): the costs-to-go
    and the cells given up, why there is no path ("" if there is one), the goal's lattice."""
    fld, ctg, given_up = req.field, req.ctg, req.given_up
    if ctg is None:
        ctg, given_up = costs_to_go(fld, req.goal, req.pose, given_up)
    error = path_error(fld, ctg, req.pose, req.goal, way_in=False)  # (checked at set_goal)
    if error or ctg is None:
        return ctg, given_up, error, None
    hf = lattice_for(fld, req.goal, ctg, req.pose) \
        if uses_lattice(fld, req.goal, req.pose, req.final, mp) else None
    return ctg, given_up, "", hf


def in_door(req: PlanRequest) -> bool:
    """The chair at rest stands in a door (NavField.in_passage), or was read so before and has
    not moved since (PlanRequest.in_door)."""
    return abs(req.v) < 0.01 and abs(req.omega) < 0.01 and (
        req.in_door or req.field.in_passage(req.pose))


def compute(req: PlanRequest, params: MpepcParams | None = None,
            blocked_progress_m: float = 0.1, blocked_gain: float = 0.1) -> PlanResult:
    """One planning cycle (_compute), with the goal's lattice's cost-to-go where the chair is,
    if the lattice is made: a stage that turns the chair away from the goal to get round a
    jamb adds to the 2-D distance left, not to this."""
    inside = in_door(req)
    res = _compute(req, params, blocked_progress_m, blocked_gain, inside)
    if inside:
        res = replace(res, in_door=True)
    if req.seek_lineup and res.ctg is not None and not res.error:
        # A door first seen on the live map (none was at the goal's route check: line-ups
        # are placed where its passage is narrow, and unseen cells count as free)
        doors = req.field.door_approaches(res.ctg, req.pose[0], req.pose[1])
        if doors:
            res = replace(res, lineup=doors[0])
    hit = _lattices.get((id(req.field), req.goal))
    if hit is None or hit[0] is not req.field or hit[1] is None:
        return res
    cost, ok = hit[1].at(np.array(req.pose[0]), np.array(req.pose[1]), np.array(req.pose[2]))
    return replace(res, lattice_left=float(cost)) if bool(ok) else res


def _compute(req: PlanRequest, params: MpepcParams | None,
             blocked_progress_m: float, blocked_gain: float, inside: bool) -> PlanResult:
    """`compute`'s cycle; `inside`: `in_door(req)`."""
    fld, mp = req.field, params or MpepcParams()
    ctg, given_up, error, hf = _setup(req, mp)
    if error or ctg is None:
        return PlanResult(req.goal_id, req.index, fld, ctg, None, error=error)
    mpc = planner_for(fld, req.law, params)
    if req.straight and req.previous is not None and abs(req.omega) < 0.01:
        # A straight stage under way (Mpepc.stage_plan): its rest, rechecked.
        on = mpc.stage_plan(req.pose, req.goal, ctg, hf, req.people, req.rates,
                            straight_to=req.previous[:2], v0=req.v, top=req.previous[3],
                            chain=req.chain, crossing=req.crossing)
        if on is not None:
            return PlanResult(req.goal_id, req.index, fld, ctg, on, given_up=given_up)
    carried: Plan | None = None
    if req.then is not None and req.previous is not None and abs(req.v) < 0.01:
        # A stage's turn under way: its rest; done (at rest): its straight; each rechecked.
        on = mpc.stage_plan(req.pose, req.goal, ctg, hf, req.people, req.rates,
                            straight_to=req.then,
                            turn_to=req.previous[2] if abs(req.omega) >= 0.01 else None,
                            chain=req.chain)
        if on is not None and not req.turn_first:
            return PlanResult(req.goal_id, req.index, fld, ctg, on, given_up=given_up)
        # (turn_first's turn: carried on only where the chair's own plan is stuck, below)
        carried = None if on is None else replace(on, turn_first=True)

    def stuck(plan: Plan) -> bool:
        if plan.min_clearance_m < mp.contact_m and not plan.escape:
            # Every motion is predicted to touch something: stand still (blocked) rather than
            # take the least bad contact. (An escape, from where the chair stands under its
            # margin, reads under it as it gets out.)
            return True
        # No progress, and nothing (a turn towards the path included) beats standing still; or
        # braking to rest is the best motion (the core brakes while blocked, as predicted).
        return not plan.is_goal and not plan.final_turn and (plan.vmax_mps <= 0.0 or (
            plan.progress_m < blocked_progress_m and plan.cost > plan.stop_cost - blocked_gain))

    def near_lattice() -> HeadingField | None:
        """The lattice for a stage, nearer than in_place_r_m too (where MPEPC does without):
        a chair blocked there, or whose goal was withheld for its turn, has a way on (office
        B's desk, 9.7 cm off at 66°: blocked till aborted; nav_eval seed 7). Not within
        `final_from` tolerances: there the landing is the stage, and at the goal a blocked
        final turn is refused rather than driven round the other way (tests/test_control.py)."""
        if hf is not None or not (mp.heading_lattice and req.final
                                  and bool(fld.map.occupied.any())) \
                or r_goal <= mp.final_from * req.law.tolerance_m:
            return hf
        return lattice_for(fld, req.goal, ctg, req.pose)

    at_rest = abs(req.v) < 0.01 and abs(req.omega) < 0.01

    def door_with_people() -> PlanResult | None:
        """At rest before or in a door, people about: into it, then across their way only
        when the whole crossing is clear of them as predicted; else stand, blocked (H75).
        Standing in a door the crossing rule does not take (no way through it ahead: on the
        live map a walker's trail can close its exit, and the way turns back), with someone
        about: stand. MPEPC's own plans crept such a chair 14 cm on into the lane of a person
        pacing beyond, and it stood there, blocked, till they walked into it (laser map,
        seed 7, "from before the door" with H73's held rule narrowed to turning commands)."""
        applies, cross = mpc.door_crossing(req.pose, req.goal, ctg, hf, req.people, req.rates,
                                           req.final, req.chain)
        if cross is not None:
            return PlanResult(req.goal_id, req.index, fld, ctg, cross, given_up=given_up)
        if applies or (req.people and inside and mpc.people_about(req.pose, req.people)):
            # (a stand: not the goal's approach, which the core would drive blocked or not;
            # a door's line-up kept: Plan.hold)
            return PlanResult(req.goal_id, req.index, fld, ctg, mpc.standing(req.pose),
                              blocked_by=blocker(fld, ctg, req.pose, req.people),
                              given_up=given_up)
        return None

    if req.door and mp.stages and abs(req.omega) < 0.01:
        # Just at a door's line-up: straight through it (moving: along its heading, if that
        # is clear; at rest: onto the clearest straight first)
        door = mpc.through_door(req.pose, req.goal, ctg, hf, req.people, req.rates, req.final,
                                turned=req.then is not None, lined=True, v0=req.v,
                                chain=req.chain, scan=req.scan)
        if door is not None:
            return PlanResult(req.goal_id, req.index, fld, ctg, door, given_up=given_up)
        if at_rest and (held := door_with_people()) is not None:
            return held
    elif at_rest and mp.stages and (held := door_with_people()) is not None:
        return held
    elif at_rest and mp.stages:
        # At rest near a door on the way: onto a straight through it, and through (a goal
        # begun in a room, facing in, at its door: Mpepc.through_door)
        door = mpc.through_door(req.pose, req.goal, ctg, hf, req.people, req.rates, req.final,
                                turned=req.then is not None and not req.turn_first,
                                chain=req.chain)
        if door is not None:
            return PlanResult(req.goal_id, req.index, fld, ctg, door, given_up=given_up)
    plan = mpc.plan(req.pose, req.v, req.omega, req.goal, ctg, req.people, req.previous,
                    req.rates, req.final, hf, chain=req.chain, on_line=req.straight_final)
    if carried is not None and (stuck(plan) or not (
            plan.is_goal or plan.final_turn or plan.progress_m >= blocked_progress_m)):
        # Mpepc.turn_first's turn under way, the half-turned chair's own plan blocked or
        # making no progress (turning back beats braking the turn): the turn carried on (else
        # MPEPC turned it back, a back-and-forth at rest before office A's door till "no
        # progress"); where its own plan moves on, that plan (MPEPC undid such turns
        # half-way to quicker ways through nav_eval's cluttered room).
        return PlanResult(req.goal_id, req.index, fld, ctg, carried, given_up=given_up)
    r_goal = math.hypot(req.goal[0] - req.pose[0], req.goal[1] - req.pose[1])
    if plan.goal_withheld and stuck(plan) and at_rest:
        # Withheld for the core's turn onto the goal's yaw (Mpepc.goal_turn_clearance), with
        # nothing else to do: a stage (its sweeps keep contact_m), else handed over as before
        # (its turn still checked by H40): the check must not make a goal unreachable.
        hf2 = near_lattice()
        for land in (True, False):  # (the stage onto the goal; the lattice's next stage)
            staged = mpc.stage_plan(req.pose, req.goal, ctg, hf2, req.people, req.rates,
                                    land=land, chain=req.chain) \
                if not land or req.law.tolerance_m < r_goal <= mp.final_move_m else None
            if staged is not None:
                return PlanResult(req.goal_id, req.index, fld, ctg, staged, given_up=given_up)
        plan = mpc.plan(req.pose, req.v, req.omega, req.goal, ctg, req.people, req.previous,
                        req.rates, req.final, hf, goal_turn=False, chain=req.chain)
    blocked = blocker(fld, ctg, req.pose, req.people) if stuck(plan) else ""
    if at_rest and req.final and not req.approaching and not plan.is_goal \
            and not plan.final_turn \
            and req.law.tolerance_m < r_goal <= mp.final_from * req.law.tolerance_m:
        # At rest just outside the tolerance, the goal not handed over: the stage onto it
        # (Mpepc.landing; the law only creeps there, and the chair stood 5–7.5 cm off).
        landed = mpc.stage_plan(req.pose, req.goal, ctg, hf, req.people, req.rates, land=True,
                                chain=req.chain)
        if landed is not None:
            return PlanResult(req.goal_id, req.index, fld, ctg, landed, given_up=given_up)
    if blocked and at_rest and (hf2 := near_lattice()) is not None:
        # At rest and blocked where the lattice has a way: its next stage, driven exactly.
        staged = mpc.stage_plan(req.pose, req.goal, ctg, hf2, req.people, req.rates,
                                chain=req.chain)
        if staged is not None:
            return PlanResult(req.goal_id, req.index, fld, ctg, staged, given_up=given_up)
    if blocked and at_rest:
        # At rest and blocked where the way runs through cells the chair cannot get to: the
        # way without them, kept for this waypoint (it never gets there from here on either).
        alt = give_up(fld, ctg, req.pose, req.goal, mp.contact_m)
        if alt is not None:
            plan2 = mpc.plan(req.pose, req.v, req.omega, req.goal, alt[0], req.people,
                             req.previous, req.rates, req.final, hf, chain=req.chain)
            if not stuck(plan2):
                return PlanResult(req.goal_id, req.index, fld, alt[0], plan2, given_up=alt[1])
    if blocked and at_rest:
        # ... else an in-place turn from which MPEPC's own plan moves on (Mpepc.turn_first)
        turn = mpc.turn_first(req.pose, req.goal, ctg, req.people, req.final, hf,
                              blocked_progress_m, blocked_gain)
        if turn is not None:
            return PlanResult(req.goal_id, req.index, fld, ctg, turn, given_up=given_up)
    if blocked and at_rest and hf is not None and mp.stages:
        # ... else the law towards targets just beyond the lattice's way (Mpepc.along_lattice)
        along = mpc.along_lattice(req.pose, req.goal, ctg, req.people, req.final, hf,
                                  blocked_progress_m, blocked_gain, req.rates, req.chain)
        if along is not None:
            return PlanResult(req.goal_id, req.index, fld, ctg, along, given_up=given_up)
    if blocked and at_rest and hf is not None:
        # ... else the lattice's next stage, beyond lattice_within_m too: before a narrow door
        # its 2-D costs-to-go are twice the way's length (slow near its frame), and a chair
        # stopped 2.4 m from office A's goal, where it could not turn in, read 4.7: blocked
        # till aborted though the lattice had a way (turn away, drive 0.3 m, turn onto the
        # door; nav_eval --map scans, walls a cell thick towards the chair)
        staged = mpc.stage_plan(req.pose, req.goal, ctg, hf, req.people, req.rates,
                                anywhere=True, chain=req.chain)
        if staged is not None:
            return PlanResult(req.goal_id, req.index, fld, ctg, staged, given_up=given_up)
    return PlanResult(req.goal_id, req.index, fld, ctg, plan, blocked_by=blocked,
                      given_up=given_up)
