"""Goals in `map` driven in `odom`: the correction, and when localization is not trusted."""

from __future__ import annotations

import math

import pytest

from autochair.geometry import compose
from autochair.nav.frames import MapFrame


def test_a_map_goal_is_where_the_correction_puts_it_in_odom() -> None:
    f = MapFrame()
    f.on_correction((0.5, -0.2, math.radians(10)))  # map → odom: odometry has drifted
    f.on_state("tracking", now=1.0)
    assert f.why_not(1.0) == ""
    goal_map = (3.0, 1.0, math.pi / 2)
    goal_odom = f.to_odom(goal_map)
    # the same place: odom expressed in map again gives the map goal back
    assert compose((0.5, -0.2, math.radians(10)), goal_odom) == pytest.approx(goal_map)
    f.on_correction((0.0, 0.0, 0.0))
    assert f.to_odom(goal_map) == pytest.approx(goal_map)  # no drift: the same numbers


@pytest.mark.parametrize("heard,state,now,why", [
    (False, "", 1.0, "no localization heard"),
    (True, "initializing", 1.0, "localization is initializing, not tracking"),
    (True, "lost", 1.0, "localization is lost, not tracking"),
    (True, "tracking", 3.6, "localization silent for 2.6 s"),
])
def test_only_a_fresh_tracking_localization_is_trusted(heard: bool, state: str, now: float,
                                                        why: str) -> None:
    f = MapFrame(stale_s=2.5)
    if heard:
        f.on_correction((0.0, 0.0, 0.0))
        f.on_state(state, now=1.0)
    assert f.why_not(now).startswith(why)
    control = MapFrame(stale_s=2.5)  # positive control: fresh and tracking
    control.on_correction((0.0, 0.0, 0.0))
    control.on_state("tracking", now=1.0)
    assert control.why_not(3.4) == ""
