import time, sys
import bench.nav_eval as ne
from autochair.control.core import ControlConfig, ControlCore, OdomSample
from autochair.runtime.config import ChairGeometry
from autochair_msgs import GoalRequest, Pose2D
ch = ChairGeometry(); fp = ne.Footprint(ch.front_m, ch.rear_m, ch.half_width_m)
mon = sys.argv[1] == "1" if len(sys.argv) > 1 else True
for name, wname, start, goal, _ in ne.CASES:
    world, fld = ne.build(wname, fp)
    core = ControlCore(ControlConfig(), footprint=fp); core.on_field(fld)
    core.on_odom(OdomSample(*start, 0.0, 0.0, 0.0))
    if mon: core.on_limit(1.2, 1.0, "clear", 0.0)
    t0 = time.perf_counter(); r = core.set_goal(GoalRequest(waypoints=[Pose2D(*goal)]), 0.0); dt = time.perf_counter() - t0
    print(f"{name:40s} {'ok ' if r.ok else 'REFUSED'} {dt*1e3:6.0f} ms {r.error}")
