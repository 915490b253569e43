"""Control node: goals in (Zenoh queries), MPEPC-planned smooth (v, ω) out while a goal is active.

Publishes keys.CMD_VEL at `rate_hz` only while a goal is active and while braking after it (then
`stop_burst_s` of zeros); when idle it publishes nothing, so the CLI or teleop can drive.

MPEPC runs inside this service (nav/; the decision and its reasons are in README "Navigation"):
the goal's state machine, the pose prediction and the limiter it plans from are the core's, and
one process means no goal handshake between two. The planning cycle (tens of ms) runs on its
own thread outside the core's lock, so the 50 Hz law is never held up by it; the navigation
field is rebuilt on a third thread when the mapping service's grid changes, with what the goal's
next planning cycle needs on it (costs-to-go, lattice, planner: nav/planner.warm).
"""

from __future__ import annotations

import sys
import threading
import time
from collections import deque
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

from autochair.geometry import quaternion_yaw
from autochair.nav import gil
from autochair.nav.field import Footprint, GridMap, NavField, place
from autochair.nav.mpepc import Person
from autochair.nav.planner import PlanRequest, PlanResult, compute, warm
from autochair.people.core import ScanPeople, StaticMap
from autochair.runtime import ConfigError, Node, service_main
from autochair.runtime.config import load_section
from autochair.runtime.helper import HelperProcess
from autochair.safety.node import SafetyConfig
from autochair_msgs import (
    CommandOwner,
    EStopState,
    FrameTransform,
    GoalReply,
    GoalRequest,
    GoalStatus,
    LaserScan,
    LocalizedPose,
    NavPlan,
    OccupancyGrid,
    Odometry,
    People,
    SafetyLimit,
    VelocityCommand,
    keys,
)

from .core import (
    ABORTED,
    CANCELLED,
    ControlConfig,
    ControlCore,
    DriveGates,
    GoalCheck,
    OdomSample,
)

SLOW_LOOP_S = 5.0  # the plan and map loops' watchdog bound (Node.every slow_s)


