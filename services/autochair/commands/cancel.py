"""`autochair cancel`: cancel the active goal (the chair brakes smoothly to a stop)."""

from __future__ import annotations

import argparse
from typing import Any

from autochair.commands.link import add_link_args


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser("cancel", help="cancel the active goal",
                                                description=__doc__)
    add_link_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from autochair.commands.link import ask
    from autochair_msgs import GoalReply, GoalRequest, keys

    reply = ask(args, keys.GOAL_CANCEL, GoalRequest(waypoints=[]), GoalReply)
    print(f"goal {reply.goal_id} cancelled" if reply.goal_id else "no active goal", flush=True)
    return 0
