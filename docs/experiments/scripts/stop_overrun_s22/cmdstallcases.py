"""The same stalls on the command path only (the control on time, the PID holding): reference."""
from autochair.control.core import ControlConfig
from bench import control_eval as ce
from autochair.tune import lockstep
win = [None]
orig_act = lockstep.Rig.act
def act(self, t, v, w, desired=None):
    wn = win[0]
    if wn is not None and wn[0] <= t < wn[0] + wn[1] - 1e-9:
        desired = None
    return orig_act(self, t, v, w, desired)
lockstep.Rig.act = act
cases = {n: (s, g) for n, s, g in ce.suite()}
for name in ["ahead 1 m", "ahead 3 m", "diagonal 3,3", "beside left 2 m", "parallel park 1 m left"]:
    s, g = cases[name]
    T0 = ce.run_case(s, g, ControlConfig())["time_s"]
    out = []
    for frac in (0.4, 0.6, 0.75, 0.9):
        win[0] = (round(T0 * frac / 0.02) * 0.02, 0.2)
        r = ce.run_case(s, g, ControlConfig())
        win[0] = None
        out.append(f"{frac:.2f}:{'ok' if r['arrived'] else 'FAIL'} {100*r['true_pos_error_m']:.1f}cm a{r['truth_peak_a_mps2']:.2f} j{r['truth_peak_jerk_mps3']:.2f}")
    print(f"{name:24s} | " + " | ".join(out), flush=True)
