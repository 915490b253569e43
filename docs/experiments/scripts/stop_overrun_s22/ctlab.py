"""Control stall ablations: how the late step is taken."""
import os, sys
from autochair.control.core import ControlConfig, ControlCore
from bench import control_eval as ce
from autochair.tune import lockstep
MODE = os.environ.get("MODE", "late")
win = [None]
log = []
last = {"t": None}
orig_step = ControlCore.step
def step(self, now, dt=None):
    w = win[0]
    if w is not None and w[0] <= now < w[0] + w[1] - 1e-9:
        return "SKIP"
    prev = last["t"]
    last["t"] = now
    if prev is not None and now - prev > 0.03 and MODE != "late":
        if MODE == "skip":      # A: the late step as if on time (the plan lags the clock)
            return orig_step(self, now, 0.02)
        if MODE == "catchup_cap":  # the missed ticks now, at most 0.1 s of them
            n = min(round((now - prev) / 0.02), 5)
            for i in range(1, n):
                orig_step(self, now, 0.02)
            return orig_step(self, now, 0.02)
        if MODE == "catchup_now":  # the missed ticks now, all on the real clock
            n = round((now - prev) / 0.02)
            for i in range(1, n):
                orig_step(self, now, 0.02)
            return orig_step(self, now, 0.02)
        if MODE == "catchup":   # B: the missed ticks run now (only the last one's command sent)
            n = round((now - prev) / 0.02)
            for i in range(1, n):
                orig_step(self, prev + 0.02 * i, 0.02)
            return orig_step(self, now, 0.02)
    return orig_step(self, now, dt)
ControlCore.step = step
orig_act = lockstep.Rig.act
def act(self, t, v, w, desired=None):
    out = orig_act(self, t, v, w, None if desired == "SKIP" else desired)
    log.append((t, self.chair.x))
    return out
lockstep.Rig.act = act
for spec in sys.argv[1:]:
    T, D = map(float, spec.split(","))
    win[0] = None if D == 0 else (T, D)
    last["t"] = None
    log.clear()
    r = ce.run_case((0, 0, 0), (6, 0, 0), ControlConfig())
    print(f"{MODE}: control stall {D*1000:.0f} ms at t={T:.2f}: {r['state']} rest ({100*(log[-1][1]-6):+.1f} cm)")
