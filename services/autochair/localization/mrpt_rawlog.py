"""Reader for MRPT "rawlog" files of the Actions/SensoryFrame kind (2D laser + 2D odometry),
such as Debian mrpt-common's `2006-01ENE-21-SENA_Telecom Faculty_one_loop_only.rawlog`.

`rawlog-edit --export-2d-scans-txt` refuses that file (its observations have empty sensor
labels), so the two classes it holds are decoded here, after MRPT's serialisation: an object
is 0x80|len, class name, version byte, fields, 0x88 end flag; the file may be gzipped.

- CObservation2DRangeScan v6: aperture f32, rightToLeft u8, maxRange f32, sensorPose
  (CPose3D v1 holding a 4×4 CMatrixD), N u32, N × f32 ranges, N × u8 valid, stdError f32,
  timestamp u64 (100 ns ticks since 1601).
- CActionRobotMovement2D v6: estimation method u32, then the odometry increment as a CPose2D
  v1 object (x, y, phi as f64).
"""

from __future__ import annotations

import gzip
import math
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .matching import F64

SENA = Path("/usr/share/mrpt/datasets/2006-01ENE-21-SENA_Telecom Faculty_one_loop_only.rawlog")
_SCAN = b"\x97CObservation2DRangeScan"
_MOVE = b"\x96CActionRobotMovement2D"
_POSE2D = b"\x87CPose2D\x01"
_MATRIX = b"\x88CMatrixD\x00"
_EPOCH_1601_S = 11644473600


class RawlogError(ValueError):
    pass


@dataclass(frozen=True)
class RawScan:
    stamp_s: float  # Unix time
    ranges: F64  # m; inf where invalid
    angle_min: float
    angle_inc: float
    mount: tuple[float, float, float]  # laser x, y, yaw on the robot
    odom_increment: tuple[float, float, float]  # robot motion since the previous frame


def _scan(d: bytes, at: int) -> tuple[RawScan, int]:
    p = at + len(_SCAN)
    if d[p] != 6:
        raise RawlogError(f"CObservation2DRangeScan version {d[p]} at {at}: only 6 is read")
    aperture, rtl, _maxr = struct.unpack_from("<f?f", d, p + 1)
    m = d.index(_MATRIX, p)
    rows, cols = struct.unpack_from("<II", d, m + len(_MATRIX))
    hm = np.frombuffer(d, "<f8", rows * cols, m + len(_MATRIX) + 8).reshape(rows, cols)
    q = m + len(_MATRIX) + 8 + 8 * rows * cols + 2  # matrix and pose end flags
    (n,) = struct.unpack_from("<I", d, q)
    r = np.frombuffer(d, "<f4", n, q + 4).astype(np.float64)
    valid = np.frombuffer(d, np.uint8, n, q + 4 + 4 * n).astype(np.bool_)
    (ticks,) = struct.unpack_from("<Q", d, q + 4 + 5 * n + 4)
    ranges = np.where(valid & (r > 0), r, np.inf)
    inc = aperture / (n - 1)
    if not rtl:
        ranges, inc = ranges[::-1].copy(), inc
    mount = (float(hm[0, 3]), float(hm[1, 3]), math.atan2(hm[1, 0], hm[0, 0]))
    return RawScan(ticks * 1e-7 - _EPOCH_1601_S, ranges, -aperture / 2, inc, mount,
                   (0.0, 0.0, 0.0)), q


def read_rawlog(path: str | Path = SENA) -> list[RawScan]:
    """Scans in file order, each with the odometry increment of the action before it."""
    raw = Path(path).read_bytes()
    d = gzip.decompress(raw) if raw[:2] == b"\x1f\x8b" else raw
    out: list[RawScan] = []
    inc = (0.0, 0.0, 0.0)
    pos = 0
    while True:
        s, mv = d.find(_SCAN, pos), d.find(_MOVE, pos)
        if s < 0 and mv < 0:
            break
        if mv >= 0 and (s < 0 or mv < s):
            k = d.index(_POSE2D, mv)
            x, y, phi = struct.unpack_from("<ddd", d, k + len(_POSE2D))
            inc = (x, y, phi)
            pos = k + len(_POSE2D) + 24
            continue
        scan, pos = _scan(d, s)
        out.append(RawScan(scan.stamp_s, scan.ranges, scan.angle_min, scan.angle_inc,
                           scan.mount, inc))
        inc = (0.0, 0.0, 0.0)
    if not out:
        raise RawlogError(f"{path}: no 2D range scans")
    return out
