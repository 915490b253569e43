"""`autochair estop [REASON]` latches the e-stop (a momentary press); `autochair release` asks to
clear it; `autochair estop --clear SOURCE` (a services identity on the chair) reports that
SOURCE's cause has cleared."""

from __future__ import annotations

import argparse
import getpass
import socket
import time
from typing import TYPE_CHECKING, Any

from autochair.cli import CliError
from autochair.commands.link import add_link_args

if TYPE_CHECKING:
    import zenoh

    from autochair_msgs import EStopCause, EStopState

CONFIRM_S = 3.0  # how long a press or clear is repeated until the e-stop service shows it


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "estop", help="latch the e-stop: the chair holds neutral until released",
        description="Press the e-stop: it latches, and `autochair release` clears it (refused "
        "while a service still holds its cause). --clear SOURCE: on the chair, as a "
        "services identity, report that SOURCE's cause has cleared (laptops may not).")
    p.add_argument("reason", nargs="?", default="operator", help="why (shown to everyone)")
    p.add_argument("--clear", metavar="SOURCE",
                   help="clear the cause held by SOURCE (e.g. safety); chair console only")
    add_link_args(p)
    p.set_defaults(func=run_estop)
    r: argparse.ArgumentParser = sub.add_parser(
        "release", help="release the e-stop (refused while a cause remains)")
    add_link_args(r)
    r.set_defaults(func=run_release)


def _who() -> str:
    return f"{getpass.getuser()}@{socket.gethostname()}"


def run_estop(args: argparse.Namespace) -> int:
    from autochair.commands.link import tool_session
    from autochair.runtime.client import Publisher, subscribe
    from autochair_msgs import EStopAssert, keys

    session = tool_session(args)
    try:
        states: list[EStopState] = []
        subscribe(session, keys.ESTOP_STATE, states.append)
        if args.clear:
            return _clear(session, states, args.clear)
        # A person's press is a button, not a lasting condition: it latches, with nothing left
        # to clear, so an explicit `autochair release` can clear it.
        source = f"cli:{_who()}"
        msg = EStopAssert(stamp_ns=time.time_ns(), source=source, reason=args.reason,
                          active=False)
        pub = Publisher(session, keys.ESTOP_ASSERT, reliable=True)

        def pressed() -> bool:
            return bool(states) and states[-1].latched and any(
                c.source == source for c in states[-1].causes)

        deadline = time.monotonic() + CONFIRM_S
        while time.monotonic() < deadline and not pressed():
            pub.put(msg)  # repeated until confirmed: a lost sample
            time.sleep(0.1)                       # must not leave the chair moving
        if not (states and states[-1].latched):
            raise CliError("no e-stop service confirmed the latch (is it running? "
                           "`autochair status`)")
        print(f"e-stop LATCHED ({args.reason}); `autochair release` to clear")
    finally:
        session.close()
    return 0


def _clear(session: zenoh.Session, states: list[EStopState], source: str) -> int:
    from autochair.runtime.client import Publisher
    from autochair_msgs import EStopAssert, keys

    def cause() -> EStopCause | None:
        return next((c for c in states[-1].causes if c.source == source), None)

    deadline = time.monotonic() + CONFIRM_S
    while not states and time.monotonic() < deadline:
        time.sleep(0.05)
    if not states:
        raise CliError("no e-stop service answered (is it running? `autochair status`)")
    first = cause()
    if first is None or not first.active:
        held = ", ".join(c.source for c in states[-1].causes if c.active) or "none"
        raise CliError(f"{source} holds no active e-stop cause (active causes: {held})")
    msg = EStopAssert(stamp_ns=time.time_ns(), source=source,
                      reason=f"cleared by hand by {_who()}", active=False)
    pub = Publisher(session, keys.ESTOP_CLEAR, reliable=True)
    deadline = time.monotonic() + CONFIRM_S
    while time.monotonic() < deadline and (c := cause()) is not None and c.active:
        pub.put(msg)
        time.sleep(0.1)
    c = cause()
    if c is not None and c.active:
        raise CliError(f"the cause of {source} was not cleared: only a services identity on "
                       "the chair may clear a cause (laptops are refused by the hub)")
    print(f"e-stop cause of {source} cleared ({first.reason}); the latch stays: "
          "`autochair release` to clear it")
    return 0


def run_release(args: argparse.Namespace) -> int:
    from autochair.commands.link import tool_session
    from autochair.runtime.client import request
    from autochair_msgs import EStopRelease, EStopReply, keys

    session = tool_session(args)
    try:
        reply = request(session, keys.ESTOP_RELEASE, EStopRelease(by=_who()), EStopReply)
        if not reply.ok:
            raise CliError(f"release {reply.error}")
        print("e-stop released")
    finally:
        session.close()
    return 0
