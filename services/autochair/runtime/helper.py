"""One helper process for calls that hold the interpreter lock (nav/gil.py).

While such a call runs in the service's own process, no other thread of it runs: the control
service's 50 Hz command stream stalled past the velocity PID's stale limit during a lattice
search. Made here, the call costs its arguments' pickling (about a millisecond per MB) and the
calling thread waits on a pipe without the lock, so the rest of the service goes on.

A plain child interpreter on two pipes, not multiprocessing: its forkserver, resource tracker
and pool worker outlived a SIGKILLed parent (measured). This child dies with its parent
(PR_SET_PDEATHSIG) and at the end of its input.
"""

from __future__ import annotations

import ctypes
import importlib
import os
import pickle
import subprocess
import sys
import threading
from collections.abc import Callable
from typing import IO, Any, TypeVar

T = TypeVar("T")

PR_SET_PDEATHSIG = 1


class HelperDied(RuntimeError):
    pass


def _send(stream: IO[bytes], obj: object) -> None:
    """`obj` pickled with its arrays' memory out of band, written to the pipe as it is: the
    writes release the interpreter lock, where pickling a 41 MB lattice graph in band held it
    for 70-90 ms (measured) in the caller, whose other threads then stood still."""
    buffers: list[pickle.PickleBuffer] = []
    data = pickle.dumps(obj, protocol=5, buffer_callback=buffers.append)
    raws = [b.raw() for b in buffers]
    stream.write(b"".join(n.to_bytes(8, "little") for n in (len(data), len(raws),
                                                             *(r.nbytes for r in raws))))
    stream.write(data)
    for raw in raws:
        stream.write(raw)
    stream.flush()


def _read_into(stream: IO[bytes], n: int) -> bytearray:
    out = bytearray(n)
    view, got = memoryview(out), 0
    while got < n:
        k = stream.readinto(view[got:])  # type: ignore[attr-defined]
        if not k:
            raise EOFError("the helper process's pipe closed")
        got += k
    return out


def _receive(stream: IO[bytes]) -> Any:
    def number() -> int:
        return int.from_bytes(_read_into(stream, 8), "little")

    n, k = number(), number()
    sizes = [number() for _ in range(k)]
    data = _read_into(stream, n)
    return pickle.loads(data, buffers=[_read_into(stream, size) for size in sizes])


class HelperProcess:
    """`helper(fn, *args, **kwargs)`: `fn(*args, **kwargs)` made in one helper process, with
    `preload` imported when it starts; one call at a time, callers queued (without the lock).
    A helper that died (killed, out of memory) is started again, `on_restart` told, and the
    call made once more."""

    def __init__(self, preload: tuple[str, ...] = (),
                 on_restart: Callable[[], None] = lambda: None) -> None:
        self._preload, self._on_restart = preload, on_restart
        self._lock = threading.Lock()
        self._proc = self._start()

    def _start(self) -> subprocess.Popen[bytes]:
        proc = subprocess.Popen([sys.executable, "-m", __name__, str(os.getpid()),
                                 *self._preload], stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        assert proc.stdout is not None
        try:
            _receive(proc.stdout)  # ready: its imports done
        except EOFError:
            raise HelperDied(f"the helper process exited at start ({proc.wait()})") from None
        return proc

    def __call__(self, fn: Callable[..., T], *args: Any, **kwargs: Any) -> T:
        with self._lock:
            for attempt in (0, 1):
                proc = self._proc
                assert proc.stdin is not None and proc.stdout is not None
                try:
                    _send(proc.stdin, (fn, args, kwargs))
                    ok, value = _receive(proc.stdout)
                    break
                except (BrokenPipeError, EOFError):
                    proc.kill()
                    proc.wait()
                    if attempt:
                        raise HelperDied("the helper process died twice on one call") from None
                    self._on_restart()
                    self._proc = self._start()
        if not ok:
            raise value
        out: T = value
        return out

    @property
    def pid(self) -> int:
        return self._proc.pid

    def close(self) -> None:
        proc = self._proc
        if proc.stdin is not None:
            proc.stdin.close()  # its end of input: it exits
        try:
            proc.wait(2.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def serve(parent: int, preload: list[str]) -> None:
    """The helper's side: calls in on stdin, (ok, result or exception) out on stdout."""
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(PR_SET_PDEATHSIG, 9)  # SIGKILL when the parent dies, however it dies
    if os.getppid() != parent:  # it died before that
        return
    for name in preload:
        importlib.import_module(name)
    inp, out = sys.stdin.buffer, sys.stdout.buffer
    sys.stdout = sys.stderr  # (a stray print must not corrupt the replies)
    _send(out, True)
    while True:
        try:
            fn, args, kwargs = _receive(inp)
        except EOFError:
            return
        try:
            reply: tuple[bool, Any] = (True, fn(*args, **kwargs))
        except Exception as e:  # (raised again in the caller)
            reply = (False, e)
        _send(out, reply)


if __name__ == "__main__":
    serve(int(sys.argv[1]), sys.argv[2:])
