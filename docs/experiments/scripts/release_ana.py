"""Analysis of release_diag.py's dumps (session 14): `ana` peak |a| on the sim clock and on the
wall stamps, the sim's rate; `lag` how far the sim's clock fell behind the wall clock after the
motion began (a sim that skips ticks loses time); `decel` the acceleration and braking peaks.

    python release_ana.py ana|lag|decel DUMP.json...
"""
import sys
import json

import numpy as np


def peak(t, v):
    grid = np.arange(t[0], t[-1], 0.01)
    vs = np.convolve(np.interp(grid, t, v), np.ones(10) / 10, mode="valid")
    d = np.diff(vs[::5]) / 0.05
    i = int(np.abs(d).argmax())
    return float(abs(d[i])), float(grid[i*5])


def ana(files):
    for fn in files:
        d = json.load(open(fn))
        s0 = d["start_ns"]
        tr = np.array(d["truth"]); tr = tr[tr[:,0] > s0]
        wall = (tr[:,0] - s0) / 1e9; sim = tr[:,1]; v = tr[:,2]
        # only until v reaches ~ the cruise (first 4 s of motion)
        moving = np.nonzero(v > 0.005)[0]
        i0 = moving[0]
        sel = slice(0, len(v))
        p_sim, at_sim = peak(sim[sel], v[sel])
        p_wall, at_wall = peak(wall[sel], v[sel])
        # sim rate: sim seconds per wall second over the ramp (first 2.5 s of motion)
        w = (sim >= sim[i0]) & (sim <= sim[i0] + 2.5)
        rate = np.polyfit(wall[w], sim[w], 1)[0]
        dsim = np.diff(sim); gaps = np.sum(dsim > 0.0105)
        # commanded accel in wall time (cmd_vel)
        c = np.array(d["cmd"]); c = c[c[:,0] > s0]
        cw = (c[:,0]-s0)/1e9
        ca = np.abs(np.diff(c[:,1]) / np.diff(cw))
        od = np.array(d["odom"]); od = od[od[:,0] > s0]
        print(f"{fn.split('/')[-1]:14s} peak sim {p_sim:.3f} @{at_sim-sim[i0]:.2f}s  wall {p_wall:.3f}  sim/wall rate {rate:.3f}  truth n={len(v)} sim-gaps>10ms {gaps} max dsim {dsim.max()*1e3:.0f}ms  cmd max|dv/dt| {ca.max():.2f} odom dt max {od[:,2].max()*1e3:.0f}ms load {d['load']:.2f}")


def lag(files):
    for fn in files:
        d = json.load(open(fn)); s0 = d["start_ns"]
        tr = np.array(d["truth"]); tr = tr[tr[:,0] > s0]
        sim = tr[:,1]; v = tr[:,2]; wall=(tr[:,0]-s0)/1e9
        i0 = np.nonzero(v > 0.005)[0][0]
        off = (wall - sim); off = off - off[i0]
        # sim time lost (ms) at 0.1 s steps after motion start, minimum-filtered over 5 samples (publish latency is positive jitter)
        out = []
        for t in np.arange(-0.5, 2.01, 0.25):
            k = (sim >= sim[i0] + t) & (sim < sim[i0] + t + 0.1)
            if k.any(): out.append(f"{t:+.2f}:{off[k].min()*1e3:5.1f}")
        dsim = np.diff(sim)[i0:]
        print(fn.split('/')[-1], "lag of sim behind wall (ms, vs motion start):", " ".join(out), "| motion dsim max", dsim.max()*1e3)


def decel(files):
    for fn in files:
        d = json.load(open(fn)); s0 = d["start_ns"]
        tr = np.array(d["truth"]); tr = tr[tr[:,0] > s0]
        sim = tr[:,1]; v = tr[:,2]
        i0 = np.nonzero(v > 0.005)[0][0]
        grid = np.arange(sim[0], sim[-1], 0.01)
        vs = np.convolve(np.interp(grid, sim, v), np.ones(10)/10, mode="valid")
        acc = np.diff(vs[::5]) / 0.05; g = grid[::5][:-1] - sim[i0]
        c = np.array(d["cmd"]); c = c[c[:,0] > s0]
        dc = np.diff(c[:,1])
        print(f"{fn.split('/')[-1]:16s} accel max {acc.max():.3f} @{g[acc.argmax()]:.2f}  decel min {acc.min():.3f} @{g[acc.argmin()]:.2f}  end {g[-1]:.2f}s  largest cmd drop/tick {dc.min():.3f}")


if __name__ == "__main__":
    {"ana": ana, "lag": lag, "decel": decel}[sys.argv[1]](sys.argv[2:])
