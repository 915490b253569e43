"""Issue 14, session 11: the plan cycles of a chain_diag.py log between T0 and T1 (truth, the
predicted pose planned from, z, flags: 1 driving, 2 final, 4 aligning, 8 straight, 16 a move,
32 a straight stage; truth clearance; blocked reason).

    .venv/bin/python docs/experiments/scripts/plan_log.py out.npz T0 T1
"""
import sys, math, numpy as np
d = np.load(sys.argv[1], allow_pickle=True); r = d['rows']; plans = d['plans']
t0 = float(sys.argv[2]) if len(sys.argv) > 2 else 0; t1 = float(sys.argv[3]) if len(sys.argv) > 3 else 1e9
for p in plans:
    if not t0 <= p['t'] <= t1: continue
    j = int(round(p['t'] / 0.02)); j = min(j, len(r) - 1); x = r[j]
    z = None if p['z'] is None else tuple(round(float(a), 2) for a in p['z'])
    print(f"t={p['t']:6.2f} T=({x[1]:.3f},{x[2]:.3f},{math.degrees(x[3]):6.1f}) v={x[4]:.2f} w={x[5]:+.2f} P=({p['pose'][0]:.3f},{p['pose'][1]:.3f},{math.degrees(p['pose'][2]):6.1f}) z={z} st={p['straight']} fl={int(x[16])} clr={x[17]:.3f} {p['blk'][:45]}{p['err'][:30]}")
