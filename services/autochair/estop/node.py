"""E-stop node: holds the latch, repeats it at 10 Hz, serves release requests.

The gateway holds neutral while the latch is set and also when this heartbeat is missing, so a
dead e-stop service stops the chair instead of silently disabling the e-stop. Decisions are in
`core`: this node only wires Zenoh (keys.ESTOP_ASSERT latches, keys.ESTOP_CLEAR clears one
source's cause, the keys.ESTOP_RELEASE query releases) and the state file.
"""

from __future__ import annotations

import sys
import threading
import time
from pathlib import Path
from typing import Annotated

import msgspec

from autochair.files import write_atomic
from autochair.runtime import Node, service_main
from autochair_msgs import EStopAssert, EStopRelease, EStopReply, keys

from .core import EStopCore


class EStopConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    # The state heartbeat; the gateway holds neutral when it is older than [stale] estop_s.
    rate_hz: Annotated[float, msgspec.Meta(ge=2, le=100)] = 10.0
    # Where the latch survives a restart of this service ("" = not kept).
    state_file: str = ""


class StateFile:
    """Where the latch survives a restart: read once, written atomically and fsynced (latch
    changes are rare and must survive a power cut). I/O only; the core decides."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def read(self) -> tuple[bytes | None, str]:
        """(content or None when there is none, why it could not be read)."""
        try:
            return self.path.read_bytes(), ""
        except FileNotFoundError:
            return None, ""
        except OSError as e:
            return None, f"{type(e).__name__}: {e}"

    def write(self, data: bytes) -> str:
        """"" when written, else why not (one line)."""
        try:
            write_atomic(self.path, data)
        except OSError as e:
            return f"{self.path}: {type(e).__name__}: {e.strerror or e}"
        return ""


def start(node: Node, cfg: EStopConfig) -> None:
    latch = _Latch(node, StateFile(Path(cfg.state_file)) if cfg.state_file else None)
    with latch.lock:
        latch.save()  # at once: a state directory that cannot be written is reported first
    node.subscribe(keys.ESTOP_ASSERT, latch.on_assert)
    node.subscribe(keys.ESTOP_CLEAR, latch.on_clear)
    node.serve(keys.ESTOP_RELEASE, latch.on_release)
    node.every(1.0 / cfg.rate_hz, latch.publish, "state")


class _Latch:
    """EStopCore wired to Zenoh and the state file."""

    def __init__(self, node: Node, file: StateFile | None) -> None:
        self.node, self.file, self.core = node, file, EStopCore()
        self.lock = threading.Lock()
        self.pub = node.publisher(keys.ESTOP_STATE)
        if file is not None:
            warning = self.core.restore(*file.read(), time.time_ns())
            if warning:
                node.event("warning", f"{warning} ({file.path})")

    def publish(self) -> None:
        with self.lock:
            state = self.core.state(time.time_ns())
            self.node.health.state, self.node.health.detail = self.core.health()
        self.pub.put(state)

    def save(self) -> None:
        """Persist the latch (call with `lock` held)."""
        if self.file is None:
            return
        error = self.file.write(self.core.snapshot(time.time_ns()))
        if error:
            self.node.health.count("save_errors")
        news = self.core.saved(error)
        if news:
            self.node.event("error" if error else "info", news)
        self.node.health.state, self.node.health.detail = self.core.health()

    def on_assert(self, msg: EStopAssert) -> None:
        self.node.health.count("assert_msgs")
        with self.lock:
            changed = self.core.latch(msg.source, msg.reason, msg.active, time.time_ns())
            if changed:
                self.save()
        if changed:
            kind = "asserted" if msg.active else "pressed"
            self.node.event("error", f"e-stop {kind} by {msg.source}: {msg.reason}")
            self.node.health.count("asserts")
            self.publish()

    def on_clear(self, msg: EStopAssert) -> None:
        self.node.health.count("clear_msgs")
        with self.lock:
            changed = self.core.clear(msg.source)
            if changed:
                self.save()
        if changed:
            self.node.event("info", f"e-stop cause of {msg.source} cleared: {msg.reason}")
            self.node.health.count("clears")
            self.publish()

    def on_release(self, req: EStopRelease) -> EStopReply:
        with self.lock:
            error = self.core.release()
            if not error:
                self.save()
            latched = self.core.latched
        self.node.event("warning" if error else "info",
                        f"e-stop release by {req.by}: {error or 'released'}")
        self.publish()
        return EStopReply(ok=not error, latched=latched, error=error)


def main(argv: list[str] | None = None) -> int:
    return service_main("estop", EStopConfig, start, argv, __doc__ or "")


if __name__ == "__main__":
    sys.exit(main())
