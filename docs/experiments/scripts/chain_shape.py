"""Issue 12, session 17: why the control core's drive-chain predictor (ChainAxis: dead time, then
two equal lags) misfits the simulated chair in fast turns. In lockstep (tune.lockstep.Rig, the
PID as [pid] configures it), random S-curve commands at the comfort limits (50 Hz, as the core
sends them) on one axis; the chair's true velocity against ChainAxis fed the same commands.
Prints, per case, the velocity rms and the 95th / 99th percentiles of the error integrated over
0.5, 1 and 1.5 s windows (the motion still to come that the pose predictor misjudges: rad or m).

  1. plant variants with the predictor as configured: the chair as simulated; without the
     joystick dead band (chair and model); a chair that IS the identified SOPDT; no feedback;
  2. the predictor refitted to the closed loop: a grid of (dead time, lag).

    PYTHONPATH=services:schemas:. .venv/bin/python docs/experiments/scripts/chain_shape.py
"""
import math

import msgspec
import numpy as np

from autochair.control.core import ChainAxis, ControlConfig
from autochair.control.limits import SCurveAxis
from autochair.pid.core import PidConfig, make_core
from autochair.sim.chair.model import ChairModel, ChairParams
from autochair.tune.lockstep import DT, Rig

H = 0.02  # the core's command period
SOPDT = dict(delay_s=0.318, tau_omega_s=0.241, tau_drive_s=0.241, tau_rotation_s=0.0,
             tau_v_s=0.358, tau_translation_s=0.0)  # (the ω model; v only roughly)


def pid(**kw):
    return make_core(msgspec.structs.replace(PidConfig(), require_safety_limit=False,
                                             require_estop=False, **kw))


def commands(seed, n, amp, offset, vmax, amax, jmax, lo=-math.inf):
    """S-curve moves to random targets, each held 0.3-1.5 s."""
    rng = np.random.default_rng(seed)
    ax, out, target, nxt = SCurveAxis(vmax, amax, jmax), [], 0.0, 0
    for i in range(n):
        if i >= nxt:
            target, nxt = max(lo, offset + amp * rng.uniform(-1, 1)), i + int(rng.uniform(15, 75))
        out.append(ax.step(target, H))
    return np.array(out)


def lockstep(cmd, axis, core, chair):
    """The chair's true velocity on `axis` after each command period."""
    rig, y = Rig(core, chair=chair), []
    for i, u in enumerate(cmd):
        for s in range(2):
            st = rig.sense()
            pair = (u, 0.0) if axis == "v" else (0.0, u)
            rig.act((2 * i + s) * DT, st.v, st.omega, pair if s == 0 else None)
        y.append(rig.chair.v if axis == "v" else rig.chair.omega)
    return np.array(y)


def chain(cmd, mean, lag):
    """ChainAxis fed the commands: its x2 after each push is the chair one period on."""
    c, out = ChainAxis(mean, lag), []
    for u in cmd:
        c.push(H, u)
        out.append(c.x2)
    return np.array(out)


def score(data, mean, lag):
    sq = n = 0.0
    wins = {25: [], 50: [], 75: []}
    for cmd, y in data:
        e = y - chain(cmd, mean, lag)
        sq, n = sq + float(np.sum(e ** 2)), n + len(e)
        c = np.cumsum(e) * H
        for w in wins:
            wins[w].append(np.abs(c[w:] - c[:-w]))
    out = f"rms {math.sqrt(sq / n):.4f}"
    for w, arr in wins.items():
        a = np.concatenate(arr)
        out += f" | {w * H:.1f} s {np.percentile(a, 95):.4f} {np.percentile(a, 99):.4f}"
    return out


def main():
    cfg = ControlConfig()
    lim = cfg.limits
    sets = {  # (amplitude, offset) per run: about zero (reversals) and about a turn / a speed
        "w": [commands(s, 3000, a, o, lim.omega_max_radps, lim.omega_acc_max_radps2,
                       lim.omega_jerk_max_radps3) for s, a, o in
              ((1, 0.6, 0.0), (2, 0.3, 0.0), (3, 0.4, 0.4), (4, 0.9, 0.0))],
        "v": [np.clip(commands(s, 3000, a, o, lim.v_max_mps, lim.a_max_mps2, lim.jerk_max_mps3),
                      0.0, None) for s, a, o in
              ((1, 0.5, 0.5), (2, 0.3, 0.3), (3, 0.6, 0.6), (4, 0.2, 0.9))],
    }
    mean = {"w": cfg.predict_omega_s, "v": cfg.predict_s}
    lag = cfg.predict_lag_s
    no_db = dict(omega_model=(1.8, 0.0, 0.241, 0.241, 0.318),
                 v_model=(1.75, 0.0, 0.358, 0.358, 0.372))
    variants = {
        "chair as simulated": (pid, ChairModel),
        "no dead band": (lambda: pid(**no_db), lambda: ChairModel(ChairParams(dead_band=0.0))),
        "chair = the SOPDT": (pid, lambda: ChairModel(ChairParams(**SOPDT))),
        "no feedback": (lambda: pid(omega_gains=(0.0, 0.0, 0.0), v_gains=(0.0, 0.0, 0.0)),
                        ChairModel),
    }
    print("cols: velocity rms | window: p95 p99 of the integrated error (rad or m)")
    for axis in ("w", "v"):
        print(f"== {axis}: predictor as configured (mean {mean[axis]}, lag {lag})")
        for name, (core, chair) in variants.items():
            if axis == "v" and name == "chair = the SOPDT":
                continue  # (SOPDT above is the ω model's)
            data = [(c, lockstep(c, axis, core(), chair())) for c in sets[axis]]
            print(f"  {name:20s} {score(data, mean[axis], lag)}")
        data = [(c, lockstep(c, axis, pid(), ChairModel())) for c in sets[axis]]
        print(f"== {axis}: refitted (dead time on the command period, lag)")
        dead = math.floor((mean[axis] - 2 * lag) / H + 1e-9) * H  # (ChainAxis's own rounding)
        for d in np.round(np.arange(dead - 0.06, dead + 0.03, 0.02), 2):
            for lg in (0.15, 0.16, 0.17, 0.18):
                print(f"  dead {d:.2f} lag {lg:.2f} (mean {d + 2 * lg:.2f}) "
                      f"{score(data, d + 2 * lg, lg)}")


if __name__ == "__main__":
    main()
