"""Odometry node: EncoderSample → Odometry at the encoder rate (keys.ODOM, for the velocity PID
and the recording), decimated to `slow_rate_hz` (keys.ODOM_SLOW, for everyone else), and the
odom→chair transform (keys.TF; REP-105: localization adds map→odom) at `tf_rate_hz` (the
same pose, for viewers)."""

from __future__ import annotations

import sys
import time
from typing import Annotated

import msgspec

from autochair.geometry import yaw_quaternion
from autochair.runtime import Node, service_main
from autochair.timing import Decimator
from autochair_msgs import EncoderSample, FrameTransform, Odometry, Quaternion, Vector3, keys

from .core import OdometryCore

Positive = Annotated[float, msgspec.Meta(gt=0)]


class OdometryConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    wheel_radius_m: Positive = 0.049
    base_m: Positive = 0.367
    counts_per_rev: Annotated[int, msgspec.Meta(gt=0)] = 10000
    # D_right / D_left (odometry calibration)
    wheel_diameter_ratio: Annotated[float, msgspec.Meta(gt=0.5, lt=2.0)] = 1.0
    velocity_window_s: Positive = 0.02
    publish_tf: bool = True
    # keys.TF at most this often (by sample stamp); 0 = every sample
    tf_rate_hz: Annotated[float, msgspec.Meta(ge=0)] = 20.0
    slow_rate_hz: Annotated[float, msgspec.Meta(ge=0)] = 50.0  # keys.ODOM_SLOW likewise


def start(node: Node, cfg: OdometryConfig) -> None:
    node.subscribe(keys.ENCODERS, _Odometry(node, cfg).on_sample)


class _Odometry:
    """OdometryCore wired to the encoder samples and its three publications."""

    def __init__(self, node: Node, cfg: OdometryConfig) -> None:
        self.node, self.cfg = node, cfg
        self.core = OdometryCore(wheel_radius_m=cfg.wheel_radius_m, base_m=cfg.base_m,
                                 counts_per_rev=cfg.counts_per_rev,
                                 wheel_diameter_ratio=cfg.wheel_diameter_ratio,
                                 velocity_window_s=cfg.velocity_window_s)
        self.odom_pub = node.publisher(keys.ODOM)
        self.tf_pub = node.publisher(keys.TF)
        self.slow_pub = node.publisher(keys.ODOM_SLOW)
        self.tf_due = Decimator.at(cfg.tf_rate_hz)
        self.slow_due = Decimator.at(cfg.slow_rate_hz)

    def on_sample(self, s: EncoderSample) -> None:
        core, node = self.core, self.node
        restarts, implausible = core.restarts, core.implausible
        st = core.update(s.left_counts, s.right_counts, s.mcu_time_us, s.status)
        if core.implausible != implausible:
            node.health.count("implausible_samples")
            node.event("warning", f"encoder sample {s.seq} implies a wheel faster than "
                                  f"{core.max_wheel_mps:g} m/s: dropped, counters re-based")
        if core.restarts != restarts:
            node.health.count("mcu_restarts")
            node.event("warning", "chair MCU restarted; odometry continues from the last pose")
        stamp = s.stamp_ns or time.time_ns()
        odom = Odometry(stamp_ns=stamp, x_m=st.x, y_m=st.y, yaw_rad=st.yaw, v_mps=st.v,
                        omega_radps=st.omega, distance_m=st.distance, sample_dt_s=st.dt,
                        source_seq=s.seq, mcu_restarts=core.restarts, link_epoch=s.link_epoch)
        self.odom_pub.put(odom)
        if self.slow_due(stamp):
            self.slow_pub.put(odom)
        if self.cfg.publish_tf and self.tf_due(stamp):
            self.tf_pub.put(FrameTransform(
                stamp_ns=stamp, parent_frame_id="odom", child_frame_id="chair",
                translation=Vector3(st.x, st.y, 0.0),
                rotation=Quaternion(*yaw_quaternion(st.yaw))))
        node.health.count("samples")


def main(argv: list[str] | None = None) -> int:
    return service_main("odometry", OdometryConfig, start, argv, __doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
