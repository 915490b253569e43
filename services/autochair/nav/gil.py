"""The searches that hold Python's interpreter lock (the GIL) for their whole run.

scipy.sparse.csgraph's `dijkstra` and `breadth_first_order` and scikit-fmm's `travel_time` are
compiled code that never releases the lock: no other thread of the process runs meanwhile
(measured: a 5 ms sleep loop beside a 0.76 s `dijkstra` woke once, 757 ms late). In nav_eval at
load ~10 one lattice search took up to 309 ms and one costs-to-go 216 ms. In the control
service those are the plan and map threads, and the 50 Hz command stream stalled past the
velocity PID's 0.3 s stale limit: the PID stopped, as it must, and refused the stream ever
after (no unexpected start-up), so the goal ended "the chair does not follow" at its start.

The cores call them through `run`. The control node installs a runner that makes each call in
a helper process (runtime/helper.py), so its own threads go on; the lockstep benches and the
tests call them here, unchanged.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

T = TypeVar("T")

_runner: Callable[..., Any] | None = None


def install(runner: Callable[..., Any] | None) -> None:
    """`runner(fn, *args, **kwargs)` makes every call from now on (None: here, in-process)."""
    global _runner
    _runner = runner


def run(fn: Callable[..., T], *args: Any, **kwargs: Any) -> T:
    """`fn(*args, **kwargs)`, through the installed runner if any (`fn` and its arguments
    must then pickle: module-level functions, arrays, sparse matrices)."""
    if _runner is None:
        return fn(*args, **kwargs)
    out: T = _runner(fn, *args, **kwargs)
    return out
