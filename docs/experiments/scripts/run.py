"""Measure command-to-chair delays through the process stack (helper wt-14b, not in the repo)."""
import json, math, statistics, sys, tempfile, threading, time
from pathlib import Path
import numpy as np
from autochair.launcher import Launcher, free_port
from autochair.processes import PROCESSES, local_values
from autochair.runtime.client import open_client, subscribe
from autochair_msgs import keys
from bench.control_stack import STACK, drive_case
from bench.control_eval import suite

DT = 0.01
names = sys.argv[1].split(";") if len(sys.argv) > 1 else ["ahead 3 m", "turn in place 90"]
logs = {k: [] for k in ("truth", "joy", "jout", "odom", "slow", "cmd", "enc")}
lock = threading.Lock()
def rec(name):
    def cb(m):
        with lock:
            logs[name].append((time.time_ns(), m))
    return cb
hub = f"tcp/127.0.0.1:{free_port()}"
with tempfile.TemporaryDirectory() as tmp:
    launcher = Launcher([p for p in PROCESSES if p.name in STACK], local_values(Path(tmp), hub), Path(tmp))
    launcher.start(ready_timeout_s=40)
    s = open_client(hub)
    try:
        truth = []
        def on_truth(m):
            with lock:
                truth.append(m); logs["truth"].append((time.time_ns(), m))
        subscribe(s, keys.SIM_TRUTH, on_truth)
        for k, key in (("joy", keys.JOYSTICK), ("jout", keys.JOYSTICK_OUT), ("odom", keys.ODOM),
                       ("slow", keys.ODOM_SLOW), ("cmd", keys.CMD_VEL), ("enc", keys.ENCODERS)):
            subscribe(s, key, rec(k))
        while not truth: time.sleep(0.05)
        time.sleep(1.5)
        cases = {n: g for n, st, g in suite()}
        for n in names:
            r = drive_case(s, truth, lock, cases[n])
            print(n, r, flush=True)
    finally:
        s.close(); launcher.stop()

import pickle; pickle.dump(logs, open(sys.argv[2] if len(sys.argv) > 2 else "/tmp/wt14b/logs.pkl", "wb"))
