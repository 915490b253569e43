"""The one geometry module: angles and yaw ↔ quaternion, used by every service."""

from __future__ import annotations

import math

import pytest

from autochair.geometry import compose, inverse, quaternion_yaw, wrap_angle, yaw_quaternion


@pytest.mark.parametrize("yaw", [0.0, 0.3, -1.2, math.pi / 2, 3.0, -3.0, math.pi])
def test_yaw_round_trips_through_a_unit_quaternion(yaw: float) -> None:
    q = yaw_quaternion(yaw)
    assert math.isclose(sum(c * c for c in q), 1.0)
    assert q[:2] == (0.0, 0.0)
    assert quaternion_yaw(*q) == pytest.approx(wrap_angle(yaw), abs=1e-12)


def test_quaternion_yaw_of_a_known_rotation() -> None:
    h = math.sqrt(0.5)
    assert quaternion_yaw(0.0, 0.0, h, h) == pytest.approx(math.pi / 2)  # 90° about z
    assert quaternion_yaw(0.0, 0.0, -h, h) == pytest.approx(-math.pi / 2)


def test_compose_and_inverse_of_planar_poses() -> None:
    a = (1.0, 2.0, math.pi / 2)
    assert compose(a, (1.0, 0.0, 0.0)) == pytest.approx((1.0, 3.0, math.pi / 2))
    for b in [(0.3, -0.2, 2.5), (-4.0, 1.0, -3.0)]:
        back = compose(inverse(b), compose(b, a))
        assert back == pytest.approx(a)
        assert compose(b, inverse(b)) == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    assert -math.pi < compose((0, 0, 3.0), (0, 0, 3.0))[2] <= math.pi  # wrapped


def test_sweep_poses_place_each_beam_between_the_sweeps_ends() -> None:
    from autochair.geometry import sweep_poses

    x, y, yaw = sweep_poses((0.0, 0.0, 0.0), (0.2, 0.0, 0.1), (1.0, 0.0, 0.5), 3)
    assert yaw.tolist() == pytest.approx([0.5, 0.55, 0.6])
    assert x.tolist() == pytest.approx([1.0, 0.1 + math.cos(0.05), 0.2 + math.cos(0.1)])
    assert y.tolist() == pytest.approx([0.0, math.sin(0.05), math.sin(0.1)])
    # Across ±π the chair turned 0.08 rad, not −6.2.
    _, _, yaw = sweep_poses((0.0, 0.0, 3.1), (0.0, 0.0, -3.1), (0.0, 0.0, 0.0), 3)
    assert yaw[1] == pytest.approx(3.1 + (2 * math.pi - 6.2) / 2)
