"""`autochair goal X Y YAW_DEG` / `autochair goal --waypoints FILE`: drive to a pose.

Poses are x forward, y left, metres; yaw in DEGREES, counter-clockwise (people think in
degrees; the wire uses radians), in the `map` frame when a localization service is running (the
map it loaded or builds; Foxglove's display frame), else in `odom` (REP-105; its origin is where
the chair started); `--frame` chooses. A goal in `map` is driven only while localization is
tracking: the chair stops and says why when it is lost.
Waypoints file: one `x, y, yaw_deg` per line (CSV), `#` comments and blank lines ignored; the
chair passes through the intermediate ones without stopping and stops at the last.
Shows progress until arrival; Ctrl-C cancels the goal.
"""

from __future__ import annotations

import argparse
import math
import sys
import threading
import time
from pathlib import Path
from typing import Any

from autochair.cli import CliError
from autochair.commands.link import add_link_args


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "goal", help="drive to a pose X Y YAW_DEG (or --waypoints FILE)",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("pose", nargs="*", type=float, metavar="X Y YAW_DEG",
                   help="goal pose: metres, metres, degrees")
    p.add_argument("--waypoints", metavar="FILE", help="CSV file of x, y, yaw_deg lines")
    p.add_argument("--tolerance-cm", type=float, default=5.0, help="position tolerance, cm")
    p.add_argument("--tolerance-deg", type=float, default=3.0, help="heading tolerance, °")
    p.add_argument("--vmax", type=float, default=None, help="speed limit for this goal, m/s")
    p.add_argument("--frame", choices=("auto", "map", "odom"), default="auto",
                   help="frame of the poses (auto: map when localization runs, else odom)")
    p.add_argument("--no-wait", action="store_true", help="set the goal and return")
    add_link_args(p)
    p.set_defaults(func=run)


def read_waypoints(path: str) -> list[tuple[float, float, float]]:
    """(x m, y m, yaw °) rows of a waypoints file; CliError naming the bad line."""
    try:
        text = Path(path).read_text()
    except OSError as e:
        raise CliError(f"cannot read {path}: {e.strerror}") from None
    rows: list[tuple[float, float, float]] = []
    for n, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = [p.strip() for p in line.split(",")]
        try:
            x, y, yaw = (float(p) for p in parts)
        except ValueError:
            raise CliError(f"{path}:{n}: want 'x, y, yaw_deg', got {line!r}") from None
        rows.append((x, y, yaw))
    if not rows:
        raise CliError(f"{path}: no waypoints")
    return rows


def run(args: argparse.Namespace) -> int:

    from autochair.commands.link import tool_session
    from autochair.runtime.client import alive_services, request, subscribe
    from autochair_msgs import GoalReply, GoalRequest, GoalStatus, Pose2D, keys

    if args.waypoints and args.pose:
        raise CliError("give either X Y YAW_DEG or --waypoints FILE, not both")
    if args.waypoints:
        rows = read_waypoints(args.waypoints)
    elif len(args.pose) == 3:
        rows = [(args.pose[0], args.pose[1], args.pose[2])]
    else:
        raise CliError("want X Y YAW_DEG (metres, metres, degrees) or --waypoints FILE")
    session = tool_session(args)
    try:
        frame = args.frame
        if frame == "auto":
            frame = "map" if "localization" in alive_services(session) else "odom"
        req = GoalRequest(waypoints=[Pose2D(x, y, math.radians(yaw)) for x, y, yaw in rows],
                          tolerance_m=args.tolerance_cm / 100.0,
                          tolerance_rad=math.radians(args.tolerance_deg), vmax_mps=args.vmax,
                          frame_id=frame)
        status: list[GoalStatus] = []
        cond = threading.Condition()

        def on_status(msg: GoalStatus) -> None:
            with cond:
                status.append(msg)
                cond.notify()

        sub = subscribe(session, keys.GOAL_STATUS, on_status)
        reply = request(session, keys.GOAL_SET, req, GoalReply)
        if not reply.ok:
            raise CliError(f"goal rejected: {reply.error}")
        print(f"goal {reply.goal_id} set: {len(rows)} waypoint(s), last "
              f"({rows[-1][0]:.2f} m, {rows[-1][1]:.2f} m, {rows[-1][2]:.1f}°) in {frame}",
              flush=True)
        if args.no_wait:
            sub.undeclare()
            return 0
        try:
            return _follow(reply.goal_id, status, cond)
        except KeyboardInterrupt:
            request(session, keys.GOAL_CANCEL, GoalRequest(waypoints=[]), GoalReply)
            print("\ncancelled", flush=True)
            return 130
        finally:
            sub.undeclare()
    finally:
        session.close()


ACTIVE_STATES = ("planning", "driving", "blocked")  # the control service's goal states


def status_line(s: Any) -> str:
    """One progress line: the state, then distance and ETA, or what blocks the chair."""
    if s.state == "planning":
        return "planning"
    where = (f"waypoint {s.waypoint_index + 1}/{s.waypoint_count}  "
             f"{s.distance_left_m:6.2f} m left")
    if s.state == "blocked":
        return f"BLOCKED  {where}  {s.reason}"
    return f"driving  {where}  ETA {s.eta_s:5.1f} s"


def _follow(goal_id: int, status: list[Any], cond: threading.Condition) -> int:
    tty = sys.stdout.isatty()
    last_print = 0.0
    shown = ""
    last_seen = time.monotonic()
    while True:
        with cond:
            cond.wait_for(lambda: bool(status), timeout=1.0)
            batch, status[:] = list(status), []
        now = time.monotonic()
        mine = [s for s in batch if s.goal_id == goal_id]
        if not mine:
            if now - last_seen > 3.0:
                raise CliError("no goal status for 3 s: lost contact with the control service")
            continue
        last_seen = now
        s = mine[-1]
        if s.state in ACTIVE_STATES:
            if tty or now - last_print >= 1.0 or s.state != shown:
                line = status_line(s)
                print(("\r" + line.ljust(100)) if tty else line, end="" if tty else "\n",
                      flush=True)
                last_print, shown = now, s.state
            continue
        if tty:
            print()
        if s.state == "arrived":
            print(f"arrived (goal {goal_id})", flush=True)
            return 0
        if s.state == "cancelled":
            print(f"goal {goal_id} cancelled", flush=True)
            return 1
        raise CliError(f"goal {goal_id} {s.state}: {s.reason}")
