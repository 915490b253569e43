"""The control service traced per planning cycle, field build and tick (sitecustomize.py
loads it; docs/experiments/planning-live-s22.md). One JSON line per record to the file."""
import json
import threading
import time

_tl = threading.local()
_out_lock = threading.Lock()


def _sched():
    with open("/proc/thread-self/schedstat") as f:
        a = f.read().split()
    return int(a[0]) / 1e6, int(a[1]) / 1e6  # on-cpu ms, run-queue wait ms


def _acc():
    d = getattr(_tl, "acc", None)
    if d is None:
        d = _tl.acc = {}
    return d


def _add(k, v):
    d = _acc()
    d[k] = d.get(k, 0.0) + v


def child_timed(fn, *args, **kwargs):  # runs in the helper process
    c0, w0 = time.thread_time(), time.perf_counter()
    out = fn(*args, **kwargs)
    return out, (time.thread_time() - c0) * 1e3, (time.perf_counter() - w0) * 1e3


def timed(name, f):
    def g(*a, **k):
        t0 = time.perf_counter()
        _acc().setdefault("s_" + name, time.monotonic())
        try:
            return f(*a, **k)
        finally:
            _add("t_" + name, (time.perf_counter() - t0) * 1e3)
            _add("n_" + name, 1)
    g.__wrapped__ = f
    return g


class Span:
    def __enter__(self):
        _tl.acc = {}
        self.w0 = time.perf_counter()
        self.m0 = time.monotonic()
        self.c0, self.r0 = _sched()
        return self

    def __exit__(self, *exc):
        c1, r1 = _sched()
        self.rec = dict(t0=self.m0, wall=(time.perf_counter() - self.w0) * 1e3,
                        cpu=c1 - self.c0, runq=r1 - self.r0, **_acc())
        _tl.acc = {}


def patch(node, path):
    from autochair.nav import gil, planner, mpepc
    from autochair.runtime import helper as hmod
    fh = open(path, "a", buffering=1)

    def write(rec):
        with _out_lock:
            fh.write(json.dumps(rec) + "\n")

    orig_call = hmod.HelperProcess.__call__

    def call(self, fn, *args, **kwargs):
        w0 = time.perf_counter()
        c0, r0 = _sched()
        out, ccpu, cwall = orig_call(self, child_timed, fn, *args, **kwargs)
        c1, r1 = _sched()
        _add("h_wall", (time.perf_counter() - w0) * 1e3)
        _add("h_cpu", c1 - c0)
        _add("h_runq", r1 - r0)
        _add("h_child_wall", cwall)
        _add("h_child_cpu", ccpu)
        _add("h_n", 1)
        _add("h_" + getattr(fn, "__name__", "?"), cwall)
        return out
    hmod.HelperProcess.__call__ = call

    for n in ("give_up", "blocker", "lattice_for", "path_error", "costs_to_go", "_setup",
              "planner_for"):
        setattr(planner, n, timed(n, getattr(planner, n)))
    for n in ("plan", "stage_plan", "turn_first", "along_lattice"):
        setattr(mpepc.Mpepc, n, timed("mpc_" + n, getattr(mpepc.Mpepc, n)))
    node.NavField = timed("NavField", node.NavField)
    node.warm = timed("warm", node.warm)
    orig_compute = node.compute

    def compute(req):
        with Span() as s:
            res = orig_compute(req)
        p = res.plan
        write(dict(kind="plan", **s.rec, blocked=bool(res.blocked_by), gid=req.goal_id,
                   has_ctg=req.ctg is not None, plan=None if p is None else
                   [round(float(v), 4) for v in (*p.target, p.vmax_mps, p.cost)]))
        return res
    node.compute = compute

    orig_refresh = node.ControlNode.refresh_field

    def refresh(self, for_goal=True):
        with Span() as s:
            orig_refresh(self, for_goal)
        if "n_NavField" in s.rec:
            write(dict(kind="field", **s.rec))
    node.ControlNode.refresh_field = refresh

    orig_tick = node.ControlNode.tick

    def tick(self):
        with Span() as s:
            orig_tick(self)
        write(dict(kind="tick", t0=s.rec["t0"], wall=round(s.rec["wall"], 2),
                   cpu=round(s.rec["cpu"], 2)))
    node.ControlNode.tick = tick
