"""Closed loop, several cases: one control-loop stall of D at T (the late tick stepped by the gap,
as Node.due), PID holding the last command. Arrival, error, chair peaks."""
import sys, math
from autochair.control.core import ControlConfig, ControlCore
from bench import control_eval as ce
win = [None]
orig_step = ControlCore.step
def step(self, now, dt=None):
    w = win[0]
    if w is not None and w[0] <= now < w[0] + w[1] - 1e-9:
        return "SKIP"
    return orig_step(self, now, dt)
ControlCore.step = step
from autochair.tune import lockstep
orig_act = lockstep.Rig.act
def act(self, t, v, w, desired=None):
    return orig_act(self, t, v, w, None if desired == "SKIP" else desired)
lockstep.Rig.act = act
# (run_case's plan peaks read core.limiter after each non-None output: SKIP is fine)
cases = {n: (s, g) for n, s, g in ce.suite()}
for name in ["ahead 1 m", "ahead 3 m", "turn in place 90", "diagonal 3,3", "behind 2 m, u-turn", "beside left 2 m", "parallel park 1 m left"]:
    s, g = cases[name]
    base = ce.run_case(s, g, ControlConfig())
    T0 = base["time_s"]
    out = []
    for frac in (0.4, 0.6, 0.75, 0.9):
        win[0] = (round(T0 * frac / 0.02) * 0.02, 0.2)
        r = ce.run_case(s, g, ControlConfig())
        win[0] = None
        out.append(f"{frac:.2f}:{'ok' if r['arrived'] else 'FAIL'} {100*r['true_pos_error_m']:.1f}cm {r['true_yaw_error_deg']:.1f}° a{r['truth_peak_a_mps2']:.2f} j{r['truth_peak_jerk_mps3']:.2f} w{r['truth_peak_omega_dot_radps2']:.2f}")
    print(f"{name:24s} base t={T0} | " + " | ".join(out), flush=True)
