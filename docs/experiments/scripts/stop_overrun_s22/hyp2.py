import json, sys
sys.path.insert(0, "/tmp/dscratch")
from replay import REC, replay, summary
cmds = json.loads(REC.read_text())
base = summary(replay(cmds), label="baseline replay")
print("--- (b) windup: stalls during the acceleration and the cruise (chair at held volts, then neutral)")
for at in (50, 100, 150, 250, 400):
    for n in (20, 29):
        summary(replay(cmds, stalls=[(at, n)]), base, f"stall {n*10}ms at t={at/100:.1f}s")
summary(replay(cmds, stalls=[(a, 29) for a in range(50, 600, 40)]), base, "stall 290ms every 0.4 s")
summary(replay(cmds, stalls=[(a, 10) for a in range(50, 660, 20)]), base, "stall 100ms every 0.2 s")
print("--- (b)/(d) unmodelled delays: PID->chair (chain) and chair->PID (odometry age)")
for d in (1, 2, 3, 5, 10, 20):
    summary(replay(cmds, chain_delay=d), base, f"chain delay {d*10} ms")
for d in (1, 2, 5, 10, 20):
    summary(replay(cmds, odom_age=d), base, f"odometry age {d*10} ms")
