"""`autochair`: the one command for people. Each subcommand lives in autochair.commands.<name>
and registers itself; keep heavy imports inside the handlers so `--help` stays fast."""

from __future__ import annotations

import argparse
import importlib
import os
import sys

COMMANDS = ("up", "drive", "status", "estop", "deploy", "certs", "monitor", "teleop", "foxglove",
            "record", "replay", "info", "report", "goal", "cancel", "health", "map", "localize",
            "tune")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="autochair", description=__doc__.split(".")[0])
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f"autochair.commands.{name}").register(sub)
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # `autochair info FILE | head`: the reader has gone; no traceback for that, and none
        # from the interpreter flushing stdout at exit either.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except CliError as e:
        print(f"autochair {args.command}: error: {e}", file=sys.stderr)
        return 2
    except Exception as e:
        from autochair.runtime.client import RequestError  # (zenoh: not at --help time)

        if not isinstance(e, RequestError):
            raise
        print(f"autochair {args.command}: error: {e}", file=sys.stderr)
        return 2


class CliError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


if __name__ == "__main__":
    # Run through the real module so CliError is the class the commands raise.
    from autochair.cli import main as _main

    sys.exit(_main())
