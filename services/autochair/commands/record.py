"""`autochair record [PATH]`: run the logger alone (every logged key to MCAP) until Ctrl-C."""

from __future__ import annotations

import argparse
import os
from typing import Any

from autochair.commands.link import add_chair_arg


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "record", help="record every logged key to MCAP (the logger alone)",
        description="Run the logger until Ctrl-C. PATH: a directory (one autochair-<UTC "
                    "time>.mcap per run) or a file ending in .mcap. An existing recording is "
                    "never overwritten: a taken name becomes NAME-1.mcap, NAME-2.mcap, ...")
    p.add_argument("path", nargs="?", default="recordings/", help="default: recordings/")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="other [logger] settings, e.g. max_size_mib=512; repeatable")
    p.add_argument("--config", help="TOML config file")
    p.add_argument("--connect", help="Zenoh endpoint(s) of the hub")
    add_chair_arg(p, "the chair to record")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from autochair.commands.link import chair_arg
    from autochair.logger.node import main
    from autochair.runtime.config import ENV_CHAIR

    chair = chair_arg(args)
    if chair is not None:  # the logger, as every service, joins $AUTOCHAIR_CHAIR's namespace
        os.environ[ENV_CHAIR] = chair

    argv = ["--set", f"path={args.path}"]
    for item in args.set:
        argv += ["--set", item]
    if args.config:
        argv += ["--config", args.config]
    if args.connect:
        argv += ["--connect", args.connect]
    return main(argv)
