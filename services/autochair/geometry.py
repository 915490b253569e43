"""Geometry shared by every service (pure): angles, planar poses, yaw ↔ quaternion, frame
checks.

One place for these, so no two services convert differently (REP-103: x forward, y left,
z up, yaw counter-clockwise about z)."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt


def wrap_angle(a: float) -> float:
    """Wrap an angle to (−π, π] (REP-103 heading range)."""
    r = math.remainder(a, math.tau)
    return r + math.tau if r <= -math.pi else r


Pose = tuple[float, float, float]  # a planar pose: x m, y m, yaw rad


def along_lateral(pose: Pose, px: float, py: float) -> tuple[float, float]:
    """The point (px, py) from the line through `pose` along its yaw: (how far along it,
    how far to its left)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    dx, dy = px - pose[0], py - pose[1]
    return dx * c + dy * s, dy * c - dx * s


def advance(x: float, y: float, yaw: float, v: float, w: float, dt: float) -> Pose:
    """The pose after dt at (v, ω), heading taken at the step's middle (unwrapped yaw)."""
    mid = yaw + 0.5 * w * dt
    return x + v * math.cos(mid) * dt, y + v * math.sin(mid) * dt, yaw + w * dt


def compose(a: Pose, b: Pose) -> Pose:
    """a ∘ b: pose b, given in a's frame, in a's parent frame."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], wrap_angle(a[2] + b[2]))


def inverse(a: Pose) -> Pose:
    """a⁻¹: the parent frame's origin in a's frame (compose(a, inverse(a)) = identity)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return (-c * a[0] - s * a[1], s * a[0] - c * a[1], wrap_angle(-a[2]))


def yaw_quaternion(yaw: float) -> tuple[float, float, float, float]:
    """The unit quaternion (x, y, z, w) of a rotation by `yaw` about z."""
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


def quaternion_yaw(x: float, y: float, z: float, w: float) -> float:
    """The yaw (about z, in (−π, π]) of a quaternion (x, y, z, w); exact for planar ones."""
    return wrap_angle(math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))


def mount_mismatch(parent: str, translation: tuple[float, float, float],
                   rotation_xyzw: tuple[float, float, float, float],
                   laser_xyz: tuple[float, float, float], laser_yaw: float,
                   parent_frame: str = "chair", tol_m: float = 1e-3,
                   tol_rad: float = math.radians(0.1)) -> str:
    """"" if a received chair→laser transform agrees with the configured mount within 1 mm
    and 0.1°, else why not (one line)."""
    if parent != parent_frame:
        return f"tf parent frame {parent!r}, want {parent_frame!r}"
    vals = (*translation, *rotation_xyzw)
    if not all(math.isfinite(v) for v in vals):
        return "tf has non-finite values"
    for axis, got, want in zip("xyz", translation, laser_xyz, strict=True):
        if abs(got - want) > tol_m:
            return (f"tf {axis} {got:.4f} m vs [chair] laser_{axis}_m {want:.4f} m "
                    f"({1000 * (got - want):+.1f} mm)")
    qx, qy, qz, qw = rotation_xyzw
    norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    if abs(norm - 1.0) > 1e-3:
        return f"tf rotation is not a unit quaternion (norm {norm:.4f})"
    h = laser_yaw / 2
    dot = abs(qz * math.sin(h) + qw * math.cos(h)) / norm  # with (0, 0, sin h, cos h)
    angle = 2 * math.acos(min(1.0, dot))
    if angle > tol_rad:
        yaw = quaternion_yaw(qx, qy, qz, qw)
        return (f"tf rotation differs by {math.degrees(angle):.2f}° (yaw {yaw:.4f} rad vs "
                f"[chair] laser_yaw_rad {laser_yaw:.4f})")
    return ""


def sweep_poses(first: Pose, last: Pose, mount: Pose, n: int
                ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64],
                           npt.NDArray[np.float64]]:
    """x, y, yaw of the laser (at `mount` on the chair) for each of the `n` beams of a sweep
    during which the chair went from `first` to `last`, linearly (a sweep lasts tens of
    milliseconds): a scan taken while turning is placed beam by beam, not skewed."""
    f = np.linspace(0.0, 1.0, n)
    x = first[0] + f * (last[0] - first[0])
    y = first[1] + f * (last[1] - first[1])
    yaw = first[2] + f * wrap_angle(last[2] - first[2])
    mx, my, myaw = mount
    c, s = np.cos(yaw), np.sin(yaw)
    return x + mx * c - my * s, y + mx * s + my * c, yaw + myaw
