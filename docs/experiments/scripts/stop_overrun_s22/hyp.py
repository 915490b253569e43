import json, sys
sys.path.insert(0, "/tmp/dscratch")
from replay import REC, replay, summary
cmds = json.loads(REC.read_text())
base = summary(replay(cmds), label="baseline replay")
# ticks: desired 0 at t=6.62 -> k=662; decel ramp from ~5.9 s
iz = next(i for i in range(400, len(cmds)) if cmds[i] is not None and cmds[i][0] == 0.0 and any(c and c[0] > 0.3 for c in cmds[i-80:i]))
print("first zero command at tick", iz)
print("--- (a) PID stalls (burst / merged), chair holds volts, gateway neutral after 0.1 s")
for at in (iz - 60, iz - 20, iz, iz + 10, iz + 30):
    for n in (10, 20, 29):
        for merged in (False, True):
            summary(replay(cmds, stalls=[(at, n)], merged=merged), base,
                    f"stall {n*10}ms at {at-iz:+d} {'merged' if merged else 'burst'}")
print("--- (a) one wrong, huge dt (chair moved 10 ms)")
for at in (iz - 20, iz, iz + 20):
    for dt in (0.1, 0.3, 1.0):
        summary(replay(cmds, wrong_dt=(at, dt)), base, f"dt {dt} at {at-iz:+d}")
