"""`autochair info FILE [--recover OUT]`: channels, counts, rates and duration of a recording,
also of one whose writer was killed (no summary); --recover writes an indexed copy."""

from __future__ import annotations

import argparse
import datetime
from typing import Any

from autochair.cli import CliError


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "info", help="summarise a recording (channels, counts, rates, duration)",
        description=__doc__)
    p.add_argument("file", help="an .mcap recording")
    p.add_argument("--recover", metavar="OUT", help="write an indexed copy of FILE to OUT")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from autochair.logger.reader import Recording, Summary, recover

    try:
        if args.recover:
            summary: Summary = recover(args.file, args.recover)
            print(f"recovered {summary.count} messages into {args.recover} (indexed)")
        else:
            summary = Recording(args.file).summary()
    except FileExistsError:
        raise CliError(f"{args.recover} exists: --recover writes a new file and never "
                       "overwrites one (the recording itself included); pick another name") \
            from None
    except (FileNotFoundError, IsADirectoryError, PermissionError) as e:
        raise CliError(str(e)) from None
    except Exception as e:  # not an MCAP at all (bad magic)
        raise CliError(f"{args.file}: not a readable MCAP file ({type(e).__name__}: {e})") \
            from None
    print_summary(summary)
    return 0


def print_summary(s: Any) -> None:
    start = datetime.datetime.fromtimestamp(s.start_ns / 1e9, datetime.UTC)
    print(f"file:      {s.path}")
    print("state:     " + ("complete (indexed)" if s.indexed else
                           "no summary: writer did not finish (killed?); read front to back"))
    if s.error:
        print(f"           stopped at a torn record ({s.error}); everything before it is listed")
    print(f"start:     {start:%Y-%m-%d %H:%M:%S.%f} UTC" if s.count else "start:     -")
    print(f"duration:  {s.duration_s:.3f} s")
    print(f"messages:  {s.count}")
    width = max([len(c.topic) for c in s.channels.values()] + [7])
    print(f"\n{'channel':<{width}}  {'count':>8}  {'rate Hz':>8}  schema")
    for c in sorted(s.channels.values(), key=lambda c: (c.derived, c.topic)):
        print(f"{c.topic:<{width}}  {c.count:>8}  {c.rate_hz:>8.1f}  {c.schema}")
