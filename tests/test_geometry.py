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
