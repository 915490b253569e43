"""autochair-localization: where the chair is on the map (REP-105 `map` → `odom`).

Scans (keys.SCAN) placed by odometry (keys.ODOM_SLOW, the `odom` frame) are matched against the map
and fused with the odometry (core.Localizer), or, in mapping mode, build the map with loop
closure (slam.Slam). Per scan it publishes the chair's pose in `map` with covariance, quality
and state (keys.LOC_POSE) and the `map` → `odom` correction on keys.TF. The map it uses or
builds goes out on keys.LOC_MAP. Health is "degraded" while lost or not yet localized.

Modes: `--map NAME` (or `--set map=NAME`) loads maps_dir/NAME.yaml (ROS map_server format) and
localizes on it, from `autochair localize X Y YAW` or by searching the whole map; without a map
it maps, and `autochair map save NAME` writes the map for the next start.
"""

from __future__ import annotations

import math
import sys
import threading
import time
from pathlib import Path
from typing import Annotated

import msgspec
import numpy as np

from autochair.geometry import yaw_quaternion
from autochair.mapping.core import ODOM_RING, MoveGate, OccupancyMapper, OdomBuffer
from autochair.mapping.mapfile import MapFile, MapFileError, load_map, map_path, save_map
from autochair.runtime.config import ConfigError
from autochair.runtime.node import Node, service_main
from autochair_msgs import (
    FrameTransform,
    LaserScan,
    LocalizedPose,
    LocalizeReply,
    LocalizeRequest,
    MapSaveReply,
    MapSaveRequest,
    OccupancyGrid,
    Quaternion,
    Vector3,
    keys,
)

from .core import TRACK_MOVE_M, TRACK_TURN_RAD, Estimate, Localizer, LocState, chair_cells
from .matching import DistanceField, GridFrame, between
from .slam import MapRenderer, Scan, Slam


class LocalizationConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    map: str = ""  # map NAME in maps_dir to localize on; "" = mapping mode
    maps_dir: str = "maps"
    # scan stamp to nearest odometry sample, else skipped
    max_odom_dt_s: Annotated[float, msgspec.Meta(gt=0)] = 0.25
    map_period_s: Annotated[float, msgspec.Meta(gt=0)] = 5.0  # keys.LOC_MAP at most this often
    map_frame: str = "map"
    odom_frame: str = "odom"
    chair_frame: str = "chair"


def map_from_grid(grid: OccupancyMapper) -> MapFile:
    s = grid.spec
    # Free: at least one beam through and none ending there (l_miss is -0.4 per beam).
    return MapFile(grid.occupied(), grid.logodds < -0.2, grid.res, s.origin_x_m, s.origin_y_m)


def grid_msg(m: MapFile, stamp_ns: int, frame_id: str) -> OccupancyGrid:
    data = np.full(m.occupied.shape, 255, dtype=np.uint8)
    data[m.free] = 0
    data[m.occupied] = 100
    h, w = m.occupied.shape
    return OccupancyGrid(stamp_ns=stamp_ns, frame_id=frame_id, resolution_m=m.resolution_m,
                         width=w, height=h, origin_x_m=m.origin_x_m, origin_y_m=m.origin_y_m,
                         data=data.tobytes())


def localizer_for(m: MapFile) -> Localizer:
    frame = GridFrame(m.resolution_m, m.origin_x_m, m.origin_y_m)
    return Localizer(DistanceField(m.occupied, frame),
                     chair_cells(m.occupied, m.free, m.resolution_m))


