"""Replay recorded planning requests (record.py) through planner.compute, each cycle under
every mode in turn (order alternated cycle by cycle), in one process. The lattice cache is put
back to the state the live run had before each cycle (a lattice the live run built in a cycle
is built in it by every mode), the Mpepc's random state and its chain cache too."""
import copy, pickle, time
import numpy as np
from autochair.nav import planner

def load(path):
    with open(path, "rb") as f:
        return pickle.load(f)

def replay(reqs, modes, reps=1, check=None, keep=None, on_cycle=None):
    """modes: {name: callable() that installs it}. Returns {name: [ms per cycle]} (min over
    reps) and the results of the last mode per cycle if keep."""
    times = {m: [] for m in modes}
    built = {}  # (id(field), goal) -> lattice
    names = list(modes)
    for i, (req, params, cached) in enumerate(reqs):
        lat = {k: v for k, v in built.items() if k[0] == id(req.field) and k[1] in cached}
        # the Mpepc for this field as the live run had it (created if new)
        mpc = planner.planner_for(req.field, req.law, params)
        rng0 = copy.deepcopy(mpc._rng.bit_generator.state)
        best = {m: float("inf") for m in names}
        res = {}
        for r in range(reps):
            order = names if (i + r) % 2 == 0 else names[::-1]
            for m in order:
                modes[m]()
                planner._lattices.clear(); planner._lattices.update(lat)
                mpc._rng.bit_generator.state = copy.deepcopy(rng0)
                mpc._free = None
                rq = req if req.chain is None else __import__("dataclasses").replace(req, chain=copy.deepcopy(req.chain))
                t0 = time.perf_counter()
                out = planner.compute(rq, params)
                best[m] = min(best[m], (time.perf_counter() - t0) * 1e3)
                res[m] = out
                rng_after = copy.deepcopy(mpc._rng.bit_generator.state)
        for k, v in planner._lattices.items():
            built.setdefault(k, v)
        for m in names:
            times[m].append(best[m])
        if check is not None:
            check(i, res)
        if on_cycle is not None:
            on_cycle(i, req, best)
    return times

def summary(times, base, new):
    o, n = np.array(times[base]), np.array(times[new])
    r = n / o
    return (f"{base}->{new}: cycles {len(o)}  median {np.median(o):.1f} -> {np.median(n):.1f} ms (x{np.median(n)/np.median(o):.3f})"
            f"  p95 {np.percentile(o,95):.1f} -> {np.percentile(n,95):.1f} ms (x{np.percentile(n,95)/np.percentile(o,95):.3f})"
            f"  pairwise median x{np.median(r):.3f}  sum x{n.sum()/o.sum():.3f}")
