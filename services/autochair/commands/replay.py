"""`autochair replay FILE [--rate R] [--loop] [--namespace NS]`: republish a recording onto its
Zenoh keys with the original timing (scaled by R), as the msgpack bytes the services consume.

A replay publishes into its own namespace, "replay" by default (every key as
replay/autochair/..., the keys a stack started with `--chair replay` uses), never into a live
chair's unless asked: `--namespace NAME` (or `--chair NAME`) replays into chair NAME's keys, and
`--namespace ''` onto the keys of a chair without a namespace. A replay never moves a chair:
while a drive-chain service (gateway, pid) is alive in the namespace it publishes into, it is
refused, before the first message and at any moment during the replay."""

from __future__ import annotations

import argparse
import contextlib
import sys
import threading
import time
from typing import TYPE_CHECKING, Any

from autochair.cli import CliError
from autochair.commands.link import add_link_args

if TYPE_CHECKING:
    import zenoh

DEFAULT_NAMESPACE = "replay"  # a replay's own namespace: no chair's keys


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
    p.add_argument("--namespace", metavar="NS", default=None,
                   help=f"publish into chair NS's namespace, every key as NS/<key> (default "
                   f"{DEFAULT_NAMESPACE!r}, where no chair runs: e.g. "
                   f"{DEFAULT_NAMESPACE}/autochair/odom; '' = the keys of a chair without a "
                   "namespace); refused while a drive-chain service is alive there")
    add_link_args(p, what="replay into chair NAME", default="--namespace; never "
                  "$AUTOCHAIR_CHAIR")
    p.add_argument("--quiet", action="store_true", help="no progress line")
    p.set_defaults(func=run)


class DriveChainWatch:
    """Drive-chain liveliness tokens seen on the bus, now and whenever one appears."""

    QUERY_S = 3.0  # the liveliness query; one that does not finish by then fails closed

    def __init__(self, session: zenoh.Session) -> None:
        from autochair.logger import replay
        from autochair.runtime.client import alive_services, watch_alive

        self.alive: set[str] = set()
        self.unsure = ""  # why the bus could not be checked (then replay is refused)
        self.appeared = threading.Event()
        self._lock = threading.Lock()

        # Ask the hub first: once this session has a liveliness subscriber, zenoh answers a
        # query from the session's own (still filling) token cache, often empty (seen).
        t0 = time.monotonic()
        names = alive_services(session, self.QUERY_S)
        if time.monotonic() - t0 >= self.QUERY_S:
            self.unsure = f"the liveliness query did not finish within {self.QUERY_S:g} s"
            self.appeared.set()
        self._add(replay.drive_chain_alive(names))

        def on_token(service: str, alive: bool) -> None:
            if alive:
                self._add(replay.drive_chain_alive([service]))

        # Then watch, with the tokens already there (one that appeared since the query).
        self._sub = watch_alive(session, on_token)

    def _add(self, names: list[str]) -> None:
        if names:
            with self._lock:
                self.alive.update(names)
            self.appeared.set()

    def refusal(self) -> str:
        from autochair.logger import replay

        with self._lock:
            alive = sorted(self.alive)
        if alive:
            return replay.refusal(alive)
        return (f"cannot tell whether a drive-chain service is alive ({self.unsure}), and a "
                "recording could act on a live chair; replay under another namespace instead "
                "(--namespace NAME publishes NAME/autochair/...)")

    def close(self) -> None:
        import zenoh

        with contextlib.suppress(zenoh.ZError):
            self._sub.undeclare()


def target_namespace(args: argparse.Namespace) -> str:
    """The namespace this replay publishes into: --namespace, else --chair, else "replay"
    (never $AUTOCHAIR_CHAIR: a replay reaches a chair's keys only when asked on its line)."""
    from autochair.runtime.config import ConfigError, check_chair

    chosen = {n for n in (args.namespace, args.chair) if n is not None}
    if len(chosen) > 1:
        raise CliError(f"--namespace {args.namespace!r} and --chair {args.chair!r} disagree: "
                       "give one")
    namespace = chosen.pop() if chosen else DEFAULT_NAMESPACE
    try:
        return namespace and check_chair(namespace, "--namespace")
    except ConfigError as e:
        raise CliError(str(e)) from None


def run(args: argparse.Namespace) -> int:
    import zenoh

    from autochair.commands.link import tool_session
    from autochair.logger import replay
    from autochair.logger.reader import Recording
    from autochair.runtime.client import Publisher
    from autochair_msgs import keys

    if not args.rate > 0:
        raise CliError("--rate must be > 0")
    namespace = target_namespace(args)
    try:
        wanted = [zenoh.KeyExpr(k.strip()) for k in args.keys.split(",")] if args.keys else []
    except zenoh.ZError as e:
        raise CliError(f"--keys: {e}") from None
    try:
        rec = Recording(args.file)
    except FileNotFoundError as e:
        raise CliError(str(e)) from None
    total_s = rec.summary().duration_s / args.rate if not args.quiet else 0.0
    # The session is in `namespace` (Zenoh's own): every key it publishes and every liveliness
    # token it watches is NAMESPACE/autochair/..., so the watch guards exactly where it
    # publishes.
    session = tool_session(args, chair=namespace)
    pubs: dict[str, Publisher] = {}
    allowed: dict[str, bool] = {}  # key → matches --keys
    watch = DriveChainWatch(session)
    stop = watch.appeared

    def refuse() -> CliError:
        where = (f" (this replay publishes into namespace {namespace!r}: that chair's)"
                 if namespace else "")
        return CliError(watch.refusal() + where)

    try:
        if stop.is_set():
            raise refuse()
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
                    stop.wait(delay)  # wakes at once when a drive-chain service appears
                if stop.is_set():
                    if not args.quiet:
                        print(file=sys.stderr)
                    raise refuse()
                pub = pubs.get(item.key)
                if pub is None:
                    # Reliable: a replay must not silently drop what it was asked to publish.
                    pub = pubs[item.key] = Publisher(session, keys.by_key(item.key), item.key,
                                                     express=True, reliable=True)
                pub.put_raw(item.payload)
                n += 1
                now = time.monotonic()
                if not args.quiet and now >= next_progress:
                    next_progress = now + 1.0
                    print(f"\rreplay {now - start:7.1f} / {total_s:.1f} s  {n} messages",
                          end="", file=sys.stderr, flush=True)
            if not args.quiet:
                print(f"\rreplayed {n} messages in {time.monotonic() - start:.1f} s"
                      + (f" under {namespace}/" if namespace else "")
                      + (f"; skipped {sum(skipped.values())} of unknown keys {sorted(skipped)}"
                         if skipped else ""), file=sys.stderr)
            if rec.error:
                print(f"note: recording ends at a torn record ({rec.error})", file=sys.stderr)
            if not args.loop:
                return 0
    finally:
        watch.close()
        for p in pubs.values():
            p.undeclare()
        session.close()
