"""E-stop node: holds the latch, repeats it at 10 Hz, serves release requests.

The gateway holds neutral while the latch is set and also when this heartbeat is missing, so a
dead e-stop service stops the chair instead of silently disabling the e-stop. Decisions are in
`core`: this node only wires Zenoh (keys.ESTOP_ASSERT latches, keys.ESTOP_CLEAR clears one
source's cause, the keys.ESTOP_RELEASE query releases) and the state file.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from pathlib import Path

import msgspec

from autochair.runtime import Node, service_main
from autochair_msgs import EStopAssert, EStopRelease, EStopReply, keys

from .core import EStopCore


class EStopConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    rate_hz: float = 10.0
    # Where the latch survives a restart of this service ("" = not kept).
    state_file: str = ""


def _write_atomic(path: Path, data: bytes) -> None:
    """Write `data` to `path` through a temporary file and a rename (fsynced: latch changes
    are rare and must survive a power cut)."""
    tmp = path.with_name(path.name + ".tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    try:
        os.write(fd, data)
        os.fsync(fd)
    finally:
        os.close(fd)
    tmp.replace(path)


def start(node: Node, cfg: EStopConfig) -> None:
    core = EStopCore()
    lock = threading.Lock()
    path = Path(cfg.state_file) if cfg.state_file else None
    if path is not None:
        saved: bytes | None = None
        read_error = ""
        try:
            saved = path.read_bytes()
        except FileNotFoundError:
            pass
        except OSError as e:
            read_error = f"{type(e).__name__}: {e}"
        warning = core.restore(saved, read_error, time.time_ns())
        if warning:
            node.event("warning", f"{warning} ({path})")
    pub = node.publisher(keys.ESTOP_STATE)

    def publish() -> None:
        with lock:
            state = core.state(time.time_ns())
            node.health.state, node.health.detail = core.health()
        pub.put(state)

    def save() -> None:
        """Persist the latch (call with `lock` held); a failure is a fault, never silent."""
        if path is None:
            return
        before = core.persist_error
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            _write_atomic(path, msgspec.json.encode(core.state(time.time_ns())))
        except OSError as e:
            core.persist_error = f"{path}: {type(e).__name__}: {e.strerror or e}"
            node.health.count("save_errors")
            if core.persist_error != before:
                node.event("error", f"e-stop state cannot be saved ({core.persist_error}): "
                                    "the latch would not survive a restart")
        else:
            core.persist_error = ""
            if before:
                node.event("info", f"e-stop state saved again to {path}")
        node.health.state, node.health.detail = core.health()

    def on_assert(msg: EStopAssert) -> None:
        node.health.count("assert_msgs")
        with lock:
            changed = core.latch(msg.source, msg.reason, msg.active, time.time_ns())
            if changed:
                save()
        if changed:
            kind = "asserted" if msg.active else "pressed"
            node.event("error", f"e-stop {kind} by {msg.source}: {msg.reason}")
            node.health.count("asserts")
            publish()

    def on_clear(msg: EStopAssert) -> None:
        node.health.count("clear_msgs")
        with lock:
            changed = core.clear(msg.source)
            if changed:
                save()
        if changed:
            node.event("info", f"e-stop cause of {msg.source} cleared: {msg.reason}")
            node.health.count("clears")
            publish()

    def on_release(req: EStopRelease) -> EStopReply:
        with lock:
            error = core.release()
            if not error:
                save()
            latched = core.latched
        node.event("warning" if error else "info",
                   f"e-stop release by {req.by}: {error or 'released'}")
        publish()
        return EStopReply(ok=not error, latched=latched, error=error)

    with lock:
        save()  # at once: a state directory that cannot be written is reported before a latch
    node.subscribe(keys.ESTOP_ASSERT, on_assert)
    node.subscribe(keys.ESTOP_CLEAR, on_clear)
    node.serve(keys.ESTOP_RELEASE, on_release)
    node.every(1.0 / cfg.rate_hz, publish, "state")


def main(argv: list[str] | None = None) -> int:
    return service_main("estop", EStopConfig, start, argv, __doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
