"""Soak: the simulated stack driving a repeating pattern; RSS growth and dropped control frames.

`python -m bench.soak [--duration S] [--time-scale K]` runs every process of the list with the
simulator (Launcher, no restarts: a death is a failure) for S simulated seconds (default 3600).
The pattern, closed on the simulator's ground truth: forward at 0.5 m/s to x = 3 m, back at
0.4 m/s to x = 0.5 m, a turn in place each way; repeat. The safety monitor and the lidar run,
and the PID requires the safety limit.

Time scaling (K > 1) speeds up only the simulated chair (model, Arduino firmware, its 200 ms
watchdog, telemetry at 200 Hz of simulated time). The lidar sim still scans at 10 Hz wall time,
and every host service (gateway, odometry, PID, safety, logger) runs in wall time and sees K
times the telemetry rate, with its stale thresholds in wall time: K > 1 is a faster hour and a
load test at once, K = 1 is the real-time run. What was actually run is in the results.
Results: bench/results/soak.json.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import msgspec
import psutil

from autochair.launcher import Launcher, free_port
from autochair.processes import PROCESSES, local_values
from autochair.runtime.client import Publisher, open_client, subscribe
from autochair_msgs import Health, VelocityCommand, keys
from bench.faults import Tap, poll

RESULTS = Path(__file__).parent / "results" / "soak.json"
NAMES = ["router", "estop", "sim", "gateway", "odometry", "pid", "control", "logger",
         "lidar-sim", "lidar", "mapping", "safety"]
ENC = msgspec.msgpack.Encoder()


def rss_mb(launcher: Launcher) -> dict[str, float]:
    out = {}
    for name in NAMES:
        pid = launcher.pid(name)
        if pid:
            with contextlib.suppress(psutil.NoSuchProcess):
                out[name] = round(psutil.Process(pid).memory_info().rss / 2**20, 2)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--duration", type=float, default=3600.0, help="simulated seconds")
    ap.add_argument("--time-scale", type=float, default=1.0)
    ap.add_argument("--warmup", type=float, default=30.0, help="wall seconds before baseline")
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument("--keep", action="store_true",
                    help="keep the run directory (recording, logs) instead of removing it")
    args = ap.parse_args(argv)
    work = Path(tempfile.mkdtemp(prefix="autochair-soak-"))
    run = work / "run"
    conf = work / "soak.toml"
    # The pattern reverses as autonomy: allow that blind (the soak is about resources).
    conf.write_text(f"[safety]\nblind_reverse_autonomy_mps = 0.4\n\n[sim]\n"
                    f"time_scale = {args.time_scale}\n")
    hub = f"tcp/127.0.0.1:{free_port()}"
    procs = [p for p in PROCESSES if p.name in NAMES]
    launcher = Launcher(procs, local_values(run, hub), run, restart=False)
    launcher.env["AUTOCHAIR_CONFIG"] = str(conf)
    launcher.start(ready_timeout_s=60)
    session = open_client(hub, timeout_ms=10000)
    truth = Tap(session, keys.SIM_TRUTH, keep=200)
    health: dict[str, Health] = {}

    def on_health(h: Health) -> None:
        health[h.service] = h

    sub = subscribe(session, keys.HEALTH, on_health)
    pub = Publisher(session, keys.CMD_VEL)
    res: dict[str, Any] = {"requested_sim_s": args.duration, "time_scale": args.time_scale}
    try:
        poll(truth.latest, 30, 0.1)
        t_wall0 = time.monotonic()
        time.sleep(args.warmup)  # imports, first allocations, logger buffers: then baseline
        rss0 = rss_mb(launcher)
        h0 = {n: dict(h.counters) for n, h in health.items()}
        sim0 = truth.latest().sim_time_s
        phase, t_phase, cycles = "fwd", time.monotonic(), 0
        stream = (phase, time.time_ns())  # each phase is a new command stream
        while truth.latest().sim_time_s - sim0 < args.duration:
            if stream[0] != phase:
                stream = (phase, time.time_ns())
            m = truth.latest()
            v, w = 0.0, 0.0
            if phase == "fwd":
                v = 0.5
                if m.x_m > 3.0:
                    phase = "rev"
            elif phase == "rev":
                v = -0.4
                if m.x_m < 0.5:
                    phase, t_phase = "ccw", time.monotonic()
            elif phase == "ccw":
                w = 0.6
                if time.monotonic() - t_phase > 3.0 / args.time_scale:
                    phase, t_phase = "cw", time.monotonic()
            else:
                w = -0.6
                if time.monotonic() - t_phase > 3.0 / args.time_scale:
                    phase, cycles = "fwd", cycles + 1
            pub.put(VelocityCommand(stamp_ns=time.time_ns(), v_mps=v, omega_radps=w,
                                    source="soak", stream_start_ns=stream[1]))
            launcher.poll()
            dead = [n for n, c in launcher.children.items() if c.state == "exited"]
            if dead:
                res["died"] = dead
                break
            time.sleep(0.05)  # the 20 Hz command stream
        rss1 = rss_mb(launcher)
        h1 = {n: dict(h.counters) for n, h in health.items()}

        def delta(svc: str, counter: str) -> int:
            return h1.get(svc, {}).get(counter, 0) - h0.get(svc, {}).get(counter, 0)

        res.update(
            ran_sim_s=round(truth.latest().sim_time_s - sim0, 1),
            ran_wall_s=round(time.monotonic() - t_wall0, 1), pattern_cycles=cycles,
            rss_start_mb=rss0, rss_end_mb=rss1,
            rss_growth_mb={n: round(rss1[n] - rss0[n], 2) for n in rss0 if n in rss1},
            gateway_dropped_frames=delta("gateway", "dropped_frames"),
            gateway_bad_frames=delta("gateway", "bad_frames"),
            sim_host_timeouts=delta("sim", "host_timeouts"),
            sim_host_bad_frames=delta("sim", "host_bad_frames"),
            sim_frames_dropped_host_not_reading=delta("sim", "frames_dropped_host_not_reading"),
            overruns={n: {k: v - h0.get(n, {}).get(k, 0) for k, v in c.items()
                          if k.startswith("overruns:") and v - h0.get(n, {}).get(k, 0)}
                      for n, c in h1.items()},
        )
        res.setdefault("died", [])
    finally:
        sub.undeclare()
        session.close()
        launcher.stop()
        if args.keep:
            print(f"run directory kept: {work}")
        else:  # an hour's recording is ~200 MB: not left behind in /tmp
            shutil.rmtree(work, ignore_errors=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(res, indent=2) + "\n")
    print(json.dumps(res, indent=2))
    return 1 if res.get("died") else 0


if __name__ == "__main__":
    sys.exit(main())
