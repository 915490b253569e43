"""The live map in lockstep: the mapping service's occupancy grid grown from the simulated
laser's scans while the chair drives (nav_eval `--map scans`).

Each piece is the live one, called as its service calls it:
- the scan: sim/lidar/scanner.py `ray_scan` from the chair's true pose and twist (the sweep
  skewed by the motion; people where they are now), the [lidar-sim] noise, mm quantisation
  and URG parameters, every period of the device (10 Hz);
- the ingest's conversion (lidar/core.py ScanDecoder: angles, beam timing, NaN for error
  codes);
- the mapping service's integration (mapping/core.py place_scan, then
  OccupancyMapper.integrate, the people's returns left out as the control service reports
  them, keys.PEOPLE): placed by odometry (keys.ODOM_SLOW, 50 Hz, interpolated at the
  scan's stamp and last beam), the [chair] laser mount, the MoveGate, the [mapping] grid and
  log odds;
- published once a second (`publish_period_s`) as the message the control service reads
  (OccupancyMapper.to_msg → GridMap.from_msg: its thresholds, unknown cells free).
The grid is laid in the world's frame (odometry started at the world's origin): the [mapping]
spec relative to odometry's origin, so its cells align with the world as they would live.
"""

from __future__ import annotations

import math

import numpy as np

from autochair.geometry import Pose
from autochair.lidar.core import LaserParams, ScanDecoder
from autochair.mapping.core import PEOPLE_MARGIN_M, OdomBuffer, place_scan
from autochair.mapping.node import MappingConfig
from autochair.nav.field import GridMap
from autochair.protocol import scip
from autochair.sim.lidar.node import LidarSimConfig
from autochair.sim.lidar.scanner import UrgParams, ray_scan
from autochair.sim.world import World
from autochair_msgs import Odometry

ODOM_PERIOD_S = 0.02  # keys.ODOM_SLOW, what the mapping service places scans by
PARKED_S = 1.0  # the chair stood this long at the start before the goal (one grid published)


def ns(t: float) -> int:
    return round(t * 1e9)


