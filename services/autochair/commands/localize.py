"""`autochair localize X Y YAW_DEG`: tell the localization service where the chair is on the
map (metres, metres, degrees counter-clockwise, in `map`); `autochair localize --global`: let
it search the whole map. A pose given is a guess, checked against the next scan (searched for
within 2σ of it) before it is tracked. Waits for the outcome: the pose tracked and how far it
is from the guess, or, after --wait seconds, what the service reports instead (exit 1)."""

from __future__ import annotations

import argparse
import math
import queue
import time
from typing import TYPE_CHECKING, Any

from autochair.cli import CliError
from autochair.commands.link import add_link_args

if TYPE_CHECKING:
    from autochair_msgs import LocalizedPose, Pose2D


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "localize", help="set the chair's pose on the map: X Y YAW_DEG (or --global)",
        description=__doc__)
    p.add_argument("pose", nargs="*", type=float, metavar="X Y YAW_DEG")
    p.add_argument("--global", dest="global_", action="store_true",
                   help="no pose: search the whole map")
    p.add_argument("--sigma-cm", type=float, default=30.0, help="uncertainty of X, Y (cm)")
    p.add_argument("--sigma-deg", type=float, default=10.0, help="uncertainty of YAW (°)")
    p.add_argument("--wait", type=float, default=10.0,
                   help="seconds to wait for the outcome (default 10)")
    add_link_args(p)
    p.set_defaults(func=run)


def request_of(args: argparse.Namespace) -> Any:
    from autochair_msgs import LocalizeRequest, Pose2D

    if args.global_ == bool(args.pose):
        raise CliError("want X Y YAW_DEG (metres, metres, degrees) or --global")
    if args.global_:
        return LocalizeRequest(pose=None)
    if len(args.pose) != 3 or not all(math.isfinite(v) for v in args.pose):
        raise CliError("want X Y YAW_DEG: three finite numbers")
    x, y, yaw = args.pose
    return LocalizeRequest(pose=Pose2D(x, y, math.radians(yaw)),
                           sigma_xy_m=args.sigma_cm / 100, sigma_yaw_rad=math.radians(
                               args.sigma_deg))


def run(args: argparse.Namespace) -> int:
    from autochair.commands.link import tool_session
    from autochair.runtime.client import request, subscribe
    from autochair_msgs import LocalizeReply, keys

    req = request_of(args)
    poses: queue.Queue[LocalizedPose] = queue.Queue()
    session = tool_session(args)
    try:
        sub = subscribe(session, keys.LOC_POSE, poses.put)
        try:
            reply = request(session, keys.LOC_SET_POSE, req, LocalizeReply)
            if not reply.ok:
                raise CliError(reply.error)
            print(f"localization: {reply.state} ("
                  + ("searching near the pose given" if req.pose is not None
                     else "searching the whole map") + ")", flush=True)
            return _outcome(poses, args.wait, req.pose)
        finally:
            sub.undeclare()
    finally:
        session.close()


def _outcome(poses: queue.Queue[LocalizedPose], wait_s: float, guess: Pose2D | None) -> int:
    """The first pose the localization reports tracking within `wait_s`: printed with its
    distance from the guess; else what it reports instead (exit 1)."""
    deadline, last = time.monotonic() + wait_s, None
    while (left := deadline - time.monotonic()) > 0:
        try:
            last = poses.get(timeout=left)
        except queue.Empty:
            break
        if last.state == "tracking":
            off = ("" if guess is None else
                   f", {100 * math.hypot(last.x_m - guess.x_m, last.y_m - guess.y_m):.0f} cm "
                   "from the pose given")
            print(f"localization: tracking at ({last.x_m:.2f} m, {last.y_m:.2f} m, "
                  f"{math.degrees(last.yaw_rad):.1f}°), quality {last.quality:.2f}{off}",
                  flush=True)
            return 0
    print(f"localization: not tracking after {wait_s:g} s ("
          + (f"{last.state}, quality {last.quality:.2f}" if last else "no pose reported")
          + "; it goes on searching)", flush=True)
    return 1
