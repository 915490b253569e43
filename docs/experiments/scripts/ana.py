import sys, pickle, json, math, statistics, bisect
import numpy as np
DT = 0.01
logs = pickle.load(open(sys.argv[1], "rb"))
tr = [m for _, m in logs["truth"]]
# sim tick index of each truth sample; volts applied in step ending at that tick
tick_volts = {round(m.sim_time_s / DT): (round(m.longitudinal_v * 1000), round(m.angular_v * 1000)) for m in tr}
tick_wall = {round(m.sim_time_s / DT): m.stamp_ns for m in tr}
seq0 = None
# telemetry seq s is emitted at sim time (s+1)*dt (firmware seq starts at 0 on the first tick)
joy = [m for _, m in logs["joy"] if m.enable]
delays, prev = [], None
for m in joy:
    v = (round(m.longitudinal_v * 1000), round(m.angular_v * 1000))
    if v == prev or v == (2500, 2500): prev = v; continue
    prev = v
    k0 = m.source_seq + 1  # tick of the counts the PID acted on
    ks = [k for k in range(k0 + 1, k0 + 12) if tick_volts.get(k) == v]
    if ks and all(k in tick_volts for k in range(k0 + 1, ks[0])):
        delays.append(ks[0] - k0)
c = {d: delays.count(d) for d in sorted(set(delays))}
print("PID loop: ticks from the counts' tick to the truth tick whose step used the volts "
      f"(lockstep = 1): {c}  n={len(delays)} mean={statistics.mean(delays):.2f}")
# wall latencies
enc = {m.seq: t for t, m in logs["enc"]}
encst = {m.seq: m.stamp_ns for t, m in logs["enc"]}
odom_rx = {m.source_seq: t for t, m in logs["odom"]}
joy_by_seq = {m.source_seq: m.stamp_ns for _, m in logs["joy"]}
def pct(x):
    x = sorted(x); return (round(x[len(x)//2], 2), round(x[int(len(x)*.9)], 2), round(x[int(len(x)*.99)], 2), round(x[-1], 2))
tw = {k: tick_wall[k] for k in tick_wall}
a = [(encst[q] - tw[q + 1]) / 1e6 for q in encst if q + 1 in tw]
b = [(joy_by_seq[q] - encst[q]) / 1e6 for q in joy_by_seq if q in encst]
print("sim tick publish -> gateway read stamp (ms p50/p90/p99/max):", pct(a))
print("gateway read stamp -> PID joystick stamp (ms):", pct(b))
# joystick stamp -> sim tick that applied it, wall
jo = [(t, m) for t, m in logs["jout"]]
# control: odometry age at command, and command -> next PID update
slow = [m.stamp_ns for _, m in logs["slow"]]
odst = sorted(m.stamp_ns for _, m in logs["odom"])
cmds = [m for _, m in logs["cmd"]]
ages, wait = [], []
import bisect
tr_w = np.array([m.stamp_ns for m in tr]); tr_mv = np.array([abs(m.v_mps) > 1e-3 or abs(m.omega_radps) > 1e-3 for m in tr])
def moving(ns):
    i = bisect.bisect_right(tr_w, ns) - 1
    return i >= 0 and tr_mv[i]
cmds = [m for m in cmds if moving(m.stamp_ns)]
for m in cmds:
    i = bisect.bisect_right(slow, m.stamp_ns) - 1
    if i >= 0: ages.append((m.stamp_ns - slow[i]) / 1e6)
    j = bisect.bisect_right(odst, m.stamp_ns)
    if j < len(odst): wait.append((odst[j] - m.stamp_ns) / 1e6)
print("control: command stamp - newest odom/slow stamp (ms):", pct(ages), "n", len(ages))
print("control: command stamp -> next odom stamp (PID applies it) (ms):", pct(wait))
cs = sorted(m.stamp_ns for m in cmds); gaps = np.diff(cs) / 1e6
print("control command period (ms):", pct(list(gaps)))
json.dump({"pid_ticks": c}, open("/tmp/wt14b/last.json", "w"))
# sim time against wall time while moving (truth every tick)
mv = [m for m in tr if abs(m.v_mps) > 1e-3 or abs(m.omega_radps) > 1e-3]
ws = np.array([m.stamp_ns for m in mv]) / 1e9; ss = np.array([m.sim_time_s for m in mv])
dw, dsim = np.diff(ws), np.diff(ss)
ok = dsim < 0.015
print(f"moving: wall {dw[ok].sum():.2f} s, sim {dsim[ok].sum():.2f} s, sim/wall {dsim[ok].sum()/dw[ok].sum():.3f}; "
      f"tick wall gaps >15 ms: {(dw[ok] > 0.015).sum()} of {ok.sum()}, >25 ms: {(dw[ok] > 0.025).sum()}")
