"""Issue 12, session 24: the core's chain model (ChainAxis) against the lockstep chair on the
commands the core really sends. Records control_eval's 28 goals (tuned PID, simulated chair),
then replays each axis's commands through ChainAxis pushed as the core pushes them (50 Hz) and
integrates the velocity error over 1 s windows (the pose error the predictor and MPEPC's committed
sweep make: rad or m). As the core reads it, x2 after the push at tick j-1 is the chair at tick j.

    PYTHONPATH=services:schemas:. .venv/bin/python docs/experiments/scripts/chain_closed_loop.py
"""
import math

import bench.control_eval as ce
import numpy as np

from autochair.control.core import ChainAxis, ControlConfig
from autochair.tune import lockstep

H, DT = 0.02, lockstep.DT


def record() -> list[list[tuple[float, object, float, float]]]:
    runs, cur = [], []
    act = lockstep.Rig.act

    def rec(self, t, vm, wm, desired=None):  # (t, command or None, chair v, chair ω)
        cur.append((t, desired, self.chair.v, self.chair.omega))
        return act(self, t, vm, wm, desired)

    lockstep.Rig.act = rec
    for _, s, g in ce.suite():
        cur = []
        ce.run_case(s, g, ControlConfig())
        runs.append(cur)
    lockstep.Rig.act = act
    return runs


def window_errors(runs, axis: int, mean: float, lag: float = 0.15, win: float = 1.0):
    out, sq, n = [], 0.0, 0
    for run in runs:
        held, cmds = 0.0, []
        for k, (_, d, _, _) in enumerate(run):
            if k % 2 == 0:
                held = d[axis] if d is not None else held
                cmds.append(held)
        y = np.array([r[2 + axis] for r in run])[::2][: len(cmds)]
        c, p = ChainAxis(mean, lag), [y[0]]
        c.reset(y[0])
        for u in cmds[:-1]:
            c.push(H, u)
            p.append(c.x2)
        e = np.array(p) - y
        sq, n = sq + float(np.sum(e ** 2)), n + len(e)
        ce_ = np.concatenate([[0.0], np.cumsum(0.5 * (e[1:] + e[:-1]) * H)])
        m = round(win / H)
        out.append(ce_[m:] - ce_[:-m])
    a = np.concatenate(out)
    return math.sqrt(sq / n), float(np.sqrt(np.mean(a ** 2))), float(np.percentile(np.abs(a), 99))


def main() -> None:
    runs = record()
    for axis, means in ((1, (0.62, 0.60)), (0, (0.67, 0.66))):
        for mean in means:
            rms, wrms, p99 = window_errors(runs, axis, mean)
            print(f"{'vw'[axis]} ChainAxis({mean}, 0.15): velocity rms {rms:.4f}, "
                  f"1 s window rms {wrms:.4f} p99 {p99:.4f}")


if __name__ == "__main__":
    main()
