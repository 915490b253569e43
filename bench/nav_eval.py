"""Navigation evaluation: MPEPC + the graceful law through the simulator's worlds, in process and
in lockstep (deterministic, faster than real time).

Loop at the drive chain's rate (autochair.tune.lockstep.DT), as bench/control_eval.py: ChairModel
(sim/chair/model.py) → encoder counts → OdometryCore → ControlCore (50 Hz; MPEPC at its plan rate,
timed) → the velocity PID as [pid] configures it → joystick volts → ChairModel. The navigation
field is the world rasterised at 0.05 m (what a perfect map would hold); with `--map scans`, the
mapping service's grid grown from the simulated laser's scans as the chair drives, from what it
saw standing 1 s at the start, or for a case that starts where an earlier goal ended, on the way
there (DRIVEN) (bench/scan_map.py: what the live chair plans on; unseen cells are free, so a goal
in an unseen room is accepted; the references below stay on the exact map).
People are given to the planner from the world's ground truth (a perfect tracker: the stack has
none yet); in SIGHT_ONLY worlds only once the laser has seen them (not hidden by the walls).
`person_clearance_m`: the footprint's least distance to a person's disc. Metrics come
from the simulator's ground truth: footprint clearance against the exact world (people included)
every 0.05 s, collisions (any contact), the true final pose error, time and path length against the
shortest feasible path, comfort peaks from the odometry (as control_eval), the wall time of
each planning cycle and of the goal's acceptance (which builds the goal's lattice). Goals that
cannot be reached must be refused (< 1 s).

Time is compared with (`timing`):
- `ref_s` / `time_ratio` (the goal's measure, ≤ 1.5): the shortest feasible path driven at the
  comfort limits, forward only (bench/path_time.py). The path: fast marching at uniform speed on
  the same grid and pass bound (the axle ≥ half width + 2 cm from obstacles), descended from the
  start. Its bends are smoothed as much as the geometry allows (`reference`): each turn spread
  as a Gaussian of the largest σ (≤ 2 m) whose path keeps the axle at the pass bound near it, the
  turns in place at the start and end too (a chair may turn while it sets off), then spread to
  the curvature the shortest path itself has at most where it wraps an obstacle's corner
  (1 / pass bound) and eased over 0.1 m; of σ capped at 2, 1, 0.5 and 0.25 m the fastest is kept
  (more smoothing is not always faster). That path is timed: the turns in place left at its ends
  as jerk-limited S-curves, the drive as the least-time speed profile with v ≤ 1.2 m/s,
  |a| ≤ 1.0 m/s², |jerk| ≤ 2.0 m/s³ and ω = v·κ within |ω| ≤ 0.9 rad/s, |ω̇| ≤ 2.8 rad/s²,
  |ω jerk| ≤ 7.7 rad/s³ (ControlConfig). It is the time of one good path, not a bound: a
  controller that swings wider round a corner or blends its turns differently can beat it.
- `bound_trapezoid_s` / `time_ratio_trapezoid` (the measure before session 17): max(trapezoid
  over the path's length at v_max, a_max; trapezoid over |goal yaw − start yaw| at ω_max, ω̇_max),
  which ignores the jerk limit, the turns onto and off the path and the curvature's limit on v.
- `time_ratio_blind` (`--monitor` only; shown beside the goal's measure, not instead of it): the
  same reference with |ω| also within the monitor's standing bound, the unseen footprint's swing
  (blind_speed_mps / its radius: 0.35 rad/s for the default chair), which holds on every turn
  whatever the obstacles: what the time is over it is not that fixed cap's.
- `min_time_s`: the least time without obstacles (bench/min_time.py, forward only, all comfort
  limits), read from its cache (`--min-time` solves what is missing, ~30 s a case): a lower
  bound the reference should not undercut (`cases_ref_under_min_time`; it is a local optimum,
  an upper bound on the true least time, and `ok` false where SLSQP did not converge).

Clearance is compared with what the case allows (bench/clearance_bound.py): `clearance_bound_m`,
no motion's minimum clearance can beat it (the start's and the goal's own, and the room along the
way); `clearance_lattice_m`, a forward-only lattice path's (capped at LATTICE_CAP_M: what is
shown to be attainable). The goal's attainable form: `cases_clearance_below_attainable` counts
the cases under min(the goal's 0.05 / 0.2 m, the bound).

    .venv/bin/python -m bench.nav_eval [--quick] [--only SUBSTRING]
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import math
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from autochair.control.core import ARRIVED, ControlConfig, ControlCore, OdomSample
from autochair.geometry import compose
from autochair.geometry import wrap_angle as wrap
from autochair.nav import planner
from autochair.nav.field import Footprint, GridMap, NavField, place
from autochair.nav.mpepc import MpepcParams, Person
from autochair.nav.planner import PlanRequest, PlanResult, compute, warm
from autochair.sim.chair.model import ChairModel
from autochair.sim.lidar.scanner import UrgParams
from autochair.sim.world import DEFAULT_WORLD, World, load_world
from autochair.tune.lockstep import DT, Rig  # DT: the drive chain's rate
from bench.clearance_bound import Room, lattice_attainable
from bench.control_eval import Planning, deriv, make_pid, smooth, trapezoid_time
from bench.min_time import Limits, cached, lookup
from bench.path_time import fit, path_time
from bench.people import visible
from bench.safety_rig import SafetyRig
from bench.scan_map import ScanMap

SETTLE_S = 1.5
TIMEOUT_S = 90.0
TRUTH_EVERY = max(1, round(0.05 / DT))  # ground-truth clearance every 0.05 s
WORLDS = DEFAULT_WORLD.parent
RESULTS = Path(__file__).parent / "results" / "nav_eval.json"
RESULTS_MONITOR = RESULTS.with_name("nav_eval_monitor.json")  # --monitor: the live stack's case
D = math.radians

Pose = tuple[float, float, float]
F64 = np.ndarray[Any, np.dtype[np.float64]]
# Smoothing of the shortest path's bends (σ, m), largest first: the largest whose path keeps the
# axle at the pass bound (0 = the grid's path, its bends only spread to the curvature bound).
SMOOTH_M = (2.0, 1.5, 1.0, 0.7, 0.5, 0.4, 0.3, 0.2, 0.15, 0.1, 0.05, 0.0)
SMOOTH_CAP_M = (2.0, 1.0, 0.5, 0.25)  # ... each the most of SMOOTH_M tried, the fastest kept
LATTICE_CAP_M = 0.3  # the lattice's clearance is searched up to this (the goal asks 0.2)
# The chair's true speed is reported where its footprint is within this of an obstacle
# (`v_tight_mps`: through a door's frame, past a jamb; H67)
TIGHT_M = 0.15
# (name, world file, start, goal, doorway: the clearance goal is 0.05 m instead of 0.2 m)
CASES: list[tuple[str, str, Pose, Pose, bool]] = [
    ("hallway: into office A", "hallway", (0, 0, 0), (4.5, 3.0, D(90)), True),
    ("hallway: office A, far corner", "hallway", (0, 0, 0), (5.5, 3.5, D(180)), True),
    ("hallway: into office B", "hallway", (0, 0, 0), (12.4, 2.5, D(90)), True),
    ("hallway: office B, at the desk", "hallway", (0, 0, 0), (12.0, 2.6, 0), True),
    ("hallway: into the store room", "hallway", (0, 0, 0), (8.5, -2.3, D(-90)), True),
    ("hallway: to the dead end", "hallway", (0, 0, 0), (20.9, 0.5, 0), False),
    ("hallway: past the bench", "hallway", (0, 0, 0), (19.5, 0.4, 0), False),
    ("hallway: recessed door", "hallway", (0, 0, 0), (16.5, -0.5, 0), False),
    ("hallway: 6 m past the bin", "hallway", (0, 0, 0), (6.0, 0.3, 0), False),
    ("hallway: turn around", "hallway", (0, 0, 0), (0.0, 0.0, D(180)), False),
    ("hallway: README example 3 0 90", "hallway", (0, 0, 0), (3.0, 0.0, D(90)), False),
    ("hallway: back to the start", "hallway", (10, 0, 0), (1.0, 0.0, D(180)), False),
    ("hallway: office A to office B", "hallway", (4.5, 3.0, D(-90)), (12.4, 2.5, D(90)), True),
    # (where the chair arrives in office A: facing in, it must turn round past the door leaf)
    ("hallway: office A (facing in) to office B", "hallway", (4.5, 3.0, D(90)),
     (12.4, 2.5, D(90)), True),
    ("hallway: store room to dead end", "hallway", (8.5, -2.3, D(90)), (20.9, 0.5, 0), True),
    ("L: past the cabinet", "l_corridor", (0, 0, 0), (6.0, 0.0, 0), False),
    ("L: into the corner", "l_corridor", (0, 0, 0), (8.0, 0.0, D(90)), False),
    ("L: round the corner", "l_corridor", (0, 0, 0), (8.0, 4.0, D(90)), False),
    ("L: to the end", "l_corridor", (0, 0, 0), (8.0, 7.5, D(90)), False),
    ("L: back from the end", "l_corridor", (8.0, 7.5, D(-90)), (0.5, 0.0, D(180)), False),
    ("door: through to room B", "doorway", (0, 0, 0), (6.5, 0.0, 0), True),
    ("door: room B corner", "doorway", (0, 0, 0), (7.5, 1.0, 0), True),
    ("door: back to room A", "doorway", (6.5, 0.0, D(180)), (1.0, 0.0, D(180)), True),
    ("door: into room B facing down", "doorway", (0.5, -1.0, D(90)), (6.0, -0.8, D(-90)),
     True),
    ("clutter: far side", "cluttered", (0, 0, 0), (5.8, 0.0, 0), False),
    ("clutter: behind the cabinet", "cluttered", (0, 0, 0), (5.9, 2.0, 0), False),
    ("clutter: behind the table", "cluttered", (0, 0, 0), (1.0, 2.0, D(180)), False),
    ("clutter: far corner", "cluttered", (0, 0, 0), (5.9, -2.3, 0), False),
    ("person: down the corridor", "crossing", (0, 0, 0), (10.0, 0.0, 0), False),
    ("person: back", "crossing", (10.0, 0.0, D(180)), (0.5, 0.0, D(180)), False),
    ("person: to the side", "crossing", (0, 0, 0), (8.0, 0.8, 0), False),
    ("person: passing head-on", "passing", (0, 0, 0), (11.0, 0.5, 0), False),
    ("person: overtaken, then met", "passing", (2.0, 0.6, 0), (6.0, 0.6, 0), False),
    # H67: a person pacing out of room B across its door's far side, given to the planner only
    # where the laser sees them (SIGHT_ONLY); from afar (the door's line-up, its straight) and
    # from 1 m before the door (no line-up: MPEPC's own way through)
    ("door person: through to room B", "door_person", (0, 0, 0), (6.5, 0.0, 0), True),
    ("door person: from before the door", "door_person", (2.6, 1.0, 0), (6.5, 0.0, 0), True),
    # H82: the crossing world's person, given to the planner only once the laser has seen them
    # (as the tracker), met 6 s into their walk: they step out of the room above into the
    # corridor as the chair comes past its door
    ("person: stepping out of a side room", "crossing", (0, 0, 0), (8.0, 0.8, 0), False),
]
# Worlds whose people are given to the planner only once the laser has seen them (not hidden by
# the walls from where it stands: a tracker's view, not the world's ground truth): a person
# beside a door beyond it is unseen till they step out (H67).
SIGHT_ONLY = {"door_person"}
# Cases given their world's people only once seen, met this far (s) into their walks (H82)
STEPPING_OUT = {"person: stepping out of a side room": 6.0}
# With `--map scans`, cases that start where the chair arrived on an earlier goal: their map is
# the one grown on the way there (the laser's scans along these poses, bench/scan_map.py
# ScanMap.driven), not a look from the start alone, which sees little behind the chair.
DRIVEN: dict[str, list[Pose]] = {
    "hallway: office A (facing in) to office B": [(0, 0, 0), (4.5, 0.0, 0), (4.5, 3.0, D(90))],
}
# Goals that must be refused at once: (name, world, start, goal).
REFUSED: list[tuple[str, str, Pose, Pose]] = [
    ("README's old example (front in the wall)", "hallway", (0, 0, 0), (3.0, 1.0, D(90))),
    ("inside the pillar", "hallway", (0, 0, 0), (20.0, -0.6, 0)),
    ("outside the building", "hallway", (0, 0, 0), (10.0, 5.0, 0)),
    ("behind the L's walls", "l_corridor", (0, 0, 0), (3.0, 5.0, 0)),
    ("beside the bench, too close", "hallway", (0, 0, 0), (18.5, 0.6, 0)),
    ("5 cm from office B's desk (tolerance 5 cm)", "hallway", (0, 0, 0), (12.5, 2.6, D(90))),
    # No forward way in with 2 cm to spare (nav/planner.py REACH_CLEAR_M; nav/lattice.py): the
    # chair fits at the pose but could only back into it (session 6: were goals that ended
    # blocked next to them, 30–50° off).
    ("behind the pillar, facing on (no forward way in)", "hallway", (0, 0, 0),
     (20.8, -0.8, 0)),
    ("past the plant, facing on (no forward way in)", "cluttered", (0, 0, 0), (3.0, -2.2, 0)),
]


def build(world_name: str, fp: Footprint) -> tuple[World, NavField]:
    world = load_world(WORLDS / f"{world_name}.world")
    gm = GridMap.from_shapes(world.segments, world.circles, frame_id="map")
    return world, NavField(gm, fp)


@functools.lru_cache(maxsize=2)  # (metrics and timing each ask for a case's: one solve)
def shortest_path(fld: NavField, start: Pose, goal: Pose) -> tuple[float, F64 | None]:
    """Length of the shortest path the axle can take (uniform speed, the same pass bound), and
    that path: (N, 2) points from the start to the goal (None if there is none; read-only)."""
    uniform = NavField(fld.map, fld.footprint, slow_factor=1.0)
    ctg = uniform.cost_to_go(goal[0], goal[1])
    length = math.inf if ctg is None else uniform.start_cost(ctg, start[0], start[1])
    if ctg is None or not math.isfinite(length):
        return length, None
    # The descent ends in the goal's cell, up to half a cell off the goal, then jumps to it:
    # that last step dropped, the path is sheared onto the goal (a kink of up to ~20° gone).
    xy = uniform.descent_path(ctg, start[0], start[1])[:-1]
    if len(xy) < 2:
        path = np.array([start[:2], goal[:2]], dtype=float)
    else:
        along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
        path = xy + (along / along[-1])[:, None] * (np.array(goal[:2]) - xy[-1])
    path.setflags(write=False)
    return length, path


def reference(fld: NavField, xy: F64 | None, start: Pose, goal: Pose, lim: Limits
              ) -> dict[str, Any]:
    """The time to drive the shortest path `xy` at the comfort limits (see the module doc)."""
    if xy is None:
        return {"time_s": math.inf}
    floor = min(fld.pass_m, float(fld.clearance_at(xy).min()))
    best: dict[str, Any] = {"time_s": math.inf}
    for cap in SMOOTH_CAP_M:  # the fastest of these (more smoothing is not always faster)
        turns, path, sigma = fit(xy, start[2], goal[2], 1.0 / fld.pass_m,
                                 tuple(x for x in SMOOTH_M if x <= cap),
                                 lambda p: fld.clearance_at(p) - floor)
        r = path_time(path, start[2], goal[2], lim, turns)
        if r["time_s"] < best["time_s"]:
            best = {"time_s": r["time_s"], "smooth_m": [float(sigma.min()), float(sigma.max())],
                    "drive_s": round(r["drive_s"], 2),
                    "turns_deg": [round(math.degrees(r["turn_start_rad"])),
                                  round(math.degrees(r["turn_end_rad"]))]}
    return best


def truth_clearance(world: World, fp: Footprint, outline: Any, x: float, y: float, yaw: float,
                    t: float) -> float:
    """Least distance of the footprint's outline to the world's shapes; −1 where the footprint
    overlaps one (the distance to a wall is unsigned: a chair driven 0.19 m through the end wall
    of the cluttered room read 0.003 m, no contact)."""
    pts = place(outline, x, y, yaw)
    w = world.at(t)
    return -1.0 if overlaps(w, fp, x, y, yaw) else float(w.distance_to(pts).min())


def overlaps(w: World, fp: Footprint, x: float, y: float, yaw: float) -> bool:
    """Whether the chair's rectangle at (x, y, yaw) overlaps any of `w`'s segments (clipped
    to it, Liang-Barsky) or discs (the nearest point of the rectangle within the radius)."""
    c, s = math.cos(yaw), math.sin(yaw)
    lo = np.array([-fp.rear_m, -fp.half_width_m])
    hi = np.array([fp.front_m, fp.half_width_m])

    def body(p: F64) -> F64:  # world (..., 2) → the chair's frame (along, left)
        dx, dy = p[..., 0] - x, p[..., 1] - y
        return np.stack([c * dx + s * dy, -s * dx + c * dy], -1)

    if len(w.segments):
        a, b = body(w.segments[:, :2]), body(w.segments[:, 2:])
        d = b - a
        t0, t1 = np.zeros(len(a)), np.ones(len(a))
        for k in range(2):
            for p, q in ((-d[:, k], a[:, k] - lo[k]), (d[:, k], hi[k] - a[:, k])):
                par = np.abs(p) < 1e-12
                t1 = np.where(par & (q < 0.0), -1.0, t1)  # parallel, outside this slab
                r = q / np.where(par, 1.0, p)
                t0 = np.where(~par & (p < 0.0), np.maximum(t0, r), t0)
                t1 = np.where(~par & (p > 0.0), np.minimum(t1, r), t1)
        if bool((t0 <= t1).any()):
            return True
    if len(w.circles):
        m = body(w.circles[:, :2])
        near = np.clip(m, lo, hi)
        if bool((np.hypot(*(m - near).T) < w.circles[:, 2]).any()):
            return True
    return False


def people_at(world: World, t: float, laser: Pose | None = None,
              seen: set[int] | None = None) -> list[Person]:
    """The world's people at t; with `laser` (its world pose) only those it has seen (in its
    field of view and range, not hidden by the walls: bench/people.py `visible`), from the
    first time on (`seen`, kept: a tracker holds a track out of view, as behind the chair)."""
    state = world.people_state(t)
    if laser is not None and seen is not None:
        ends = UrgParams().step_angles()
        fov = max(abs(float(ends[0])), abs(float(ends[-1])))
        seen.update(i for i, p in enumerate(state)
                    if i not in seen and visible(world, p, laser, fov, UrgParams().dmax_mm / 1e3))
        state = state[sorted(seen)]
    return [Person(float(x), float(y), float(vx), float(vy), float(r))
            for x, y, vx, vy, r in state]


def person_clearance(world: World, outline: Any, x: float, y: float, yaw: float,
                     t: float) -> float:
    """Least distance of the footprint's outline to the people's discs (inf: no one)."""
    state = world.people_state(t)
    if not len(state):
        return math.inf
    pts = place(outline, x, y, yaw)
    return float((np.hypot(pts[:, None, 0] - state[None, :, 0], pts[:, None, 1]
                           - state[None, :, 1]) - state[None, :, 4]).min())


def run_case(world: World, fld: NavField, start: Pose, goal: Pose, cfg: ControlConfig,
             fp: Footprint, params: MpepcParams | None = None, plan_delay_s: float = 0.0,
             scans: ScanMap | None = None, driven: list[Pose] | None = None,
             monitor: SafetyRig | None = None,
             on_tick: Callable[[float, ControlCore, ChairModel], None] | None = None,
             sight_only: bool = False) -> dict[str, Any]:
    """One goal in lockstep. `plan_delay_s`: each plan takes effect this long after it was
    asked for (the node plans on its own thread meanwhile, the core driving the previous
    plan; 0: at once, as the figures are made). `scans`: the chair plans on the map grown
    from its laser's scans (bench/scan_map.py), not on `fld` (the exact world, which the
    metrics' references keep); `driven`: that map grown along these poses first (DRIVEN);
    `monitor`: the safety monitor beside it, its limit required by the PID (bench/safety_rig);
    `on_tick(t, core, chair)`: called each tick once the chair has moved (the true chair);
    `sight_only`: people given to the planner only once the laser has seen them (SIGHT_ONLY)."""
    from autochair_msgs import GoalRequest, Pose2D

    rig = Rig(make_pid("tuned", monitor is not None), start=start)  # as the node configures it
    model = rig.chair
    core = ControlCore(cfg, footprint=fp)
    plan_ms: list[float] = []

    def timed(req: PlanRequest) -> PlanResult:
        t0 = time.perf_counter()
        res = compute(req, params)
        plan_ms.append((time.perf_counter() - t0) * 1e3)
        return res

    planning = Planning(core, plan_delay_s, timed)  # planned here, so each cycle is timed
    map_ms: list[float] = []  # the map's upkeep (the mapping service's and the map thread's)
    grid_key = b""
    if scans is None:
        core.on_field(fld)
    else:
        t0 = time.perf_counter()
        parked = scans.parked(0.0, start) if driven is None else scans.driven(0.0, driven)
        core.on_field(NavField(parked, fp))
        grid_key = parked.occupied.tobytes()
        map_ms.append((time.perf_counter() - t0) * 1e3)
    outline = fp.outline(0.02)
    mount = laser_mount()
    seen: set[int] = set()  # (sight_only: the people the laser has seen so far)
    ctrl_every = max(1, round(1.0 / (cfg.rate_hz * DT)))
    status_every = max(1, round(1.0 / (cfg.status_rate_hz * DT)))
    rows: list[tuple[float, ...]] = []
    clear: list[float] = []
    to_people: list[float] = []  # least distance to a person's disc (inf: no one)
    speeds: list[float] = []  # true |v| at each clearance sample
    where: list[tuple[float, float, float]] = []  # true pose at each clearance sample
    states: set[str] = set()
    t_end: float | None = None
    k = 0
    while True:
        t = k * DT
        st = rig.sense()
        core.on_odom(OdomSample(st.x, st.y, st.yaw, st.v, st.omega, t))
        if monitor is not None:
            monitor.tick(t, world, (model.x, model.y, model.yaw), (model.v, model.omega),
                         (st.v, st.omega), rig.core, core)
        if k == 0:
            t0 = time.perf_counter()
            reply = core.set_goal(GoalRequest(waypoints=[Pose2D(*goal)]), t)
            accept_ms = (time.perf_counter() - t0) * 1e3
            if not reply.ok:
                return {"state": "refused", "reason": reply.error, "arrived": False}
        out = None
        if scans is not None:
            t0 = time.perf_counter()
            gm = scans.step(t, (st.x, st.y, st.yaw), (model.x, model.y, model.yaw),
                            (model.v, model.omega))
            # As the control service's map thread: a new field where the obstacles changed,
            # warmed for the goal's next cycle (control/node.py refresh_field)
            if gm is not None and core.active and (key := gm.occupied.tobytes()) != grid_key:
                grid_key = key
                new = NavField(gm, fp)
                req = core.field_request(new, t)
                core.on_field(new, None if req is None else warm(req, params))
            map_ms.append((time.perf_counter() - t0) * 1e3)
        if k % ctrl_every == 0:
            core.people = people_at(world, t, compose((model.x, model.y, model.yaw), mount),
                                    seen) if sight_only else people_at(world, t)
            planning.tick(t)
            states.add(core.state)
            out = core.step(t)
        if k % status_every == 0:  # (the control node reads the PID's status at its 5 Hz)
            core.gates.pid_inhibit = rig.core.inhibit(t)
        rig.act(t, st.v, st.omega, out)
        if on_tick is not None:
            on_tick(t, core, model)
        rows.append((t, st.x, st.y, st.yaw, st.v, st.omega, st.distance,
                     model.x, model.y, model.yaw))
        if k % TRUTH_EVERY == 0:
            clear.append(truth_clearance(world, fp, outline, model.x, model.y, model.yaw, t))
            to_people.append(person_clearance(world, outline, model.x, model.y, model.yaw, t))
            speeds.append(abs(model.v))
            where.append((model.x, model.y, model.yaw))
        if t_end is None and not core.active:
            t_end = t
        # (recorded until the chair is at rest: a goal aborted at speed would otherwise end
        # the record mid-braking, and the smoothed derivatives spike at the cut, 7 m/s³)
        at_rest = abs(model.v) < 0.01 and abs(model.omega) < 0.01
        if (t_end is not None and t - t_end >= SETTLE_S and at_rest) or t >= TIMEOUT_S:
            break
        k += 1
    result = metrics(rows, clear, plan_ms, core, start, goal, t_end, fld, states)
    result["accept_ms"] = round(accept_ms, 1)
    if monitor is not None:
        result["monitor"] = {"scans": monitor.scans, "binding": monitor.binding,
                             "stops": len(monitor.stops), "first_stop": monitor.stops[:1],
                             "estops": monitor.estops, "pid_stop": rig.core.stop_reason}
    if scans is not None:
        result["map_s"] = round(sum(map_ms) / 1e3, 2)
        result["scans_mapped"] = scans.mapper.scans
    cl, sp = np.array(clear), np.array(speeds)
    starts = (cl <= 0.0) & np.concatenate([[True], cl[:-1] > 0.0])
    result["collisions_moving"] = int(np.sum(starts & (sp > 0.05)))  # the chair was driving
    i = int(np.argmin(cl))  # where the least clearance was (what limits it)
    result["min_clearance_at"] = (round(where[i][0], 2), round(where[i][1], 2),
                                  round(math.degrees(where[i][2])), round(float(sp[i]), 2))
    near = min(to_people, default=math.inf)
    result["person_clearance_m"] = round(near, 3) if math.isfinite(near) else None
    tight = cl < TIGHT_M
    result["v_tight_mps"] = round(float(sp[tight].max()), 3) if tight.any() else 0.0
    return result


def metrics(rows: list[tuple[float, ...]], clear: list[float], plan_ms: list[float],
            core: ControlCore, start: Pose, goal: Pose, t_end: float | None, fld: NavField,
            states: set[str]) -> dict[str, Any]:
    a = np.array(rows)
    n, h = round(0.1 / DT), round(0.05 / DT)
    v, w = smooth(a[:, 4], n), smooth(a[:, 5], n)
    acc = deriv(v, h)
    jerk = deriv(smooth(acc, n), h)
    wdot = deriv(w, h)
    i_end = len(a) - 1 if t_end is None else round(t_end / DT)
    true_path = float(np.hypot(np.diff(a[:i_end + 1, 7]), np.diff(a[:i_end + 1, 8])).sum())
    shortest, _ = shortest_path(fld, start, goal)
    t_goal = t_end if t_end is not None else TIMEOUT_S
    end = a[-1]
    cl = np.array(clear)
    return {
        "state": core.state, "reason": core.reason, "arrived": core.state == ARRIVED,
        "states_seen": sorted(states),
        "time_s": round(t_goal, 2),
        "path_m": round(true_path, 2), "shortest_m": round(shortest, 2),
        "path_ratio": round(true_path / shortest, 2) if shortest > 0.05 else None,
        "true_pos_error_m": round(math.hypot(goal[0] - end[7], goal[1] - end[8]), 4),
        "true_yaw_error_deg": round(math.degrees(abs(wrap(goal[2] - end[9]))), 2),
        "min_clearance_m": round(float(cl.min()), 3),
        "collisions": int(np.sum((cl[1:] <= 0.0) & (cl[:-1] > 0.0)) + int(cl[0] <= 0.0)),
        "peak_a_mps2": round(float(np.max(np.abs(acc))), 3),
        "peak_jerk_mps3": round(float(np.max(np.abs(jerk))), 3),
        "peak_omega_dot_radps2": round(float(np.max(np.abs(wdot))), 3),
        "plan_cycles": len(plan_ms),
        "plan_ms_median": round(statistics.median(plan_ms), 1) if plan_ms else None,
        "plan_ms_max": round(max(plan_ms), 1) if plan_ms else None,
        "plan_ms": plan_ms,
    }


def timing(fld: NavField, start: Pose, goal: Pose, cfg: ControlConfig, t_goal: float,
           solve_min_time: bool, omega_cap: float = math.inf) -> dict[str, Any]:
    """The time against the references: the shortest path driven at the comfort limits (the
    goal's measure), the old trapezoid bound, and the least time without obstacles; with a
    finite `omega_cap` (the monitor's standing |ω| bound), that path within it too."""
    shortest, xy = shortest_path(fld, start, goal)
    turn = abs(wrap(goal[2] - start[2]))
    bound = max(trapezoid_time(shortest, cfg.vmax_mps, cfg.a_max_mps2),
                trapezoid_time(turn, cfg.omega_max_radps, cfg.omega_acc_max_radps2))
    lim = Limits.of(cfg)
    ref = reference(fld, xy, start, goal, lim)
    s, g = tuple(map(float, start)), tuple(map(float, goal))  # (the cache's key: floats)
    least = (cached if solve_min_time else lookup)(s, g, lim)  # type: ignore[arg-type]
    return {"ref_s": round(ref["time_s"], 2),
            "time_ratio": round(t_goal / ref["time_s"], 2) if ref["time_s"] > 0 else None,
            "ref": {k: v for k, v in ref.items() if k != "time_s"},
            "bound_trapezoid_s": round(bound, 2),
            "time_ratio_trapezoid": round(t_goal / bound, 2) if bound > 0 else None,
            "min_time_s": None if least is None else round(least.time_s, 2),
            "min_time_ok": None if least is None else least.ok,
            **({} if omega_cap == math.inf else {"time_ratio_blind": round(t_goal / reference(
                fld, xy, start, goal, dataclasses.replace(lim, w_max=min(lim.w_max, omega_cap))
            )["time_s"], 2)})}


def clearance_goal(doorway: bool) -> float:
    return 0.05 if doorway else 0.2


def room_for(fld: NavField, room: Room, fp: Footprint, start: Pose, goal: Pose
             ) -> dict[str, Any]:
    """The best minimum clearance the case allows, and a lattice path's (see the module doc)."""
    ub = room.upper_bound(fp, start, goal)
    lat = lattice_attainable(fld, start, goal, min(ub["bound_m"], LATTICE_CAP_M))
    return {"clearance_bound_m": round(ub["bound_m"], 3),
            "clearance_bound_terms": {k: round(ub[k], 3) for k in ("start_m", "goal_m", "way_m")},
            "clearance_lattice_m": None if lat is None else round(lat, 3)}


def refusal(world_name: str, start: Pose, goal: Pose, cfg: ControlConfig,
            fp: Footprint, scans: int | None = None) -> dict[str, Any]:
    """`scans`: on the map the chair's laser made standing at the start (bench/scan_map.py,
    this rng seed), as a goal given then would be checked."""
    from autochair_msgs import GoalRequest, Pose2D

    world, fld = build(world_name, fp)
    if scans is not None:
        fld = NavField(ScanMap(world, laser_mount(), scans).parked(0.0, start), fp)
    core = ControlCore(cfg, footprint=fp)
    core.on_field(fld)
    core.on_odom(OdomSample(*start, 0.0, 0.0, 0.0))
    t0 = time.perf_counter()
    reply = core.set_goal(GoalRequest(waypoints=[Pose2D(*goal)]), 0.0)
    return {"refused": not reply.ok, "reason": reply.error,
            "seconds": round(time.perf_counter() - t0, 4)}


def laser_mount() -> Pose:
    from autochair.runtime.config import ChairGeometry

    return ChairGeometry().laser_mount


def summarise(runs: list[dict[str, Any]], refused: list[dict[str, Any]], wall: float
              ) -> dict[str, Any]:
    ok = [r for r in runs if r.get("time_s") is not None]
    door = [r for r in ok if r["doorway"]]
    other = [r for r in ok if not r["doorway"]]
    cycles = [ms for r in ok for ms in r["plan_ms"]]
    sim_s = sum(r["time_s"] + SETTLE_S for r in ok)
    return {
        "cases": len(runs), "arrived": sum(r["arrived"] for r in runs),
        "within_5cm_3deg": sum(r["arrived"] and r["true_pos_error_m"] <= 0.05
                               and r["true_yaw_error_deg"] <= 3.0 for r in ok),
        "collisions": sum(r["collisions"] for r in ok),
        "collisions_chair_moving": sum(r["collisions_moving"] for r in ok),
        "min_clearance_doorway_m": min((r["min_clearance_m"] for r in door), default=None),
        "min_clearance_elsewhere_m": min((r["min_clearance_m"] for r in other), default=None),
        "max_v_tight_doorway_mps": max((r["v_tight_mps"] for r in door), default=None),
        "max_v_tight_elsewhere_mps": max((r["v_tight_mps"] for r in other), default=None),
        "cases_clearance_below_goal": sum(r["min_clearance_m"] < clearance_goal(r["doorway"])
                                          for r in ok),
        # (the goal where the case allows it: no motion could do better than the bound)
        "cases_clearance_below_attainable": sum(
            r["min_clearance_m"] < min(clearance_goal(r["doorway"]), r["clearance_bound_m"])
            for r in ok),
        # (... under what a forward-only lattice path keeps: shown attainable)
        "cases_clearance_below_lattice": sum(
            r["clearance_lattice_m"] is not None and r["min_clearance_m"]
            < min(clearance_goal(r["doorway"]), r["clearance_lattice_m"]) for r in ok),
        "median_time_ratio": statistics.median(r["time_ratio"] for r in ok if r["arrived"])
        if any(r["arrived"] for r in ok) else None,
        **({"median_time_ratio_blind": round(statistics.median(
            r["time_ratio_blind"] for r in ok if r["arrived"]), 3)}
           if any(r["arrived"] and "time_ratio_blind" in r for r in ok) else {}),
        "cases_time_ratio_over_1_5": sum(r["arrived"] and r["time_ratio"] > 1.5 for r in ok),
        "median_time_ratio_trapezoid": statistics.median(
            r["time_ratio_trapezoid"] for r in ok if r["arrived"])
        if any(r["arrived"] for r in ok) else None,
        "cases_time_ratio_trapezoid_over_1_5": sum(
            r["arrived"] and r["time_ratio_trapezoid"] > 1.5 for r in ok),
        # the reference path's time is never under the least time without obstacles (by more
        # than the 1 % its piecewise-constant jerks can add: an in-place half turn 4.183 s
        # against the exact 4.170)
        "cases_ref_under_min_time": sum(bool(r["min_time_ok"])
                                        and r["ref_s"] < 0.99 * r["min_time_s"] for r in ok),
        "median_path_ratio": statistics.median(ratios) if (ratios := [
            r["path_ratio"] for r in ok if r["arrived"] and r["path_ratio"]]) else None,
        "max_peak_a_mps2": max(r["peak_a_mps2"] for r in ok),
        "max_peak_jerk_mps3": max(r["peak_jerk_mps3"] for r in ok),
        "max_peak_omega_dot_radps2": max(r["peak_omega_dot_radps2"] for r in ok),
        "plan_cycles": len(cycles),
        "plan_ms_median": round(statistics.median(cycles), 1),
        "plan_ms_p95": round(float(np.percentile(cycles, 95)), 1),
        "plan_ms_max": round(max(cycles), 1),
        # (the goal's acceptance: its route check, and its lattice, built there rather than in
        # the first planning cycle: nav/planner.py prepare)
        "accept_ms_median": round(statistics.median(r["accept_ms"] for r in ok), 1),
        "accept_ms_max": round(max(r["accept_ms"] for r in ok), 1),
        "refused_correctly": sum(r["refused"] for r in refused), "refusals": len(refused),
        "refusal_s_max": max(r["seconds"] for r in refused),
        "sim_time_s": round(sim_s, 1), "wall_time_s": round(wall, 1),
        "speedup_vs_real_time": round(sim_s / wall, 2),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="one case per world")
    ap.add_argument("--only", default="",
                    help="cases whose name contains this (several: separated by |)")
    ap.add_argument("--no-save", action="store_true", help="do not write the results file")
    ap.add_argument("--seed", type=int, default=MpepcParams().seed,
                    help="MPEPC's sampler seed (another seed: the results file is not written)")
    ap.add_argument("--no-lattice", action="store_true",
                    help="MPEPC without the heading-aware lattice (nav/lattice.py), to compare")
    ap.add_argument("--min-time", action="store_true",
                    help="solve the least time without obstacles where bench/min_time.py's "
                         "cache lacks it (~30 s a case; read from the cache in any case)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="override a [control] setting")
    ap.add_argument("--plan-delay-s", type=float, default=0.0,
                    help="each plan takes effect this long after it was asked for, as in the "
                         "node, where planning takes 50-100 ms (results file not written)")
    ap.add_argument("--map", choices=("exact", "scans"), default="exact",
                    help="what the chair plans on: the world rasterised (exact), or the "
                         "mapping service's grid grown from the simulated laser's scans as "
                         "it drives (bench/scan_map.py; results file not written)")
    ap.add_argument("--monitor", action="store_true",
                    help="the safety monitor in the loop, as the live stack runs it (its limit "
                         "required by the PID; results in nav_eval_monitor.json)")
    ap.add_argument("--scan-seed", type=int, default=0,
                    help="the simulated laser's noise seed (--map scans)")
    args = ap.parse_args(argv)
    from autochair.runtime.config import ChairGeometry, load_section

    cfg = load_section(ControlConfig, "control", None, args.set)
    chair = ChairGeometry()
    fp = Footprint(chair.front_m, chair.rear_m, chair.half_width_m)
    cases = [c for c in CASES if any(s in c[0] for s in args.only.split("|"))]
    if args.quick:
        seen: set[str] = set()
        cases = [c for c in cases if not (c[1] in seen or seen.add(c[1]))]  # type: ignore[func-returns-value]
    fields: dict[str, tuple[World, NavField]] = {}
    rooms: dict[str, Room] = {}
    runs: list[dict[str, Any]] = []
    ref_wall = 0.0
    t0 = time.perf_counter()
    omega_cap = SafetyRig().omega_cap if args.monitor else math.inf
    for name, wname, start, goal, doorway in cases:
        if wname not in fields:
            fields[wname] = build(wname, fp)
        world, fld = fields[wname]
        if name in STEPPING_OUT:
            world = dataclasses.replace(world, phase_s=STEPPING_OUT[name])
        planner._planners.clear()  # a fresh planner (and sampler) per case: order-independent
        planner._lattices.clear()
        scans = ScanMap(world, laser_mount(), args.scan_seed) if args.map == "scans" else None
        r = run_case(world, fld, start, goal, cfg, fp,
                     MpepcParams(seed=args.seed,
                                 heading_lattice=MpepcParams().heading_lattice
                                 and not args.no_lattice), args.plan_delay_s, scans,
                     DRIVEN.get(name), SafetyRig(args.scan_seed) if args.monitor else None,
                     sight_only=wname in SIGHT_ONLY or name in STEPPING_OUT)
        r.update(name=name, world=wname, start=start, goal=goal, doorway=doorway)
        runs.append(r)
        if r["state"] == "refused":
            print(f"{name:34s} REFUSED {r['reason']}", flush=True)
            continue
        t_ref = time.perf_counter()
        r.update(timing(fld, start, goal, cfg, r["time_s"], args.min_time, omega_cap))
        if wname not in rooms:
            rooms[wname] = Room(world)
        r.update(room_for(fld, rooms[wname], fp, start, goal))
        ref_wall += time.perf_counter() - t_ref  # (not the stack's: left out of wall_time_s)
        blind = f"(blind x{r['time_ratio_blind']}) " if "time_ratio_blind" in r else ""
        print(f"{name:34s} {r['state']:8s} t={r['time_s']:6.2f}s x{r['time_ratio']:<5} {blind}"
              f"(trapezoid x{r['time_ratio_trapezoid']}) "
              f"path x{r['path_ratio']} err={r['true_pos_error_m'] * 100:4.1f}cm/"
              f"{r['true_yaw_error_deg']:4.1f}° clr={r['min_clearance_m']:.3f}"
              f"/{r['clearance_bound_m']:.3f}/{r['clearance_lattice_m']} "
              f"hits={r['collisions']}/{r['collisions_moving']} vt={r['v_tight_mps']:.2f} "
              f"a={r['peak_a_mps2']:.2f} j={r['peak_jerk_mps3']:.2f} "
              f"ω̇={r['peak_omega_dot_radps2']:.2f} plan={r['plan_ms_median']}ms "
              f"accept={r['accept_ms']}ms "
              + (f"person={r['person_clearance_m']} " if r["person_clearance_m"] is not None
                 else "")
              + (f"map={r['map_s']}s/{r['scans_mapped']} " if scans else "")
              + (f"monitor={r['monitor']} " if args.monitor else "")
              + f"{r['reason']}", flush=True)
    wall = time.perf_counter() - t0 - ref_wall
    refused = []
    for name, wname, start, goal in ([] if args.only or args.quick else REFUSED):
        rr = refusal(wname, start, goal, cfg, fp,
                     args.scan_seed if args.map == "scans" else None)
        rr.update(name=name, world=wname, start=start, goal=goal)
        refused.append(rr)
        print(f"refuse {name:40s} {rr['refused']} {rr['seconds'] * 1e3:.0f} ms: {rr['reason']}")
    ok_runs = [r for r in runs if r["state"] != "refused"]
    summary = summarise(ok_runs, refused or [{"refused": True, "seconds": 0.0}], wall) \
        if ok_runs else {}
    summary["refused_reachable"] = len(runs) - len(ok_runs)
    summary["seed"] = args.seed
    if args.monitor:
        summary["monitor_cases_stopped"] = sum(r["monitor"]["stops"] > 0 for r in ok_runs)
        summary["monitor_estops"] = sum(r["monitor"]["estops"] for r in ok_runs)
        summary["monitor_safety_stopped"] = sum("safety" in r["monitor"]["pid_stop"]
                                                for r in ok_runs)
    if args.map == "scans":
        summary["map"] = f"scans (seed {args.scan_seed})"
        summary["map_s"] = round(sum(r["map_s"] for r in ok_runs), 1)
    print(json.dumps(summary, indent=1))
    summary["heading_lattice"] = MpepcParams().heading_lattice and not args.no_lattice
    if not (args.only or args.quick or args.no_save or args.no_lattice or args.plan_delay_s
            or args.seed != MpepcParams().seed or args.map != "exact"):
        out = RESULTS_MONITOR if args.monitor else RESULTS
        out.parent.mkdir(parents=True, exist_ok=True)
        for r in runs:
            r.pop("plan_ms", None)
        out.write_text(json.dumps({"config": {f: getattr(cfg, f)
                                              for f in cfg.__struct_fields__},
                                   "summary": summary, "runs": runs,
                                   "refusals": refused}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
