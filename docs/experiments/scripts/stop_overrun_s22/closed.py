"""Closed loop (control in the loop): which unmodelled delay overruns the 6 m goal."""
import dataclasses, sys
from autochair.control.core import ControlConfig, ControlCore
from bench import control_eval as ce
from autochair.tune import lockstep

state = {"t": -lockstep.DT, "hide": False}
log = []
orig_act = lockstep.Rig.act
def act(self, t, v, w, desired=None):
    state["t"] = t
    out = orig_act(self, t, v, w, desired)
    log.append((t, out.desired[0], v, out.v_effort, self.chair.x, self.chair.v))
    return out
lockstep.Rig.act = act
orig_on_odom = ControlCore.on_odom
def on_odom(self, s):
    if state["hide"]:  # the sample's age unknown to the control: stamped on receipt
        s = dataclasses.replace(s, t=state["t"] + lockstep.DT)
    return orig_on_odom(self, s)
ControlCore.on_odom = on_odom
for spec in sys.argv[1:]:
    oa, cd, hide = spec.split(",")
    state["hide"] = hide == "1"
    log.clear()
    r = ce.run_case((0, 0, 0), (6, 0, 0), ControlConfig(), odom_age_ticks=int(oa),
                    cmd_delay_ticks=int(cd))
    i0 = next(i for i, row in enumerate(log) if row[1] > 0.3)
    iz = next(i for i in range(i0, len(log)) if log[i][1] == 0.0)
    after = [row[3] for row in log[iz:iz + 100] if row[5] > 0.02]
    print(f"odom age {oa} ({'unknown' if state['hide'] else 'known'}) cmd delay {cd}: {r['state']} "
          f"rest x={log[-1][4]:.4f} ({100*(log[-1][4]-6):+.1f} cm) | desired 0 at chair v {log[iz][5]:.3f} "
          f"(meas {log[iz][2]:.3f}), x={log[iz][4]:.3f}; effort after, moving: [{min(after):+.3f}, {max(after):+.3f}]")