class ControlNode:
    def __init__(self, node: Node, cfg: ControlConfig) -> None:
        chair = node.chair
        fp = Footprint(chair.front_m, chair.rear_m, chair.half_width_m)
        try:  # the odometry watchdog is one of the chain's thresholds, set in [stale] only
            self.core = ControlCore(cfg, odom_timeout_s=node.stale.odometry_s, footprint=fp,
                                    gates=DriveGates(node.stale.estop_s,
                                                     node.stale.safety_limit_s))
        except ValueError as e:
            raise ConfigError(f"[control] {e}") from None
        self.core.inline_planning = False  # planned on its own thread (plan_tick)
        # (the monitor's margins, as its service reads them from the same file: a goal is
        # checked for a way in the monitor lets through, H71)
        self.core.monitor_tuning = load_section(SafetyConfig, "safety", node.config_path)
        self._due: float | None = None  # the last tick's schedule (Node.due)
        self.node, self.cfg = node, cfg
        self.lock = threading.Lock()
        self.cmd_pub = node.publisher(keys.CMD_VEL)
        self.status_pub = node.publisher(keys.GOAL_STATUS)
        self.plan_pub = node.publisher(keys.NAV_PLAN)
        # When the current goal was accepted (Unix ns): its commands carry it as their stream
        # start, so the velocity PID obeys them only if the goal came after its last stop.
        self.stream_start_ns = 0
        self.announced = 0
        self.grid: OccupancyGrid | None = None  # newest map, not yet turned into a field
        self.grid_key = b""
        self.field_grid: OccupancyGrid | None = None  # the grid the field was last made for
        self.field_lock = threading.Lock()  # (the map thread and a goal request both make it)
        self.planned_field: NavField | None = None  # the field the last planning cycle was on
        # People for MPEPC, tracked in the scans (on the scan callback, its own lock).
        self.people = ScanPeople(chair.laser_mount)
        self.people_lock = threading.Lock()
        # Odometry for the tracker, taken in on the next scan: the odometry callback never
        # waits for a scan being tracked (deque appends and pops are thread-safe).
        self.people_odom: deque[Odometry] = deque(maxlen=500)
        self.people_pub = node.publisher(keys.PEOPLE)
        self.people_grid: OccupancyGrid | None = None  # the grid the tracker's map is of
        # The newest odometry, taken into the core when it next runs (tick, request, plan).
        # Kept off the core's lock: odometry waiting behind a long holder of the lock (a
        # goal's route check was one, 0.1-1.5 s on a loaded CPU) was taken for stale by the
        # tick that got the lock first (goals aborted at the start, a CI run in session 10).
        # Its time stays when it arrived: a silent odometry service is still stale.
        self.odom_in: OdomSample | None = None
        self._taken: OdomSample | None = None
        self.pid_status = node.latest(keys.PID_STATUS)
        self._pid_seen_ns = 0  # the newest PID status taken in (tick)

    @contextmanager
    def held(self) -> Iterator[None]:
        """The core, under its lock, with the newest odometry taken in."""
        with self.lock:
            o = self.odom_in
            if o is not self._taken and o is not None:
                self._taken = o
                self.core.on_odom(o)
            yield

    # --- inputs -----------------------------------------------------------------------------
    def on_odom(self, o: Odometry) -> None:
        age = (time.time_ns() - o.stamp_ns) / 1e9  # (clamped in the core's prediction)
        self.odom_in = OdomSample(o.x_m, o.y_m, o.yaw_rad, o.v_mps, o.omega_radps,
                                  time.monotonic(), max(age, 0.0))
        self.people_odom.append(o)
        self.node.health.count("odom")

    def on_scan(self, msg: LaserScan) -> None:
        with self.people_lock:
            while self.people_odom:
                self.people.on_odom(self.people_odom.popleft())
            found = self.people.on_scan(msg.stamp_ns, msg.ranges_m, msg.angle_min_rad,
                                        msg.angle_increment_rad, msg.range_min_m,
                                        msg.range_max_m, msg.time_increment_s)
        if found is None:
            self.node.health.count("scans_without_odometry")
            return
        with self.held():
            self.core.people = [Person(q.x_m, q.y_m, q.vx_mps, q.vy_mps, q.radius_m)
                                for q in found]
            if self.people.points is not None:  # (a door's straight is chosen by them, H79)
                self.core.on_scan(time.monotonic(), self.people.points)
        self.people_pub.put(People(stamp_ns=msg.stamp_ns, frame_id="odom", people=found))

    def on_estop(self, msg: EStopState) -> None:
        with self.held():
            self.core.on_estop(msg.latched, time.monotonic())

    def on_owner(self, msg: CommandOwner) -> None:
        with self.held():
            self.core.on_owner(msg.owner, time.monotonic())

    def on_limit(self, msg: SafetyLimit) -> None:
        with self.held():  # plan within the monitor's bounds instead of being clamped by the PID
            self.core.on_limit(msg.v_max_fwd_mps, msg.omega_max_radps, msg.reason,
                               time.monotonic())

    def on_monitor_alive(self, alive: bool) -> None:
        with self.held():
            self.core.gates.monitor_up = alive

    def on_tf(self, msg: FrameTransform) -> None:
        if msg.parent_frame_id != "map" or msg.child_frame_id != "odom":
            return
        t, r = msg.translation, msg.rotation
        with self.held():
            self.core.on_correction((t.x, t.y, quaternion_yaw(r.x, r.y, r.z, r.w)))

    def on_loc(self, msg: LocalizedPose) -> None:
        with self.held():
            self.core.on_loc_state(msg.state, time.monotonic())

    def on_grid(self, msg: OccupancyGrid) -> None:
        self.grid = msg  # (built on the map thread: never block a Zenoh callback)

    # --- loops ------------------------------------------------------------------------------
    def tick(self) -> None:
        core = self.core
        pid = self.pid_status()
        with self.held():
            if pid is not None and pid.active and pid.stamp_ns != self._pid_seen_ns:
                self._pid_seen_ns = pid.stamp_ns
                core.on_command_age(pid.command_age_s)
            # The plan steps by the loop's schedule, not by when its thread woke: that jitter
            # (8-35 ms apart, measured) taken for time made the plan's acceleration chatter
            # (±0.2 m/s², its jerk ±1.8 m/s³ tick to tick); the commands are a 50 Hz stream.
            # Freshness (stale odometry, timeouts) stays judged on the real clock.
            due = self.node.due.get("control")
            dt = None if due is None or self._due is None else due - self._due
            self._due = due
            out = core.step(time.monotonic(), dt)
            ended = not core.active and self.announced != core.goal_id
            if ended:
                self.announced = core.goal_id
        if ended and core.goal_id and core.state != CANCELLED:  # (cancel says so itself)
            why = f": {core.reason}" if core.reason else ""
            self.node.event("warning" if core.state == ABORTED else "info",
                            f"goal {core.goal_id} {core.state}{why}")
        if out is not None:
            self.cmd_pub.put(VelocityCommand(stamp_ns=time.time_ns(), v_mps=out[0],
                                             omega_radps=out[1], source="control",
                                             stream_start_ns=self.stream_start_ns))
            self.node.health.count("commands")

    def plan_tick(self) -> None:
        with self.held():
            req = self.core.plan_request(time.monotonic())
        if req is None:
            return
        new_field = req.field is not self.planned_field  # (NavPlan.new_field)
        self.planned_field = req.field
        if new_field and req.ctg is not None:  # (its costs-to-go made before: warm)
            self.node.health.count("new_fields_warm")
        t0 = time.perf_counter()
        res = compute(req)  # outside the lock: the 50 Hz loop goes on meanwhile
        ms = (time.perf_counter() - t0) * 1e3
        self.node.health.count("plans")
        if ms > 1000.0 / self.cfg.plan_rate_hz:
            self.node.health.count("plans_late")
        with self.held():
            self.core.on_plan(res, time.monotonic())
            state = self.core.state
        self.publish_plan(req, res, state, ms, new_field)

    def publish_plan(self, req: PlanRequest, res: PlanResult, state: str, ms: float,
                     new_field: bool) -> None:
        """The plan, the footprint and the people for the 3D view (keys.NAV_PLAN)."""
        p, fp = res.plan, self.core.footprint
        corners = np.array([[fp.front_m, fp.half_width_m], [fp.front_m, -fp.half_width_m],
                            [-fp.rear_m, -fp.half_width_m], [-fp.rear_m, fp.half_width_m]])
        outline = place(corners, *req.pose).reshape(-1)
        path = np.zeros((0, 3)) if p is None else p.path
        target = req.pose if p is None else p.target
        self.plan_pub.put(NavPlan(
            stamp_ns=time.time_ns(), frame_id=req.field.frame_id, goal_id=req.goal_id,
            state=state, target_x_m=target[0], target_y_m=target[1], target_yaw_rad=target[2],
            vmax_mps=0.0 if p is None else p.vmax_mps, path_x_m=path[:, 0].round(3).tolist(),
            path_y_m=path[:, 1].round(3).tolist(), path_yaw_rad=path[:, 2].round(3).tolist(),
            footprint_xy_m=outline.round(3).tolist(),
            people_xyr_m=[v for q in req.people for v in (q.x_m, q.y_m, q.radius_m)],
            cost=0.0 if p is None else round(p.cost, 4),
            progress_m=0.0 if p is None else round(p.progress_m, 3),
            survival=1.0 if p is None else round(p.survival, 3),
            min_clearance_m=0.0 if p is None else round(p.min_clearance_m, 3),
            plan_ms=round(ms, 2), new_field=new_field))

    def map_tick(self) -> None:
        """Take a new grid in: the people tracker's static map at once; the navigation field
        while a goal is active, else when one is asked for (`on_set`). A parked or driven
        chair's map changes every second and the field went unused without a goal (the
        control service's largest idle cost, ~1 % of a core: profiled)."""
        msg = self.grid
        if msg is None:
            return
        if msg is not self.people_grid:  # (ticks twice per grid published)
            self.people_grid = msg  # every new grid: what the tracker leaves to the map
            self.node.health.count("grids")
            with self.people_lock:
                old = self.people.tracker.static
            static = StaticMap.from_grid(msg, reuse=old)
            if static is not old:
                with self.people_lock:
                    self.people.tracker.static = static
        with self.held():
            active = self.core.active
        if active:
            self.refresh_field()

    def refresh_field(self, for_goal: bool = True) -> None:
        """Rebuild the navigation field if the newest grid's obstacles changed; `for_goal`:
        with what the current goal's next planning cycle needs on it (planner.warm)."""
        with self.field_lock:
            msg = self.grid
            if msg is None or msg is self.field_grid:
                return
            self.field_grid = msg
            # At the map's own resolution, as nav_eval plans: the field's clearance reads over
            # the truth near an obstacle's corner by up to ~2.3 cm on 5 cm cells but ~4.5 cm on
            # the 0.1 m cells it was coarsened to (measured, H47), most of MPEPC's 5 cm
            # contact margin. (Coarsened to bound the costs-to-go's cost while they stalled
            # the 50 Hz loop; they run in the helper process now, H46.)
            gm = GridMap.from_msg(msg)
            key = gm.occupied.tobytes() + repr((gm.resolution_m, gm.origin_x_m,
                                               gm.origin_y_m)).encode()
            if key == self.grid_key:
                return
            self.grid_key = key
            t0 = time.perf_counter()
            fld = NavField(gm, self.core.footprint)
            with self.held():
                req = self.core.field_request(fld, time.monotonic()) if for_goal else None
            warmed = None if req is None else warm(req)  # (without the lock, as compute)
            with self.held():
                self.core.on_field(fld, warmed)
            self.node.health.count("nav_fields")
            # (with nav_fields: the map thread's mean time per field)
            self.node.health.count("nav_field_ms", round((time.perf_counter() - t0) * 1e3))

    # --- requests and status ------------------------------------------------------------------
    def status_msg(self) -> GoalStatus:
        with self.held():
            s = self.core.status()
        return GoalStatus(stamp_ns=time.time_ns(), goal_id=s.goal_id, state=s.state,
                          waypoint_index=s.waypoint_index, waypoint_count=s.waypoint_count,
                          distance_left_m=round(s.distance_left_m, 4), eta_s=round(s.eta_s, 2),
                          reason=s.reason)

    def status_tick(self) -> None:
        pid = self.pid_status()  # (its newest, read here: no thread woken at its 100 Hz)
        with self.held():
            # What the PID says holds it (it stays so until a new stream): named if a goal
            # ends because the chair does not follow.
            self.core.gates.pid_inhibit = "" if pid is None else pid.inhibit
            why = self.core.why_not_ready(time.monotonic())
        # (`autochair status` shows it: why a goal would be refused now)
        self.node.health.detail = f"goals refused: {why}" if why else "ready for goals"
        self.status_pub.put(self.status_msg())

    def on_set(self, req: GoalRequest) -> GoalReply:
        self.refresh_field(for_goal=False)  # (not kept up while no goal was active)
        with self.held():
            check = self.core.check_goal(req, time.monotonic())
        if isinstance(check, GoalCheck):
            # The route check (costs-to-go, the forward lattice; and the goal's lattice for the
            # planner, planner.prepare: up to 1.5 s on a loaded CPU) runs without the lock, so
            # the 50 Hz loop and odometry go on meanwhile; the goal is taken only if its asker
            # is still waiting.
            routed = check.routed()
            late = self.node.too_late()
            with self.held():
                result = (GoalReply(ok=False, error=f"not acted on: {late}") if late
                          else self.core.accept_goal(routed, time.monotonic()))
                if result.ok:
                    self.stream_start_ns = time.time_ns()
        else:
            result = check
        if result.ok:
            last = req.waypoints[-1]
            self.node.event("info", f"goal {result.goal_id}: {len(req.waypoints)} waypoint(s) "
                                    f"to ({last.x_m:.2f}, {last.y_m:.2f}, {last.yaw_rad:.3f} rad)")
        else:
            self.node.health.count("rejected_goals")
            self.node.event("warning", f"goal rejected: {result.error}")
        return result

    def on_cancel(self, _: GoalRequest) -> GoalReply:
        with self.held():
            result = self.core.cancel(time.monotonic())
        if result.goal_id:
            self.node.event("info", f"goal {result.goal_id} cancelled")
        return result


