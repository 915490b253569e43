"""Issue 14, session 11: how well the control core's drive-chain predictor (ChainAxis, mean lag
and two lags) matches the chair in chain_diag.py logs: per axis, the chain fed the commands sent
against the simulator's true velocity; rms, and the error integrated over 1 s windows (the
motion still to come the pose predictor misjudges, m or rad), for a grid of (mean, lag).

    PYTHONPATH=. .venv/bin/python docs/experiments/scripts/chain_fit.py a.npz [b.npz ...]
"""
import sys, math, numpy as np
from autochair.control.core import ChainAxis
files = sys.argv[1:]
data = [np.load(f, allow_pickle=True)['rows'] for f in files]
def err(mean, lag, axis):
    ci, ti = (12, 4) if axis == 0 else (13, 5)
    tot_e = tot_i = 0.0; n = 0; worst = 0.0
    for r in data:
        ch = ChainAxis(mean, lag)
        ch.reset(0.0)
        ys = []
        for row in r:
            ys.append(ch.x2)          # model's chair before this tick's command
            ch.push(0.02, row[ci])
        ys = np.array(ys); tr = r[:, ti]
        e = tr - ys
        tot_e += (e ** 2).sum(); n += len(e)
        # integrated error over 1 s windows (the pending-motion error)
        c = np.cumsum(e) * 0.02
        w = c[50:] - c[:-50]
        tot_i += (w ** 2).sum(); worst = max(worst, np.abs(w).max())
    return math.sqrt(tot_e / n), math.sqrt(tot_i / n), worst
for axis in (0, 1):
    best = []
    for mean in np.arange(0.24, 0.46, 0.02):
        for lag in (0.0, 0.03, 0.06, 0.09, 0.12):
            if 2 * lag > mean: continue
            best.append((err(mean, lag, axis), mean, lag))
    best.sort(key=lambda b: b[0][1])
    print("axis", axis)
    for b in best[:6]:
        print(f"  mean={b[1]:.2f} lag={b[2]:.2f} rms={b[0][0]:.4f} rms_int1s={b[0][1]:.4f} worst_int={b[0][2]:.4f}")
    for m, l in ((0.34, 0.03), (0.30, 0.03), (0.67, 0.15), (0.62, 0.15)):
        e = err(m, l, axis); print(f"  ref mean={m} lag={l}: rms={e[0]:.4f} int={e[1]:.4f} worst={e[2]:.4f}")
