"""`autochair deploy`: write deploy/ from the process list, or check it has not drifted."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from autochair.cli import CliError


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "deploy", help="generate or check deploy/ (compose, supervisord, systemd, zenoh)",
        description="deploy/ is generated from autochair/processes.py; never edit it by hand.")
    act = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    g = act.add_parser("generate", help="write the deploy files")
    g.add_argument("--out", default="deploy", help="output directory (default: deploy)")
    c = act.add_parser("check", help="fail if the files differ from what the list generates")
    c.add_argument("--dir", default="deploy", help="directory to check (default: deploy)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from autochair import deploy

    try:
        if args.action == "generate":
            for path in deploy.write(Path(args.out)):
                print(path)
            return 0
        bad = deploy.drift(Path(args.dir))
    except deploy.DeployError as e:
        raise CliError(str(e)) from None
    if bad:
        raise CliError(f"{args.dir} drifted from the process list: {', '.join(bad)} "
                       "(run `autochair deploy generate`)")
    print(f"{args.dir}: up to date")
    return 0