class ScanMap:
    """The mapping service fed by the simulated laser, stepped by the caller's clock."""

    def __init__(self, world: World, mount: Pose, seed: int = 0,
                 cfg: MappingConfig | None = None, lidar: LidarSimConfig | None = None
                 ) -> None:
        self.cfg = cfg = cfg or MappingConfig()
        lidar = lidar or LidarSimConfig(tcp_port=0)
        self.world, self.mount, self.noise_m = world, mount, lidar.noise_std_m
        self.urg = UrgParams(scan_rate_hz=lidar.scan_rate_hz)
        p = self.urg
        req = scip.ScanRequest("MD", p.amin, p.amax, 1, 0, 0)  # the ingest's default request
        self.dec = ScanDecoder(LaserParams.from_pp(p.pp()), req, "laser", lambda *_: None)
        self.period_s = 1.0 / p.scan_rate_hz
        self.rng = np.random.default_rng(seed)
        self.mapper = cfg.mapper()
        self.gate = cfg.gate()
        self.odom = OdomBuffer()
        self.next_odom_s = -math.inf
        self.next_scan_s = -math.inf
        self.next_publish_s = -math.inf
        self.scans = 0  # scans the laser swept (the mapped ones: self.mapper.scans)

    def parked(self, t0: float, pose: Pose) -> GridMap:
        """The chair standing at `pose` for PARKED_S before `t0`: the grid published at t0."""
        t = t0 - PARKED_S
        while t < t0 - 1e-9:
            self.step(t, pose, pose, (0.0, 0.0))
            t += 0.01
        grid = self.step(t0, pose, pose, (0.0, 0.0))
        assert grid is not None
        return grid

    def driven(self, t0: float, way: list[Pose], v_mps: float = 0.5, omega_radps: float = 0.9
               ) -> GridMap:
        """The chair driven along `way` before `t0` (from its first pose: an in-place turn onto
        each next point, a straight to it, at the end a turn onto the last pose's yaw, then
        PARKED_S standing there; odometry exact): the grid published at t0. As a goal given
        where the chair arrived, having mapped its way there (bench/nav_eval.py DRIVEN)."""
        poses: list[tuple[Pose, tuple[float, float]]] = []
        dt = 0.01

        def turn(x: float, y: float, a: float, b: float) -> float:
            e = math.remainder(b - a, 2 * math.pi)
            n = max(1, math.ceil(abs(e) / (omega_radps * dt)))
            poses.extend(((x, y, a + e * (i + 1) / n), (0.0, math.copysign(omega_radps, e)))
                         for i in range(n))
            return b

        x, y, yaw = way[0]
        for nx, ny, _ in way[1:]:
            yaw = turn(x, y, yaw, math.atan2(ny - y, nx - x))
            d = math.hypot(nx - x, ny - y)
            n = max(1, math.ceil(d / (v_mps * dt)))
            poses.extend(((x + (nx - x) * (i + 1) / n, y + (ny - y) * (i + 1) / n, yaw),
                          (v_mps, 0.0)) for i in range(n))
            x, y = nx, ny
        turn(x, y, yaw, way[-1][2])
        # (begun standing at the first pose, so that a grid is published at t0, once a period)
        period = self.cfg.publish_period_s
        pad = round(math.ceil((PARKED_S + dt * len(poses)) / period) * period / dt) \
            - round(PARKED_S / dt) - len(poses)
        poses[:0] = [(way[0], (0.0, 0.0))] * pad
        t = t0 - PARKED_S - dt * len(poses)
        for pose, twist in poses:
            self.step(t, pose, pose, twist)
            t += dt
        return self.parked(t0, way[-1])

    def step(self, t: float, odom: Pose, truth: Pose, twist: tuple[float, float]
             ) -> GridMap | None:
        """Time `t`: the odometry's pose `odom`, the chair's true pose and twist (v, ω); the
        scans due by now taken; the grid the control service reads if one is published now."""
        if t >= self.next_odom_s - 1e-9:  # (only the pose and stamp are read)
            self.odom.add(Odometry(stamp_ns=ns(t), x_m=odom[0], y_m=odom[1], yaw_rad=odom[2],
                                   v_mps=twist[0], omega_radps=twist[1]))
            self.next_odom_s = (t if math.isinf(self.next_odom_s) else self.next_odom_s) \
                + ODOM_PERIOD_S
        if t >= self.next_scan_s - 1e-9:  # a sweep ends now
            self.scan(t, truth, twist)
            self.next_scan_s = (t if math.isinf(self.next_scan_s) else self.next_scan_s) \
                + self.period_s
        if t >= self.next_publish_s - 1e-9:
            self.next_publish_s = (t if math.isinf(self.next_publish_s)
                                   else self.next_publish_s) + self.cfg.publish_period_s
            return GridMap.from_msg(self.mapper.to_msg(ns(t), self.cfg.frame_id))
        return None

    def scan(self, t_end: float, truth: Pose, twist: tuple[float, float]) -> None:
        """The sweep that ends at `t_end` (sim/lidar/node.py scan_fn), as the ingest stamps
        it, integrated as the mapping service does."""
        raw = ray_scan(self.world.at(t_end), self.urg, truth, self.mount, self.noise_m,
                       self.rng, twist)
        self.scans += 1
        dec = self.dec
        ranges = dec.ranges(raw)
        # the device stamps the start of its turn, a period before it ends
        stamp = ns(t_end - self.period_s) + dec.first_beam_ns
        placed = place_scan(self.odom, self.gate, stamp, ranges.size, dec.time_increment_s,
                            self.mount, ns(self.cfg.max_odom_dt_s))
        if not isinstance(placed, str):
            # (the people as the control service reports them, here where they truly are,
            # mid-sweep: a tracker's first reports come a few scans after it first sees them)
            state = self.world.people_state(t_end - self.period_s / 2)
            people = np.column_stack([state[:, :2], state[:, 4] + PEOPLE_MARGIN_M])
            self.mapper.integrate(ranges, dec.angle_min, dec.angle_inc, placed.laser,
                                  placed.beams, people)
