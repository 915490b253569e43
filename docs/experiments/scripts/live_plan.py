"""The live control node's planning cycle times while it drives goals in the simulated stack
(real processes, the live map from the mapping service; session 20, issue 12).

Splits NavPlan.plan_ms into the first cycles on a new navigation field (the map changed) and
the rest; prints the map thread's time per field (health nav_field_ms / nav_fields).

Run from the worktree with an ABSOLUTE PYTHONPATH (the services it launches inherit it):
    PYTHONPATH=$PWD/services:$PWD/schemas:$PWD python docs/experiments/scripts/live_plan.py
"""

from __future__ import annotations

import json
import math
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np
from tests.helpers import Recorder, client_session, goal_ready, make_stack, wait_for

from autochair.launcher import free_port
from autochair.runtime.client import request
from autochair_msgs import GoalReply, GoalRequest, Pose2D, keys

STACK = ["router", "estop", "sim", "gateway", "odometry", "pid", "lidar-sim", "lidar",
         "mapping", "control"]
GOALS = [(4.5, 3.0, 90), (12.4, 2.5, 90), (8.5, -2.3, -90), (20.9, 0.5, 0)]  # default hallway


def stats(xs: list[float]) -> str:
    if not xs:
        return "n=0"
    return (f"n={len(xs)} median={statistics.median(xs):.1f} "
            f"p95={float(np.percentile(xs, 95)):.1f} max={max(xs):.1f} ms")


def main() -> int:
    hub = f"tcp/127.0.0.1:{free_port()}"
    run = Path(tempfile.mkdtemp(prefix="live_plan-"))
    stack = make_stack(STACK, hub, run)
    stack.start(ready_timeout_s=30)
    session = client_session(hub)
    try:
        plans = Recorder(session, keys.NAV_PLAN)
        status = Recorder(session, keys.GOAL_STATUS)
        health = Recorder(session, keys.HEALTH, keys.HEALTH.for_service("control"))
        wait_for(lambda: (lambda h: h is not None and h.counters.get("grids", 0) >= 1)(
            health.latest()), 30, "the live map at the control service")
        ends = []
        for x, y, yaw in GOALS:
            goal_ready(session)
            reply = request(session, keys.GOAL_SET, GoalRequest(
                waypoints=[Pose2D(x, y, math.radians(yaw))]), GoalReply, timeout_s=10)
            if not reply.ok:
                ends.append(f"({x}, {y}) refused: {reply.error}")
                continue
            gid = reply.goal_id
            wait_for(lambda g=gid: any(s.goal_id == g and s.state not in (  # type: ignore[misc]
                "planning", "driving", "blocked") for s in status.messages()), 120, "goal end")
            last = [s for s in status.messages() if s.goal_id == gid][-1]
            ends.append(f"({x}, {y}) {last.state} {last.reason}")
        h = health.latest().counters
        msgs = plans.messages()
        new = [m.plan_ms for m in msgs if m.new_field]
        rest = [m.plan_ms for m in msgs if not m.new_field]
        print("\n".join(ends))
        print("all cycles      ", stats(new + rest))
        print("new-field cycles", stats(new))
        print("other cycles    ", stats(rest))
        for state in sorted({m.state for m in msgs}):  # (blocked cycles plan more: give_up, ...)
            print(f"{state:8} new-field", stats([m.plan_ms for m in msgs
                                                 if m.state == state and m.new_field]))
            print(f"{state:8} other    ", stats([m.plan_ms for m in msgs
                                                 if m.state == state and not m.new_field]))
        n = h.get("nav_fields", 0)
        print(f"map thread: {n} fields, {h.get('nav_field_ms', 0) / max(n, 1):.1f} ms per field; "
              f"{h.get('new_fields_warm', 0)} new-field cycles found their costs-to-go made")
        out = run / "plans.json"
        out.write_text(json.dumps({"plans": [(m.plan_ms, m.new_field, m.state) for m in msgs],
                                   "counters": h}))
        print("raw:", out)
    finally:
        session.close()
        stack.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
