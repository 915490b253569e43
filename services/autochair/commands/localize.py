"""`autochair localize X Y YAW_DEG`: tell the localization service where the chair is on the
map (metres, metres, degrees counter-clockwise, in `map`); `autochair localize --global`: let
it search the whole map. Prints the state it reports: a pose given is a guess, checked
against the next scan (searched for within 2σ of it) before it is tracked."""

from __future__ import annotations

import argparse
import math
from typing import Any

from autochair.cli import CliError
from autochair.commands.link import add_link_args


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "localize", help="set the chair's pose on the map: X Y YAW_DEG (or --global)",
        description=__doc__)
    p.add_argument("pose", nargs="*", type=float, metavar="X Y YAW_DEG")
    p.add_argument("--global", dest="global_", action="store_true",
                   help="no pose: search the whole map")
    p.add_argument("--sigma-cm", type=float, default=30.0, help="uncertainty of X, Y (cm)")
    p.add_argument("--sigma-deg", type=float, default=10.0, help="uncertainty of YAW (°)")
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
    from autochair.commands.link import ask
    from autochair_msgs import LocalizeReply, keys

    req = request_of(args)
    reply = ask(args, keys.LOC_SET_POSE, req, LocalizeReply)
    what = ("the next scan is searched for near the pose given; tracked once it fits"
            if req.pose is not None else "the whole map is searched")
    print(f"localization: {reply.state} ({what}; `autochair status` shows it)", flush=True)
    return 0
