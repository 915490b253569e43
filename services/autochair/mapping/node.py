"""autochair-mapping: occupancy grid (keys.MAP_GRID) and point cloud (keys.MAP_CLOUD) from
scans (keys.SCAN) placed by odometry (keys.ODOM_SLOW, interpolated) and the chair→laser mount
of the [chair] section (`node.chair`). A chair→laser transform on keys.TF_STATIC that
disagrees with it is counted (`tf_mount_mismatch`) and reported, not followed: the mount is
defined once. Scans are integrated one per 10 cm or 0.1 rad driven, once a second parked
(`MoveGate`). The returns of the people the control service tracks (keys.PEOPLE) who have
walked (`Walkers`) are left out of the grid (`people_discs`): they are not the map's, and
pacing they left trails in it."""

from __future__ import annotations

import sys
import threading
import time
from typing import Annotated

import msgspec
import numpy as np

from autochair.geometry import Pose, quaternion_yaw
from autochair.runtime.node import Node, service_main
from autochair.safety.keepout import load_keepout, paint
from autochair_msgs import (
    FrameTransform,
    LaserScan,
    LocalizedPose,
    OccupancyGrid,
    People,
    keys,
)

from .core import (
    ODOM_RING,
    GridSpec,
    MoveGate,
    NoReturn,
    OccupancyMapper,
    OdomBuffer,
    VoxelCloud,
    Walkers,
    people_discs,
    place_scan,
    scan_points,
)

Positive = Annotated[float, msgspec.Meta(gt=0)]


class MappingConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    resolution_m: Positive = 0.05
    width_m: Positive = 30.0
    height_m: Positive = 20.0
    origin_x_m: float = -5.0  # odom position of the grid's (0, 0) corner
    origin_y_m: float = -10.0
    l_hit: float = 0.85  # log-odds added to a cell a beam ends in
    l_miss: float = -0.4  # log-odds added to a cell a beam passes through
    # Beams with no return clear free space this far (m; 0: not at all), bounded as
    # mapping/core.py NoReturn says (a dark or glancing obstacle gives none either; off: it
    # let the planner into contacts, measured there)
    no_return_m: Annotated[float, msgspec.Meta(ge=0)] = 0.0
    max_odom_dt_s: float = 0.25  # scan stamp to nearest odometry sample, else the scan is skipped
    require_odom: bool = True  # False: map scans at the origin when there is no odometry
    voxel_m: float = 0.05  # point-cloud voxel size
    max_points: int = 100_000
    publish_period_s: Positive = 1.0
    frame_id: str = "odom"  # REP-105: placed by odometry alone (localization maps in `map`)
    laser_frame: str = "laser"
    # Scans are integrated one per 10 cm or 0.1 rad driven, or once a second parked (MoveGate).
    still_period_s: Annotated[float, msgspec.Meta(ge=0)] = 1.0
    # Keep-out zones (a mask map, as [safety] keepout_map) painted into the published grid
    # while localization places them, so navigation plans round them and refuses goals in them.
    keepout_map: str = ""

    def mapper(self) -> OccupancyMapper:
        return OccupancyMapper(GridSpec(self.resolution_m, self.width_m, self.height_m,
                                        self.origin_x_m, self.origin_y_m),
                               self.l_hit, self.l_miss, no_return=NoReturn(self.no_return_m)
                               if self.no_return_m > 0 else None)

    def gate(self) -> MoveGate:
        return MoveGate(max_age_ns=int(self.still_period_s * 1e9))

    def __post_init__(self) -> None:
        if self.width_m * self.height_m / self.resolution_m**2 > 50e6:
            raise ValueError("grid over 50 M cells; coarsen resolution_m or shrink it")


