"""Closed loop: the control runs on time, but its commands do not reach the PID for D from T
(a stalled command path / PID subscriber): the PID holds the last one."""
import sys
from autochair.control.core import ControlConfig, ControlCore
from bench import control_eval as ce
from autochair.tune import lockstep
win = [None]
log = []
orig_act = lockstep.Rig.act
def act(self, t, v, w, desired=None):
    wn = win[0]
    if wn is not None and wn[0] <= t < wn[0] + wn[1] - 1e-9:
        desired = None
    out = orig_act(self, t, v, w, desired)
    log.append((t, out.desired[0], v, out.v_effort, self.chair.x, self.chair.v))
    return out
lockstep.Rig.act = act
for spec in sys.argv[1:]:
    T, D = map(float, spec.split(","))
    win[0] = None if D == 0 else (T, D)
    log.clear()
    r = ce.run_case((0, 0, 0), (6, 0, 0), ControlConfig())
    print(f"command path stall {D*1000:.0f} ms at t={T:.2f}: {r['state']} rest x={log[-1][4]:.4f} ({100*(log[-1][4]-6):+.1f} cm)")
