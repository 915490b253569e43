import sys
from autochair.control.core import ControlConfig, ControlCore
from autochair.control import limits
from bench import control_eval as ce
from autochair.tune import lockstep
win = [None]
rows = []
orig_move = limits.ComfortLimiter.move
def move(self, v_to, w_to, dt, **kw):
    before = (self.v.value, self.v.rate, self.v._plan_state, self.v._left == (self.v.value, self.v.rate))
    out = orig_move(self, v_to, w_to, dt, **kw)
    rows.append((cur["t"], dt, v_to, before, out[0], self.v._plan_state))
    return out
limits.ComfortLimiter.move = move
cur = {"t": 0}
orig_step = ControlCore.step
def step(self, now, dt=None):
    cur["t"] = now
    w = win[0]
    if w is not None and w[0] <= now < w[0] + w[1] - 1e-9:
        return "SKIP"
    return orig_step(self, now, dt)
ControlCore.step = step
orig_act = lockstep.Rig.act
def act(self, t, v, w, desired=None):
    return orig_act(self, t, v, w, None if desired == "SKIP" else desired)
lockstep.Rig.act = act
for D in (0.0, 0.1):
    win[0] = None if D == 0 else (5.3, D)
    rows.clear()
    ce.run_case((0, 0, 0), (6, 0, 0), ControlConfig())
    print("D", D)
    for r in rows:
        if 5.24 <= r[0] <= 5.5:
            t, dt, dist, (v0, a0, ps, fresh), vout, ps1 = r
            print(f"t={t:.2f} dt={dt:.3f} dist={dist:.4f} from v={v0:.4f} a={a0:+.3f} plan=({ps[0]:.4f},{ps[1]:+.3f}) own={fresh} -> sent {vout:.4f} plan=({ps1[0]:.4f},{ps1[1]:+.3f})")