def start(node: Node, cfg: ControlConfig) -> None:
    c = ControlNode(node, cfg)
    # The planner's searches hold the interpreter lock for up to 0.3 s (nav/gil.py): made in a
    # helper process, they no longer stall the command stream.
    helper = HelperProcess(("autochair.nav.lattice",),
                           on_restart=lambda: node.health.count("helper_restarts"))
    gil.install(helper)
    node.on_close(helper.close)
    node.on_close(lambda: gil.install(None))  # (run first: last registered)
    node.health.thresholds.update(odometry_s=node.stale.odometry_s, rate_hz=cfg.rate_hz)
    node.subscribe(keys.ODOM_SLOW, c.on_odom)  # 50 Hz: the law runs at 50 Hz too
    node.subscribe(keys.ESTOP_STATE, c.on_estop)
    node.subscribe(keys.CMD_OWNER, c.on_owner)
    node.subscribe(keys.SAFETY_LIMIT, c.on_limit)
    node.watch_alive("safety", c.on_monitor_alive)  # its limit is required while it runs
    node.subscribe(keys.MAP_GRID, c.on_grid)
    node.subscribe(keys.TF, c.on_tf)  # map → odom, for goals in map
    node.subscribe(keys.LOC_POSE, c.on_loc)
    node.subscribe(keys.SCAN, c.on_scan)  # people, for MPEPC
    node.serve(keys.GOAL_SET, c.on_set)
    node.serve(keys.GOAL_CANCEL, c.on_cancel)
    node.serve(keys.GOAL_GET, lambda _: c.status_msg())
    node.every(1.0 / cfg.rate_hz, c.tick, "control")
    # A blocked goal's planning cycle took up to 2.2 s under load, a field's build 1.8 s: past
    # the watchdog's 1.5 s the service was killed mid-goal (H58). Neither moves the chair: a
    # plan older than three periods is a stop (ControlCore._plan_stale), and a late field
    # leaves the plans on the map before it, the safety monitor on live scans meanwhile.
    node.every(0.5 / cfg.plan_rate_hz, c.plan_tick, "plan", slow_s=SLOW_LOOP_S)
    node.every(0.5, c.map_tick, "map", slow_s=SLOW_LOOP_S)
    node.every(1.0 / cfg.status_rate_hz, c.status_tick, "status")


def main(argv: list[str] | None = None) -> int:
    return service_main("control", ControlConfig, start, argv, __doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