class LocalizationService:
    """The thin glue: Zenoh callbacks queue, one worker thread runs the core."""

    def __init__(self, node: Node, cfg: LocalizationConfig) -> None:
        self.node, self.cfg = node, cfg
        self.lock = threading.Lock()
        self.odom = OdomBuffer()
        # 50 Hz, taken in as each scan is processed (interpolated at its stamps): no thread
        # wakes per sample.
        self.odom_waiting = node.queued(keys.ODOM_SLOW, ODOM_RING)
        self.gate = MoveGate(TRACK_MOVE_M, TRACK_TURN_RAD)
        self.map: MapFile | None = None
        self.loc: Localizer | None = None
        self.slam: Slam | None = None
        if cfg.map:
            try:
                self.map = load_map(map_path(cfg.maps_dir, cfg.map))
            except MapFileError as e:
                raise ConfigError(f"localization: {e}") from None
            self.loc = localizer_for(self.map)
        else:
            self.slam = Slam()
        self.mode = "localization" if self.loc else "mapping"
        self.pose_pub = node.publisher(keys.LOC_POSE)
        self.tf_pub = node.publisher(keys.TF)
        self.map_pub = node.publisher(keys.LOC_MAP)
        self.last_state = ""
        self._rendered: tuple[tuple[int, int], MapFile] | None = None
        self._renderer = MapRenderer(self.slam.p) if self.slam is not None else None
        self._render_lock = threading.Lock()  # the map timer and MAP_SAVE both render

    # --- Zenoh side -----------------------------------------------------------------------
    def on_set_pose(self, req: LocalizeRequest) -> LocalizeReply:
        if self.loc is None:
            return LocalizeReply(ok=False, error="mapping mode: the map starts where the "
                                                 "chair is; start with --map NAME to localize")
        with self.lock:
            if req.pose is None:
                self.loc.relocalize()
            else:
                p = req.pose
                self.loc.hint(np.array([p.x_m, p.y_m, p.yaw_rad]), req.sigma_xy_m,
                              req.sigma_yaw_rad)
            state = self.loc.state.value
        self.node.event("info", f"localization: pose set to {req.pose} ({state})")
        return LocalizeReply(ok=True, state=state)

    def on_save(self, req: MapSaveRequest) -> MapSaveReply:
        try:
            path = map_path(self.cfg.maps_dir, req.name)
            m = self.current_map()
            if m is None:
                return MapSaveReply(ok=False, error="no map yet: no scans mapped")
            save_map(m, path)
        except (MapFileError, OSError) as e:
            return MapSaveReply(ok=False, error=str(e))
        self.node.event("info", f"map saved to {path}")
        return MapSaveReply(ok=True, path=str(path.resolve()))

    # --- worker side ----------------------------------------------------------------------
    def current_map(self) -> MapFile | None:
        """The loaded map, or the one being built (rendered outside the lock: it takes a
        while on a large map, and the scans must not wait for it)."""
        if self.slam is None:
            return self.map
        with self.lock:
            nodes, kfs = self.slam.snapshot()
            version = (len(kfs), self.slam.stats.loops)
        if not kfs or self._renderer is None:
            return None
        with self._render_lock:
            if self._rendered is None or self._rendered[0] != version:
                self._rendered = (version, map_from_grid(self._renderer.update(nodes, kfs)))
            return self._rendered[1]

    def process(self, msg: LaserScan) -> None:
        health = self.node.health
        max_dt = int(self.cfg.max_odom_dt_s * 1e9)
        with self.lock:
            for m in self.odom_waiting():
                self.odom.add(m)
            pose = self.odom.at(msg.stamp_ns, max_dt)  # the first beam's: the scan's pose
            end = self.odom.at_last_beam(msg.stamp_ns, len(msg.ranges_m), msg.time_increment_s,
                                         max_dt)
        if pose is None:
            health.count("scans_no_odom")
            return
        # Tracking a parked chair: one scan a second is enough (a kidnap is still caught
        # within a second); lost or initializing, every scan counts.
        if not self.gate.take(pose, msg.stamp_ns) and self.last_state == LocState.TRACKING.value:
            health.count("scans_still")
            return
        # each beam from where the chair was when it was taken (a turn at 0.8 rad/s skews
        # a URG sweep by 3°: 16 cm at 3 m); odometry between the first and the last beam
        last = between(np.array(pose), np.array(end)) if end is not None else np.zeros(3)
        scan = Scan(np.asarray(msg.ranges_m, dtype=np.float64), msg.angle_min_rad,
                    msg.angle_increment_rad, self.node.chair.laser_mount,
                    last=(float(last[0]), float(last[1]), float(last[2])))
        odom = np.array(pose)
        t0 = time.perf_counter()
        with self.lock:
            est = (self.loc.update(odom, scan.points()) if self.loc is not None
                   else self.slam.update(odom, scan) if self.slam is not None else None)
        health.count("scan_us", int((time.perf_counter() - t0) * 1e6))
        health.count("scans")
        if est is not None:
            self.publish(msg.stamp_ns, est)

    def publish(self, stamp_ns: int, est: Estimate) -> None:
        cfg, x = self.cfg, est.pose
        self.pose_pub.put(LocalizedPose(
            stamp_ns=stamp_ns, frame_id=cfg.map_frame, x_m=float(x[0]), y_m=float(x[1]),
            yaw_rad=float(x[2]), covariance=[float(v) for v in est.covariance.ravel()],
            quality=est.quality, state=est.state.value, mode=self.mode))
        c = est.correction
        self.tf_pub.put(FrameTransform(
            stamp_ns=stamp_ns, parent_frame_id=cfg.map_frame, child_frame_id=cfg.odom_frame,
            translation=Vector3(float(c[0]), float(c[1]), 0.0),
            rotation=Quaternion(*yaw_quaternion(float(c[2])))))
        self.report(est)

    def report(self, est: Estimate) -> None:
        health, state = self.node.health, est.state.value
        health.state = "ok" if est.state is LocState.TRACKING else "degraded"
        health.detail = (f"{self.mode}: {state}, quality {est.quality:.2f}, "
                         f"σxy {math.sqrt(max(est.covariance[0, 0], 0.0)):.3f} m")
        if state != self.last_state:
            if est.state is LocState.LOST:
                health.count("lost")
            self.node.event("warning" if est.state is LocState.LOST else "info",
                            f"localization: {state}")
            self.last_state = state

    def publish_map(self) -> None:
        m = self.current_map()
        if m is not None:
            self.map_pub.put(grid_msg(m, time.time_ns(), self.cfg.map_frame))


def start(node: Node, cfg: LocalizationConfig) -> None:
    svc = LocalizationService(node, cfg)
    node.health.detail = f"{svc.mode}" + (f" on {Path(cfg.map).name}" if cfg.map else "")
    # Matching runs on a worker thread, not the Zenoh thread; 4 scans may wait.
    node.subscribe(keys.SCAN, node.worker("localize", svc.process, 4, "scans_dropped_busy"))
    node.serve(keys.LOC_SET_POSE, svc.on_set_pose)
    node.serve(keys.MAP_SAVE, svc.on_save)
    node.every(cfg.map_period_s, svc.publish_map, "map")


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if "--map" in args:  # `--map NAME` is `--set map=NAME`
        i = args.index("--map")
        if i + 1 >= len(args):
            print("autochair-localization: error: --map wants a NAME", file=sys.stderr)
            return 2
        args[i:i + 2] = ["--set", f"map={args[i + 1]}"]
    return service_main("localization", LocalizationConfig, start, args, __doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
