"""autochair-mapping: occupancy grid (keys.MAP_GRID) and point cloud (keys.MAP_CLOUD) from
scans (keys.SCAN) placed by odometry (keys.ODOM) and the chair→laser mount of the [chair]
section (`node.chair`). A chair→laser transform on keys.TF_STATIC that disagrees with it is
counted (`tf_mount_mismatch`) and reported, not followed: the mount is defined once."""

from __future__ import annotations

import sys
import threading
import time
from collections import deque

import msgspec
import numpy as np

from autochair.runtime.config import ConfigError
from autochair.runtime.node import Node, service_main
from autochair_msgs import FrameTransform, LaserScan, Odometry, keys

from .core import GridSpec, OccupancyMapper, OdomBuffer, Pose, VoxelCloud, compose, scan_points


class MappingConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    resolution_m: float = 0.05
    width_m: float = 30.0
    height_m: float = 20.0
    origin_x_m: float = -5.0  # world position of the grid's (0, 0) corner
    origin_y_m: float = -10.0
    l_hit: float = 0.85  # log-odds added to a cell a beam ends in
    l_miss: float = -0.4  # log-odds added to a cell a beam passes through
    max_odom_dt_s: float = 0.25  # scan stamp to nearest odometry sample, else the scan is skipped
    require_odom: bool = True  # False: map scans at the origin when there is no odometry
    voxel_m: float = 0.05  # point-cloud voxel size
    max_points: int = 100_000
    publish_period_s: float = 1.0
    frame_id: str = "world"
    laser_frame: str = "laser"


def start(node: Node, cfg: MappingConfig) -> None:
    if cfg.resolution_m <= 0 or cfg.width_m <= 0 or cfg.height_m <= 0:
        raise ConfigError("mapping: resolution_m, width_m and height_m must be > 0")
    if cfg.width_m * cfg.height_m / cfg.resolution_m**2 > 50e6:
        raise ConfigError("mapping: grid over 50 M cells; coarsen resolution_m or shrink it")
    mapper = OccupancyMapper(GridSpec(cfg.resolution_m, cfg.width_m, cfg.height_m,
                                      cfg.origin_x_m, cfg.origin_y_m), cfg.l_hit, cfg.l_miss)
    cloud = VoxelCloud(cfg.voxel_m, cfg.max_points)
    odom = OdomBuffer()
    chair = node.chair
    mount: Pose = chair.laser_mount
    z = chair.laser_z_m
    tf_state = {"error": ""}
    pending: deque[LaserScan] = deque(maxlen=8)
    lock = threading.Lock()
    wake = threading.Event()
    health = node.health
    grid_pub, cloud_pub = node.publisher(keys.MAP_GRID), node.publisher(keys.MAP_CLOUD)

    def on_odom(msg: Odometry) -> None:
        with lock:
            odom.add(msg)

    def on_tf(msg: FrameTransform) -> None:
        if msg.child_frame_id != cfg.laser_frame:
            return
        err = chair.laser_tf_error(msg)
        if err:
            health.count("tf_mount_mismatch")
        if err != tf_state["error"]:
            tf_state["error"] = err
            node.event("warning" if err else "info",
                       f"mapping: laser mount mismatch ({err}); mapping with [chair]" if err
                       else "mapping: tf_static laser mount agrees with [chair]")

    def on_scan(msg: LaserScan) -> None:
        if len(pending) == pending.maxlen:
            health.count("scans_dropped_busy")
        pending.append(msg)  # the worker thread does the ray updates, not the Zenoh thread
        wake.set()

    def worker() -> None:
        while not node.stop_event.is_set():
            wake.wait(0.2)
            wake.clear()
            while pending:
                scan = pending.popleft()
                with lock:
                    pose = odom.nearest(scan.stamp_ns, int(cfg.max_odom_dt_s * 1e9))
                if pose is None:
                    if cfg.require_odom:
                        health.count("scans_no_odom")
                        continue
                    pose = (0.0, 0.0, 0.0)
                laser = compose(pose, mount)
                r = np.asarray(scan.ranges_m, dtype=np.float64)
                mapper.integrate(r, scan.angle_min_rad, scan.angle_increment_rad, laser)
                cloud.add(scan_points(r, scan.angle_min_rad, scan.angle_increment_rad, laser), z)
                health.count("scans_mapped")

    def publish() -> None:
        now = time.time_ns()
        grid_pub.put(mapper.to_msg(now, cfg.frame_id))
        cloud_pub.put(cloud.to_msg(now, cfg.frame_id))
        health.count("maps_published")

    node.subscribe(keys.ODOM, on_odom)
    node.subscribe(keys.TF_STATIC, on_tf)
    node.subscribe(keys.SCAN, on_scan)
    node.thread(worker, "map")
    node.every(cfg.publish_period_s, publish, "publish")


def main(argv: list[str] | None = None) -> int:
    return service_main("mapping", MappingConfig, start, argv, description=__doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
