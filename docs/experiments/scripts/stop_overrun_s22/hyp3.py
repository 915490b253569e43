import json, sys
sys.path.insert(0, "/tmp/dscratch")
from replay import REC, replay, summary
cmds = json.loads(REC.read_text())
base = summary(replay(cmds), label="baseline")
summary(replay(cmds, after_zero=lambda u, v: min(u, 0.0)), base, "after desired 0: effort <= 0")
summary(replay(cmds, after_zero=lambda u, v: 0.0), base, "after desired 0: exact neutral")
for b in (0.1, 0.2, 0.3):
    summary(replay(cmds, after_zero=lambda u, v: min(u, -b) if v > 0.05 else min(u, 0.0)), base,
            f"after desired 0: effort <= -{b} while v > 0.05")
