"""MPEPC anticipates the safety monitor's forward bound along its own prediction (H76:
`Mpepc.monitor_top`), on the map's cells that are not people."""

from __future__ import annotations

import math

import numpy as np

from autochair.control.core import ControlConfig
from autochair.nav.field import Footprint, GridMap, NavField
from autochair.nav.mpepc import Mpepc, Person
from autochair.safety.core import SafetyTuning

LAW = ControlConfig().law(0.025)


def _cruise(mpc: Mpepc, v: float = 1.2) -> dict[str, np.ndarray]:
    """A prediction straight along x at v from (0, 0), as `_costs`' info row."""
    t = (np.arange(mpc.steps) + 1) * mpc.p.dt_s
    z = np.zeros_like(t)
    return {"x": v * t, "y": z, "yaw": z, "v": np.full_like(t, v), "w": z}


def test_the_bound_ahead_is_read_on_the_maps_cells_but_not_on_a_person() -> None:
    """A disc 3 m ahead of a chair cruising at 1.2 m/s: the monitor's bound falls under 1.2
    within its horizon, so the plan must slow (finite, under 1.2). The same disc where a
    person is tracked standing is their body on the map (the laser's map draws them): MPEPC's
    people checks keep the chair off them, the anticipated bound does not brake for it."""
    box = np.array([[-2.0, -3.0, 9.0, -3.0], [9.0, -3.0, 9.0, 3.0], [9.0, 3.0, -2.0, 3.0],
                    [-2.0, 3.0, -2.0, -3.0]])
    gm = GridMap.from_shapes(box, np.array([[3.0, 0.0, 0.25]]))
    mpc = Mpepc(NavField(gm, Footprint()), LAW)
    row, m = _cruise(mpc), SafetyTuning()
    top = mpc.monitor_top((0.0, 0.0, 0.0), 1.2, 0.0, row, [], m)
    assert 0.0 < top < 1.0, top
    assert mpc.monitor_top((0.0, 0.0, 0.0), 1.2, 0.0, row, [Person(3.0, 0.0)], m) == math.inf
    # Nothing within the monitor's reach of the way: no bound
    open_ = Mpepc(NavField(GridMap.from_shapes(box, np.zeros((0, 3))), Footprint()), LAW)
    assert open_.monitor_top((0.0, 0.0, 0.0), 0.5, 0.0, _cruise(open_, 0.5), [], m) == math.inf
