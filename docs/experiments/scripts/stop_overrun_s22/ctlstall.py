"""Closed loop: the control's 50 Hz loop stalls once for D at time T (the PID holds the last
command meanwhile, as through the processes); the plan then steps by the gap (<= 0.1 s)."""
import sys
from autochair.control.core import ControlConfig, ControlCore
from bench import control_eval as ce
from autochair.tune import lockstep

win = [None]
log = []
orig_step = ControlCore.step
def step(self, now, dt=None):
    w = win[0]
    if w is not None and w[0] <= now < w[0] + w[1] - 1e-9:
        return "SKIP"
    return orig_step(self, now, dt)
ControlCore.step = step
orig_act = lockstep.Rig.act
def act(self, t, v, w, desired=None):
    if desired == "SKIP":
        desired = None
    out = orig_act(self, t, v, w, desired)
    log.append((t, out.desired[0], v, out.v_effort, self.chair.x, self.chair.v))
    return out
lockstep.Rig.act = act
# (run_case appends step's output to cmds when not None: keep "SKIP" out of the plan's peaks)
orig_run = ce.run_case
for spec in sys.argv[1:]:
    T, D = map(float, spec.split(","))
    win[0] = None if D == 0 else (T, D)
    log.clear()
    try:
        r = ce.run_case((0, 0, 0), (6, 0, 0), ControlConfig())
        st = r["state"]
    except Exception as e:  # (the plan's peak statistics may choke on SKIP)
        st = f"error {type(e).__name__}: {e}"
    i0 = next(i for i, row in enumerate(log) if row[1] > 0.3)
    iz = next(i for i in range(i0, len(log)) if log[i][1] == 0.0)
    after = [row[3] for row in log[iz:iz + 100] if row[5] > 0.02]
    print(f"control stall {D*1000:.0f} ms at t={T:.2f}: {st} rest x={log[-1][4]:.4f} "
          f"({100*(log[-1][4]-6):+.1f} cm) | desired 0 at t={log[iz][0]:.2f} chair v {log[iz][5]:.3f} "
          f"(meas {log[iz][2]:.3f}); effort after, moving [{min(after):+.3f}, {max(after):+.3f}]")
