"""Session 9, offline: does a traversal cost on never-observed cells send the L corridor's
costs-to-go forward from the closed end? Replays the last live map of a run where the goal
(8, 7.5) stood "blocked" at the start (docs/experiments/l-corridor-start-grid.msgpack.gz).
Run from the repository root: PYTHONPATH=. python docs/experiments/scripts/unknown_cost.py"""
import gzip
import math
import sys

import msgspec

import numpy as np

from autochair.nav.field import Footprint, GridMap, NavField
from autochair.runtime.config import ChairGeometry

from autochair_msgs import OccupancyGrid

path = sys.argv[1] if len(sys.argv) > 1 else "docs/experiments/l-corridor-start-grid.msgpack.gz"
g = msgspec.msgpack.decode(gzip.decompress(open(path, "rb").read()), type=OccupancyGrid)
ch = ChairGeometry()
fp = Footprint(ch.front_m, ch.rear_m, ch.half_width_m)
raw = np.frombuffer(g.data, np.uint8).reshape(g.height, g.width)
h, w = raw.shape
pad = np.ones((h + h % 2, w + w % 2), bool)
pad[:h, :w] = raw == 255
unknown = pad.reshape(pad.shape[0] // 2, 2, pad.shape[1] // 2, 2).all(axis=(1, 3))
gm = GridMap.from_msg(g).coarsened(2)
for k in (1.0, 2.0, 3.0, 4.0, 6.0):
    fld = NavField(gm, fp)
    fld.speed = np.where(unknown, fld.speed / k, fld.speed)
    ctg = fld.cost_to_go(8.0, 7.5)
    assert ctg is not None
    phi = ctg.at(gm, np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]))
    desc = math.degrees(float(ctg.descent(gm, np.array([0.0, 0.0]))))
    print(f"unknown x{k:g}: phi at x 0/1/2 m {np.round(phi, 2)}, descent at start {desc:.0f}°")
