"""`autochair replay FILE [--rate R] [--loop]`: republish a recording onto its Zenoh keys with
the original timing (scaled by R), as the msgpack bytes the services consume."""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

from autochair.cli import CliError
from autochair.remote import add_link_args


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "replay", help="republish a recording onto Zenoh with its original timing",
        description=__doc__ + " Derived foxglove.* channels are not republished.")
    p.add_argument("file", help="an .mcap recording")
    p.add_argument("--rate", type=float, default=1.0, help="speed factor (2 = twice as fast)")
    p.add_argument("--loop", action="store_true", help="start over at the end until Ctrl-C")
    p.add_argument("--keys", metavar="EXPR[,EXPR]",
                   help="replay only keys matching these Zenoh key expressions, e.g. "
                   "autochair/chair/encoders to re-run odometry and what follows on recorded "
                   "input (the re-run services then publish their own outputs)")
    add_link_args(p)
    p.add_argument("--quiet", action="store_true", help="no progress line")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import zenoh

    from autochair.logger import replay
    from autochair.logger.reader import Recording
    from autochair.remote import open_session

    if not args.rate > 0:
        raise CliError("--rate must be > 0")
    try:
        wanted = [zenoh.KeyExpr(k.strip()) for k in args.keys.split(",")] if args.keys else []
    except zenoh.ZError as e:
        raise CliError(f"--keys: {e}") from None
    try:
        rec = Recording(args.file)
    except FileNotFoundError as e:
        raise CliError(str(e)) from None
    total_s = rec.summary().duration_s / args.rate if not args.quiet else 0.0
    session = open_session(args)
    pubs: dict[str, zenoh.Publisher] = {}
    allowed: dict[str, bool] = {}  # key → matches --keys
    try:
        while True:
            skipped: dict[str, int] = {}
            n = 0
            start = time.monotonic()
            next_progress = start
            for item in replay.plan(rec.messages(), args.rate, skipped):
                if wanted:
                    if item.key not in allowed:
                        allowed[item.key] = any(w.intersects(zenoh.KeyExpr(item.key))
                                                for w in wanted)
                    if not allowed[item.key]:
                        continue
                delay = start + item.offset_s - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
                pub = pubs.get(item.key)
                if pub is None:
                    # BLOCK: a replay must not silently drop what it was asked to publish.
                    pub = pubs[item.key] = session.declare_publisher(
                        item.key, express=True,
                        congestion_control=zenoh.CongestionControl.BLOCK)
                pub.put(item.payload)
                n += 1
                now = time.monotonic()
                if not args.quiet and now >= next_progress:
                    next_progress = now + 1.0
                    print(f"\rreplay {now - start:7.1f} / {total_s:.1f} s  {n} messages",
                          end="", file=sys.stderr, flush=True)
            if not args.quiet:
                print(f"\rreplayed {n} messages in {time.monotonic() - start:.1f} s"
                      + (f"; skipped {sum(skipped.values())} of unknown keys {sorted(skipped)}"
                         if skipped else ""), file=sys.stderr)
            if rec.error:
                print(f"note: recording ends at a torn record ({rec.error})", file=sys.stderr)
            if not args.loop:
                return 0
    finally:
        for p in pubs.values():
            p.undeclare()
        session.close()
