"""`autochair estop [REASON]` latches the e-stop; `autochair release` asks to clear it."""

from __future__ import annotations

import argparse
import getpass
import socket
import time
from typing import Any

from autochair.cli import CliError
from autochair.remote import add_link_args


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "estop", help="latch the e-stop: the chair holds neutral until released")
    p.add_argument("reason", nargs="?", default="operator", help="why (shown to everyone)")
    add_link_args(p)
    p.set_defaults(func=run_estop)
    r: argparse.ArgumentParser = sub.add_parser(
        "release", help="release the e-stop (refused while a cause remains)")
    add_link_args(r)
    r.set_defaults(func=run_release)


def _who() -> str:
    return f"{getpass.getuser()}@{socket.gethostname()}"


def run_estop(args: argparse.Namespace) -> int:
    import msgspec

    from autochair.remote import open_session
    from autochair.runtime.client import subscribe
    from autochair_msgs import EStopAssert, EStopState, keys

    session = open_session(args)
    try:
        states: list[EStopState] = []
        subscribe(session, keys.ESTOP_STATE, states.append)
        msg = EStopAssert(stamp_ns=time.time_ns(), source=f"cli:{_who()}", reason=args.reason)
        pub = session.declare_publisher(keys.ESTOP_ASSERT.key)
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline and not (states and states[-1].latched):
            pub.put(msgspec.msgpack.encode(msg))  # repeated until confirmed: a lost sample
            time.sleep(0.1)                       # must not leave the chair moving
        if not (states and states[-1].latched):
            raise CliError("no e-stop service confirmed the latch (is it running? "
                           "`autochair status`)")
        # A person's press is a button, not a lasting condition: the latch stays, but this
        # cause is not "still active", so an explicit release can clear it.
        pub.put(msgspec.msgpack.encode(msgspec.structs.replace(msg, active=False)))
        print(f"e-stop LATCHED ({args.reason}); `autochair release` to clear")
    finally:
        session.close()
    return 0


def run_release(args: argparse.Namespace) -> int:
    import msgspec

    from autochair.remote import open_session
    from autochair_msgs import EStopRelease, EStopReply, keys

    session = open_session(args)
    try:
        replies = list(session.get(keys.ESTOP_RELEASE.key,
                                   payload=msgspec.msgpack.encode(EStopRelease(by=_who())),
                                   timeout=3.0))
        ok = [r.ok for r in replies if r.ok is not None]
        if not ok:
            raise CliError("no e-stop service answered (is it running? `autochair status`)")
        reply = msgspec.msgpack.decode(ok[0].payload.to_bytes(), type=EStopReply)
        if not reply.ok:
            raise CliError(f"release {reply.error}")
        print("e-stop released")
    finally:
        session.close()
    return 0
