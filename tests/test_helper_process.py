"""The helper process for searches that hold the interpreter lock (runtime/helper.py,
nav/gil.py): in the control service a lattice search stalled the 50 Hz command stream past
the velocity PID's stale limit, and goals ended "the chair does not follow" at their start."""

from __future__ import annotations

import io
import itertools
import math
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from autochair.nav import gil
from autochair.runtime.helper import HelperProcess, _receive, _send
from tests.helpers import wait_for


@pytest.fixture
def helper() -> Iterator[HelperProcess]:
    h = HelperProcess(("scipy.sparse.csgraph",))
    try:
        yield h
    finally:
        h.close()


def gone(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split(") ")[1][0] in "ZX"
    except (FileNotFoundError, ProcessLookupError):
        return True


def big_graph(n: int = 300_000) -> csr_matrix:
    rng = np.random.default_rng(1)
    return csr_matrix((rng.random(5 * n), rng.integers(0, n, 5 * n),
                       np.arange(0, 5 * n + 1, 5)), shape=(n, n))


def longest_stall(call: Callable[[], object]) -> tuple[float, float, object]:
    """(the call's duration, the longest a 2 ms sleep loop beside it went without waking, the
    call's result): what the command stream's thread would see."""
    stop, wakes = threading.Event(), [time.perf_counter()]

    def loop() -> None:
        while not stop.is_set():
            time.sleep(0.002)
            wakes.append(time.perf_counter())

    t = threading.Thread(target=loop)
    t.start()
    wait_for(lambda: len(wakes) > 3, 5, "the loop running")
    t0 = time.perf_counter()
    out = call()
    t1 = time.perf_counter()
    stop.set()
    t.join()
    marks = [t0, *(w for w in wakes if t0 < w < t1), t1]
    return t1 - t0, max(b - a for a, b in itertools.pairwise(marks)), out


def test_a_search_made_in_the_helper_leaves_the_threads_running(helper: HelperProcess) -> None:
    graph = big_graph()
    here_s, here_stall, here = longest_stall(lambda: dijkstra(graph, indices=[0]))
    # Positive control: made here, the search holds the lock: the loop sleeps through it.
    assert here_stall > 0.8 * here_s, (here_s, here_stall)
    there_s, there_stall, there = longest_stall(lambda: helper(dijkstra, graph, indices=[0]))
    assert np.array_equal(np.asarray(here), np.asarray(there))
    # (pickling the 18 MB graph holds the lock for a few tens of ms; the search itself none)
    assert there_stall < 0.5 * here_s, (here_s, there_s, there_stall)
    print(f"\nhere {here_s:.3f} s, stalled {here_stall:.3f} s; in the helper {there_s:.3f} s, "
          f"stalled {there_stall:.3f} s")


def test_big_arrays_go_through_the_pipe_out_of_band() -> None:
    """Pickled in band, the 41 MB lattice graph of a goal's first plans held the lock 70-90 ms
    in the control service (the 50 Hz stream stalled most just as driving began): the arrays'
    memory is written to the pipe as it is (writes release the lock), the pickle stays small."""
    graph = big_graph()
    writes: list[int] = []

    class Pipe(io.BytesIO):
        def write(self, b: Any) -> int:
            writes.append(memoryview(b).nbytes)
            return super().write(b)

    pipe = Pipe()
    _send(pipe, (dijkstra, (graph,), {"indices": [0]}))
    arrays = sorted(a.nbytes for a in (graph.data, graph.indices, graph.indptr))
    assert sorted(writes)[-3:] == arrays, writes  # each array in one write of its own
    assert sum(writes) - sum(arrays) < 2000, writes  # header + pickle
    pipe.seek(0)
    fn, (back,), kwargs = _receive(pipe)
    assert fn is dijkstra and kwargs == {"indices": [0]}
    assert (back != graph).nnz == 0 and back.data.flags.writeable
    with pytest.raises(EOFError):
        _receive(io.BytesIO(pipe.getvalue()[:-1]))  # a pipe closed mid-message


def test_the_helpers_errors_come_back_and_a_killed_helper_is_started_again(
        helper: HelperProcess) -> None:
    with pytest.raises(ValueError, match="math domain error"):
        helper(math.sqrt, -1.0)
    assert helper(sum, [1, 2, 3]) == 6  # positive control: it still answers
    restarts: list[int] = []
    helper._on_restart = lambda: restarts.append(1)
    old = helper.pid
    os.kill(old, signal.SIGKILL)
    wait_for(lambda: gone(old), 5, "the helper killed")
    assert helper(sum, [4, 5]) == 9 and helper.pid != old and restarts == [1]


def test_the_helper_dies_with_its_parent(tmp_path: Path) -> None:
    parent = subprocess.Popen(
        [sys.executable, "-c", "import sys, time\n"
         "from autochair.runtime.helper import HelperProcess\n"
         "h = HelperProcess()\nprint(h.pid, flush=True)\ntime.sleep(60)"],
        stdout=subprocess.PIPE, text=True)
    try:
        assert parent.stdout is not None
        pid = int(parent.stdout.readline())
        assert not gone(pid)  # positive control: it runs while its parent does
        parent.kill()
        parent.wait()
        wait_for(lambda: gone(pid), 5, "the helper gone with its SIGKILLed parent")
    finally:
        parent.kill()
        parent.wait()


def test_the_cores_searches_go_through_the_installed_runner() -> None:
    from autochair.nav.field import Footprint, GridMap, NavField
    from autochair.nav.lattice import build

    made: list[str] = []

    def runner(fn: Callable[..., object], *args: object, **kwargs: object) -> object:
        made.append(getattr(fn, "__name__", "?"))
        return fn(*args, **kwargs)

    fld = NavField(GridMap(np.zeros((40, 60), dtype=np.bool_), 0.1, 0.0, 0.0, "odom"),
                   Footprint())
    goal = (4.0, 2.0, 0.0)
    ctg = fld.cost_to_go(goal[0], goal[1])
    assert ctg is not None
    gil.install(runner)
    try:
        build(fld, goal, ctg.phi, start=(1.0, 2.0, 0.0))
    finally:
        gil.install(None)
    assert "dijkstra" in made and "travel_time" not in made  # (ctg made before installing)
    made.clear()
    build(fld, goal, ctg.phi, start=(1.0, 2.0, 0.0))
    assert not made  # uninstalled: here again
