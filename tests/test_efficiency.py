"""The efficiency changes of bench/cpu.py's work keep behaviour: derived-channel decimation,
the summary of an indexed recording read from its indexes, the mapper's per-scan update."""

from __future__ import annotations

from pathlib import Path

import msgspec
import numpy as np

from autochair.logger import foxglove
from autochair.logger.reader import Recording, indexed_summary
from autochair.logger.writer import LoggerConfig, Recorder
from autochair.mapping.core import GridSpec, OccupancyMapper
from autochair_msgs import FrameTransform, OccupancyGrid, Odometry, Quaternion, Vector3, keys

T0 = 1_763_700_000_000_000_000


def tf(stamp: int, child: str = "chair") -> FrameTransform:
    return FrameTransform(stamp_ns=stamp, parent_frame_id="odom", child_frame_id=child,
                          translation=Vector3(1.0, 2.0, 0.0), rotation=Quaternion(0, 0, 0, 1))


def test_transforms_and_poses_are_not_derived() -> None:
    """The chair's pose is shown by the transforms, recorded as foxglove.FrameTransform: no
    /tf or /pose copy; a map is (positive control)."""
    d = foxglove.Deriver()
    assert d.derive(keys.TF.key, tf(T0)) == [] and d.derive(keys.TF_STATIC.key, tf(T0)) == []
    assert d.derive(keys.ODOM.key, Odometry(stamp_ns=T0, x_m=0.0, y_m=0.0, yaw_rad=0.0,
                                            v_mps=0.0, omega_radps=0.0)) == []
    grid = OccupancyGrid(stamp_ns=T0, frame_id="odom", resolution_m=0.05, width=1, height=1,
                         origin_x_m=0.0, origin_y_m=0.0, data=b"\x00")
    assert [t for t, _, _ in d.derive(keys.MAP_GRID.key, grid)] == ["/map"]


def test_indexed_summary_equals_a_full_read(tmp_path: Path) -> None:
    rec = Recorder(LoggerConfig(path=str(tmp_path / "r.mcap"), chunk_size_kib=4),
                   T0, 0.0)
    enc_tf = msgspec.msgpack.encode
    for i in range(3000):
        stamp = T0 + i * 1_000_000
        rec.write(keys.TF.key, enc_tf(tf(stamp)), stamp + 1000)
        if i % 7 == 0:
            rec.write(keys.TF_STATIC.key, enc_tf(tf(stamp, "laser")), stamp + 2000)
        if i % 500 == 0:
            rec.tick(float(i))
    rec.finish()
    r = Recording(rec.path)
    fast = indexed_summary(r.path)
    assert fast is not None
    scanned = Recording(rec.path).scanned_summary()
    assert fast.channels == scanned.channels
    assert r.summary().channels == scanned.channels
    assert fast.channels[keys.TF.key].schema == "foxglove.FrameTransform"
    assert fast.channels[keys.TF.key].count == 3000


def _integrate_reference(m: OccupancyMapper, ranges: np.ndarray, angle_min: float,
                         angle_inc: float, pose: tuple[float, float, float]) -> None:
    """The mapper's update as it was (np.unique + setdiff1d), for comparison."""
    a = angle_min + angle_inc * np.arange(ranges.size) + pose[2]
    ok = np.isfinite(ranges) & (ranges > 0) & (ranges <= m.max_range_m)
    r, a = ranges[ok], a[ok]
    t = np.arange(0.0, float(r.max()), m.res / 2)
    cos, sin = np.cos(a)[:, None], np.sin(a)[:, None]
    free_mask = t[None, :] < (r[:, None] - m.res)
    fx = (pose[0] + cos * t[None, :])[free_mask]
    fy = (pose[1] + sin * t[None, :])[free_mask]
    free = np.unique(m.cells(np.stack([fx, fy], axis=1)))
    hits = np.unique(m.cells(np.stack([pose[0] + r * cos[:, 0], pose[1] + r * sin[:, 0]],
                                      axis=1)))
    free, hits = free[free >= 0], hits[hits >= 0]
    free = np.setdiff1d(free, hits, assume_unique=True)
    flat = m.logodds.reshape(-1)
    flat[free] += m.l_miss
    flat[hits] += m.l_hit
    np.clip(flat, m.l_min, m.l_max, out=flat)


def test_mapper_update_unchanged() -> None:
    spec = GridSpec(0.05, 10.0, 8.0, -5.0, -4.0)
    new, ref = OccupancyMapper(spec, 0.85, -0.4), OccupancyMapper(spec, 0.85, -0.4)
    rng = np.random.default_rng(1)
    for k in range(20):
        ranges = rng.uniform(0.1, 7.0, 300)
        ranges[rng.random(300) < 0.1] = np.nan
        pose = (rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-3, 3))
        new.integrate(ranges, -2.0, 4.0 / 300, pose)
        _integrate_reference(ref, ranges, -2.0, 4.0 / 300, pose)
        assert np.array_equal(new.logodds, ref.logodds), k
