"""E-stop node: holds the latch, repeats it at 10 Hz, serves release requests.

The gateway holds neutral while the latch is set and also when this heartbeat is missing, so a
dead e-stop service stops the chair instead of silently disabling the e-stop.
"""

from __future__ import annotations

import sys
import threading
import time
from pathlib import Path

import msgspec
import zenoh

from autochair.runtime import Node, service_main
from autochair_msgs import EStopAssert, EStopRelease, EStopReply, EStopState, keys

from .core import EStopCore


class EStopConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    rate_hz: float = 10.0
    # Where the latch survives a restart of this service ("" = not kept).
    state_file: str = ""


def start(node: Node, cfg: EStopConfig) -> None:
    core = EStopCore()
    lock = threading.Lock()
    path = Path(cfg.state_file) if cfg.state_file else None
    if path is not None and path.exists():
        try:
            saved = msgspec.json.decode(path.read_bytes(), type=EStopState)
            core.latched, core.causes = saved.latched, {c.source: c for c in saved.causes}
            if core.latched:
                node.event("warning", "e-stop restored LATCHED from " + str(path))
        except (msgspec.DecodeError, msgspec.ValidationError, OSError) as e:
            # An unreadable latch file reads as latched (the safe reading), releasable by hand.
            why = f"state file unreadable ({e})"
            core.assert_("estop", why, True, time.time_ns())
            core.assert_("estop", why, False, time.time_ns())
    pub = node.publisher(keys.ESTOP_STATE)

    def publish() -> None:
        with lock:
            state = core.state(time.time_ns())
        pub.put(state)
        node.health.detail = "LATCHED" if state.latched else "released"

    def save() -> None:
        if path is not None:
            tmp = path.with_suffix(".tmp")
            tmp.write_bytes(msgspec.json.encode(core.state(time.time_ns())))
            tmp.replace(path)

    def on_assert(msg: EStopAssert) -> None:
        with lock:
            changed = core.assert_(msg.source, msg.reason, msg.active, time.time_ns())
            if changed:
                save()
        if changed:
            verb = "asserted" if msg.active else "cause cleared"
            node.event("error" if msg.active else "info",
                       f"e-stop {verb} by {msg.source}: {msg.reason}")
            node.health.count("asserts" if msg.active else "clears")
            publish()

    req_dec = msgspec.msgpack.Decoder(EStopRelease)
    enc = msgspec.msgpack.Encoder()

    def on_release(query: zenoh.Query) -> None:
        try:
            payload = query.payload
            req = req_dec.decode(payload.to_bytes() if payload is not None else b"")
        except (msgspec.DecodeError, msgspec.ValidationError) as e:
            query.reply(query.key_expr, enc.encode(EStopReply(ok=False, latched=core.latched,
                                                              error=f"bad request: {e}")))
            return
        with lock:
            error = core.release()
            if not error:
                save()
            latched = core.latched
        node.event("warning" if error else "info",
                   f"e-stop release by {req.by}: {error or 'released'}")
        query.reply(query.key_expr, enc.encode(EStopReply(ok=not error, latched=latched,
                                                          error=error)))
        publish()

    node.subscribe(keys.ESTOP_ASSERT, on_assert)
    node.queryable(keys.ESTOP_RELEASE, on_release)
    node.every(1.0 / cfg.rate_hz, publish, "state")


def main(argv: list[str] | None = None) -> int:
    return service_main("estop", EStopConfig, start, argv, __doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
