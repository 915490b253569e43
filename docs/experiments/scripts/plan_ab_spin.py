"""HEAD (an SCurveAxis made per in-place candidate, every ruckig input set each move step) vs
this tree (one axis, each candidate's state loaded onto it; the constant inputs set once),
alternated per cycle on seed 7's 1080 recorded cycles in one process; every plan result
compared field by field (arrays exactly)."""
import sys, time, collections, dataclasses, types, numpy as np
sys.path.insert(0, "/tmp/s18A")
from replay import load, replay, summary
from autochair.control import limits as L
from autochair.nav import mpepc as M
lo, hi = (int(a) for a in sys.argv[1:3]) if len(sys.argv) > 2 else (0, None)
reqs = load("/tmp/s18A/seed7.pkl")[lo:hi]
# HEAD's limits module (its SCurveAxis) and HEAD's spin / spin_step bound to it
old_lim = types.ModuleType("limits_head"); old_lim.__file__ = "/tmp/s18A/limits_head.py"; sys.modules["limits_head"] = old_lim
exec(compile(open("/tmp/s18A/limits_head.py").read(), "/tmp/s18A/limits_head.py", "exec"), old_lim.__dict__)
def old_spin(self, in_place, z, w0, q0):
    idx = np.nonzero(in_place)[0]
    if idx.size == 0:
        return None
    g = self.law
    axes = []
    for _ in idx:
        a = old_lim.SCurveAxis(g.omega_max_radps, g.omega_acc_radps2, g.omega_jerk_radps3)
        a.reset(w0, q0)
        axes.append(a)
    return idx, z[idx, 3] <= self.p.v_min_mps + 0.01, axes
def old_spin_step(spin, yaw_was, yaw, st, tgt, turning, dt):
    idx, only, axes = spin
    on = np.nonzero(only | turning[idx])[0]
    if on.size == 0:
        return yaw
    i = idx[on]
    e = M.wrap(tgt[i, 2] - yaw_was[i]).tolist()
    w = np.array([axes[k].move(d, dt) for k, d in zip(on.tolist(), e, strict=True)])
    st[2, i], st[3, i] = w, [axes[k].rate for k in on.tolist()]
    yaw[i] = M.wrap(yaw_was[i] + w * dt)
    return yaw
NEW = (M.Mpepc.spin, M.Mpepc.spin_step)
spent = collections.Counter()
def timed(f, name):
    def g(*a):
        t0 = time.perf_counter(); r = f(*a); spent[name] += time.perf_counter() - t0; return r
    return g
def mode(name, spin, step):
    def install():
        M.Mpepc.spin = timed(spin, name + "_spin")
        M.Mpepc.spin_step = staticmethod(timed(step, name + "_step"))
    return install
modes = {"old": mode("old", old_spin, old_spin_step), "new": mode("new", *NEW)}
def same(a, b):
    if a is None or b is None: return a is b
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            if not np.array_equal(np.asarray(x), np.asarray(y)): return False
        elif x != y and not (x != x and y != y): return False
    return True
bad = [0]
def check(i, res):
    o, n = res["old"], res["new"]
    if not same(o.plan, n.plan) or (o.blocked_by, o.error) != (n.blocked_by, n.error):
        bad[0] += 1; print("DIFF at cycle", i, flush=True)
    if i % 100 == 0: print("cycle", i, flush=True)
t = replay(reqs, modes, check=check)
np.save("/tmp/s18A/ab2_times.npy", np.array([t["old"], t["new"]]))
print(summary(t, "old", "new"))
print({k: round(v, 3) for k, v in spent.items()}, "plans differing:", bad[0])