class MappingService:
    """The thin glue: Zenoh callbacks queue scans, one worker thread does the ray updates."""

    def __init__(self, node: Node, cfg: MappingConfig) -> None:
        self.node, self.cfg = node, cfg
        self.mapper = cfg.mapper()
        self.cloud = VoxelCloud(cfg.voxel_m, cfg.max_points)
        self.odom = OdomBuffer()
        # 50 Hz, taken in as each scan is integrated (interpolated at its stamps): no thread
        # wakes per sample.
        self.odom_waiting = node.queued(keys.ODOM_SLOW, ODOM_RING)
        self.gate = cfg.gate()
        self.mount: Pose = node.chair.laser_mount
        self.tf_error = ""
        self.lock = threading.Lock()
        self.grid_pub = node.publisher(keys.MAP_GRID)
        self.keepout = load_keepout("mapping", cfg.keepout_map)
        self.unplaced = ""
        self.cloud_pub = node.publisher(keys.MAP_CLOUD)
        self.walkers = Walkers()
        self.people: People | None = None  # the control service's newest (keys.PEOPLE), walkers

    def on_people(self, msg: People) -> None:
        self.people = self.walkers.of(msg)

    def on_tf(self, msg: FrameTransform) -> None:
        if msg.child_frame_id != self.cfg.laser_frame:
            return
        err = self.node.chair.laser_tf_error(msg)
        if err:
            self.node.health.count("tf_mount_mismatch")
        if err != self.tf_error:
            self.tf_error = err
            self.node.event("warning" if err else "info",
                            f"mapping: laser mount mismatch ({err}); mapping with [chair]" if err
                            else "mapping: tf_static laser mount agrees with [chair]")

    def integrate(self, scan: LaserScan) -> None:
        cfg, health = self.cfg, self.node.health
        r = np.asarray(scan.ranges_m, dtype=np.float64)
        with self.lock:
            for msg in self.odom_waiting():
                self.odom.add(msg)
            placed = place_scan(self.odom, self.gate, scan.stamp_ns, r.size,
                                scan.time_increment_s, self.mount,
                                int(cfg.max_odom_dt_s * 1e9),
                                None if cfg.require_odom else (0.0, 0.0, 0.0))
        if isinstance(placed, str):
            health.count(placed)
            return
        self.mapper.integrate(r, scan.angle_min_rad, scan.angle_increment_rad, placed.laser,
                              placed.beams,
                              people_discs(self.people, scan.stamp_ns, cfg.frame_id))
        self.cloud.add(scan_points(r, scan.angle_min_rad, scan.angle_increment_rad,
                                   placed.laser), self.node.chair.laser_z_m)
        health.count("scans_mapped")

    def on_correction(self, msg: FrameTransform) -> None:
        if msg.parent_frame_id == "map" and msg.child_frame_id == "odom" and self.keepout:
            t, r = msg.translation, msg.rotation
            with self.lock:
                self.keepout.frame.on_correction((t.x, t.y, quaternion_yaw(r.x, r.y, r.z, r.w)))

    def on_loc(self, msg: LocalizedPose) -> None:
        if self.keepout is not None:
            with self.lock:
                self.keepout.on_loc(msg.state, msg.mode, time.monotonic())

    def on_loc_map(self, grid: OccupancyGrid) -> None:
        if self.keepout is not None:
            with self.lock:
                self.keepout.on_map(grid)

    def publish(self) -> None:
        now = time.time_ns()
        grid = self.mapper.to_msg(now, self.cfg.frame_id)
        if self.keepout is not None:
            with self.lock:
                pts, why = self.keepout.in_odom(time.monotonic())
            if pts is not None:
                grid = paint(grid, pts)
            if why != self.unplaced:  # the safety monitor stops meanwhile (H42)
                self.node.event("warning" if why else "info",
                                f"mapping: {why}" if why else "mapping: keep-out zones placed")
                self.unplaced = why
        self.grid_pub.put(grid)
        self.cloud_pub.put(self.cloud.to_msg(now, self.cfg.frame_id))
        self.node.health.count("maps_published")


def start(node: Node, cfg: MappingConfig) -> None:
    svc = MappingService(node, cfg)
    node.subscribe(keys.TF_STATIC, svc.on_tf)
    node.subscribe(keys.PEOPLE, svc.on_people)  # (their returns are not the map's)
    if svc.keepout is not None:
        node.subscribe(keys.TF, svc.on_correction)
        node.subscribe(keys.LOC_POSE, svc.on_loc)
        node.subscribe(keys.LOC_MAP, svc.on_loc_map)
    # The ray updates run on a worker thread, not the Zenoh thread; 8 scans may wait.
    node.subscribe(keys.SCAN, node.worker("map", svc.integrate, 8, "scans_dropped_busy"))
    node.every(cfg.publish_period_s, svc.publish, "publish")


def main(argv: list[str] | None = None) -> int:
    return service_main("mapping", MappingConfig, start, argv, description=__doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
