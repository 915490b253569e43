"""CPU per service and recording size per hour: the idle simulated stack, the soak's driving
pattern, and the transport floor (a bare Zenoh publisher and subscriber pair), in one run.

`python -m bench cpu` (or `python -m bench.cpu [--window S] [--warmup S] [--slices N]`) runs,
one after the other:
- **idle**: every process of the list with --sim (`processes.selected(sim=True)`, started by
  the Launcher as the soak does), nothing commanded;
- **driving**: the same stack, fresh recording, driven by the soak's pattern (forward 0.5 m/s
  to x = 3 m, back 0.4 m/s to x = 0.5 m, a 3 s turn each way, repeated; a new command stream
  per phase, blind reverse allowed for autonomy as bench/soak.py configures);
- **floor**: two bare Python processes, one publishing the stack's main streams at their
  table rates with the payload sizes seen on the idle stack, one subscribed to them all
  (receives and copies each payload, nothing else), peer to peer over loopback.

CPU is user + system time from /proc (psutil) over the measured window, after a warm-up, as %
of one core; the window is cut into `--slices` equal slices and each service's figure is the
median of the slices (this 2-core VM is noisy), the whole-window mean is kept too. Recording
size: bytes the logger's MCAP file grew over the window, scaled to one hour (chunks are
flushed every second, so the error is at most about one chunk).
Results: bench/results/cpu.json.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import msgspec
import psutil
import zenoh

from autochair.launcher import Launcher, free_port
from autochair.processes import local_values, selected
from autochair.runtime.client import Publisher, open_client, subscribe
from autochair.runtime.config import ZenohSettings
from autochair.runtime.session import open_session
from autochair_msgs import GroundTruth, Health, VelocityCommand, keys

RESULTS = Path(__file__).parent / "results" / "cpu.json"
ENC = msgspec.msgpack.Encoder()
# The stack's streams that the floor reproduces (every periodic publish row that runs in sim).
FLOOR_TOPICS: list[keys.Topic[Any]] = [
    keys.ENCODERS, keys.JOYSTICK, keys.JOYSTICK_OUT, keys.ODOM, keys.TF, keys.PID_STATUS,
    keys.SIM_TRUTH, keys.SCAN, keys.ESTOP_STATE, keys.SAFETY_LIMIT, keys.MAP_GRID,
    keys.MAP_CLOUD]


def cpu_s(pid: int) -> float:
    """User + system time of the process and of its live children (control's helper process,
    runtime/helper.py, is part of the control service's cost)."""
    try:
        proc = psutil.Process(pid)
        t = proc.cpu_times()
        children = proc.children(recursive=True)
    except psutil.NoSuchProcess:
        return float("nan")
    total = t.user + t.system
    for c in children:
        with contextlib.suppress(psutil.NoSuchProcess):  # (one that ended meanwhile)
            ct = c.cpu_times()
            total += ct.user + ct.system
    return float(total)


class Sampler:
    """CPU seconds of named processes, sampled at slice boundaries."""

    def __init__(self, pids: dict[str, int]) -> None:
        self.pids = pids
        self.marks: list[tuple[float, dict[str, float]]] = []

    def mark(self) -> None:
        self.marks.append((time.monotonic(), {n: cpu_s(p) for n, p in self.pids.items()}))

    def result(self) -> dict[str, dict[str, float]]:
        out: dict[str, dict[str, float]] = {}
        (t0, c0), (t1, c1) = self.marks[0], self.marks[-1]
        for name in self.pids:
            slices = [100 * (b[1][name] - a[1][name]) / (b[0] - a[0])
                      for a, b in zip(self.marks, self.marks[1:], strict=False)]
            out[name] = {"median_pct": round(statistics.median(slices), 2),
                         "mean_pct": round(100 * (c1[name] - c0[name]) / (t1 - t0), 2)}
        return out


def channel_breakdown(run: Path) -> dict[str, dict[str, float]]:
    """Per recorded channel: messages/s, raw kB/s and its share of the file in kB/s: how much
    smaller the file would be without it. The file's chunks are rebuilt as the logger writes
    them (1 s of messages, each with its 31-byte record header, zstd at the logger's level)
    with and without the channel, plus its 16-byte index entry per message. A channel that
    repeats another within a chunk (a derived copy) costs little; compressed alone, it would
    look expensive. Over the whole recording (warm-up included), biggest share first."""
    import zstandard
    from mcap.reader import make_reader

    from autochair.logger.writer import ZSTD_LEVEL

    chunks: dict[int, list[tuple[str, bytes]]] = {}
    count: dict[str, int] = {}
    size: dict[str, int] = {}
    t0, t1 = None, 0
    for path in sorted(run.glob("*.mcap")):
        with open(path, "rb") as f:
            for _, channel, msg in make_reader(f).iter_messages():
                k = channel.topic
                count[k] = count.get(k, 0) + 1
                size[k] = size.get(k, 0) + len(msg.data)
                header = (channel.id.to_bytes(2, "little") + msg.sequence.to_bytes(4, "little")
                          + msg.log_time.to_bytes(8, "little") * 2 + bytes(9))
                chunks.setdefault(msg.log_time // 10**9, []).append((k, header + msg.data))
                t0 = msg.log_time if t0 is None else min(t0, msg.log_time)
                t1 = max(t1, msg.log_time)
    zstd = zstandard.ZstdCompressor(level=ZSTD_LEVEL)

    def packed(without: str | None) -> int:
        return sum(len(zstd.compress(b"".join(r for k, r in c if k != without)))
                   for c in chunks.values())

    full = packed(None)
    span = max((t1 - (t0 or 0)) / 1e9, 1e-9)
    share = {k: full - packed(k) + 16 * count[k] for k in size}
    return {k: {"hz": round(count[k] / span, 1), "raw_kb_per_s": round(size[k] / span / 1e3, 2),
                "share_kb_per_s": round(share[k] / span / 1e3, 2)}
            for k in sorted(share, key=share.__getitem__, reverse=True)}


def recording_bytes(run: Path) -> int:
    return sum(p.stat().st_size for p in run.glob("*.mcap"))


def _measure(pids: dict[str, int], run: Path | None, window_s: float, slices: int,
             during: Any = None) -> dict[str, Any]:
    sampler = Sampler(pids)
    size0 = recording_bytes(run) if run else 0
    sampler.mark()
    t0 = time.monotonic()
    for i in range(1, slices + 1):
        end = t0 + window_s * i / slices
        while time.monotonic() < end:
            if during is not None:
                during()
            time.sleep(min(0.05, max(0.0, end - time.monotonic())))
        sampler.mark()
    per = sampler.result()
    res: dict[str, Any] = {
        "window_s": round(time.monotonic() - t0, 1),
        "services": per,
        "total_median_pct": round(sum(v["median_pct"] for v in per.values()), 1),
        "total_mean_pct": round(sum(v["mean_pct"] for v in per.values()), 1),
    }
    if run is not None:
        grown = recording_bytes(run) - size0
        res["recording_mb_per_h"] = round(grown / 1e6 * 3600 / res["window_s"], 1)
    return res


class Driver:
    """The soak's pattern (bench/soak.py), closed on the simulator's ground truth; one
    `step()` per 50 ms publishes one VelocityCommand (a new stream per phase). The PID obeys
    only a stream begun after its last stop (e.g. the start-up stop before the first safety
    limit): a chair commanded to move that stands still for 2 s gets a new stream."""

    def __init__(self, session: zenoh.Session) -> None:
        self.truth: GroundTruth | None = None

        def on_truth(m: GroundTruth) -> None:
            self.truth = m

        self.sub = subscribe(session, keys.SIM_TRUTH, on_truth)
        # What the PID says it does (its health's detail: why it obeys nothing, if so), for a
        # restart's record; not its 100 Hz status, which the hub would relay to this client.
        self.pid_detail = ""

        def on_pid(m: Health) -> None:
            self.pid_detail = m.detail

        self.pid_sub = subscribe(session, keys.HEALTH, on_pid, keys.HEALTH.for_service("pid"))
        self.why: list[str] = []  # the first restarts: phase, what the PID says, true pose
        self.pub = Publisher(session, keys.CMD_VEL)
        self.phase, self.t_phase, self.cycles = "fwd", time.monotonic(), 0
        self.stream = (self.phase, time.time_ns())
        self.next_t = time.monotonic()
        self.moved_at = time.monotonic()
        self.restarts = 0

    def step(self) -> None:
        now = time.monotonic()
        if now < self.next_t or self.truth is None:
            return
        self.next_t = max(self.next_t + 0.05, now)
        m, v, w = self.truth, 0.0, 0.0
        if self.phase == "fwd":
            v = 0.5
            if m.x_m > 3.0:
                self.phase = "rev"
        elif self.phase == "rev":
            v = -0.4
            if m.x_m < 0.5:
                self.phase, self.t_phase = "ccw", now
        elif self.phase == "ccw":
            w = 0.6
            if now - self.t_phase > 3.0:
                self.phase, self.t_phase = "cw", now
        else:
            w = -0.6
            if now - self.t_phase > 3.0:
                self.phase, self.cycles = "fwd", self.cycles + 1
        if abs(m.v_mps) > 0.02 or abs(m.omega_radps) > 0.02:
            self.moved_at = now
        if self.stream[0] != self.phase or now - self.moved_at > 2.0:
            if self.stream[0] == self.phase:
                self.restarts += 1
                if len(self.why) < 5:
                    self.why.append(f"{self.phase}: PID {self.pid_detail!r} at "
                                    f"({m.x_m:.2f}, {m.y_m:.2f}, {math.degrees(m.yaw_rad):.0f}°)")
            self.stream, self.moved_at = (self.phase, time.time_ns()), now
        self.pub.put(VelocityCommand(stamp_ns=time.time_ns(), v_mps=v, omega_radps=w,
                                     source="bench-cpu", stream_start_ns=self.stream[1]))

    def close(self) -> None:
        self.sub.undeclare()
        self.pid_sub.undeclare()
        self.pub.undeclare()


def payload_sizes(session: zenoh.Session, seconds: float) -> dict[str, int]:
    """Median payload size of each floor stream on the running stack."""
    seen: dict[str, list[int]] = {t.key: [] for t in FLOOR_TOPICS}

    def counter(key: str) -> Any:
        return lambda s: seen[key].append(len(s.payload))

    subs = [session.declare_subscriber(t.key, counter(t.key)) for t in FLOOR_TOPICS]
    time.sleep(seconds)
    for s in subs:
        s.undeclare()
    return {k: int(statistics.median(v)) if v else 0 for k, v in seen.items()}


def run_stack(case: str, args: argparse.Namespace, work: Path,
              sizes: dict[str, int] | None = None) -> dict[str, Any]:
    run = work / case
    conf = work / f"{case}.toml"
    # As the soak: the pattern reverses as autonomy, allowed blind (this is about resources).
    conf.write_text("[safety]\nblind_reverse_autonomy_mps = 0.4\n")
    hub = f"tcp/127.0.0.1:{free_port()}"
    procs = selected(sim=True)
    launcher = Launcher(procs, local_values(run, hub), run, restart=False)
    launcher.env["AUTOCHAIR_CONFIG"] = str(conf)
    launcher.start(ready_timeout_s=60)
    session = open_client(hub, timeout_ms=10000)
    driver: Driver | None = None
    try:
        if case == "driving":
            driver = Driver(session)
        t_end = time.monotonic() + args.warmup
        while time.monotonic() < t_end:
            if driver is not None:
                driver.step()
            time.sleep(0.02)
        if sizes is not None:
            sizes.update(payload_sizes(session, 2.0))
        pids = {p.name: launcher.pid(p.name) or 0 for p in procs}
        res = _measure(pids, run, args.window, args.slices,
                       during=driver.step if driver is not None else None)
        dead = [n for n, c in launcher.children.items() if c.state == "exited"]
        res["died"] = dead
        if driver is not None:
            res["pattern_cycles"] = driver.cycles
            res["pattern_phase_at_end"] = driver.phase
            res["stream_restarts"] = driver.restarts
            if driver.why:
                res["restarts_first"] = driver.why
    finally:
        if driver is not None:
            driver.close()
        session.close()
        launcher.stop()
    res["channels"] = channel_breakdown(run)
    return res


# --- the transport floor -------------------------------------------------------------------
def _floor_session(role: str, endpoint: str) -> zenoh.Session:
    if role == "pub":
        return open_session(ZenohSettings(connect=[], listen=[endpoint]))
    return open_session(ZenohSettings(connect=[endpoint]))


def floor_role(role: str, endpoint: str, spec: str) -> int:
    """One process of the floor pair; runs until stdin closes."""
    streams: dict[str, tuple[float, int]] = json.loads(spec)  # key → (rate, size)
    session = _floor_session(role, endpoint)
    stop = threading.Event()

    def wait_stdin() -> None:
        sys.stdin.read()
        stop.set()

    threading.Thread(target=wait_stdin, daemon=True).start()
    if role == "sub":
        got = [0]

        def on_sample(s: zenoh.Sample) -> None:
            s.payload.to_bytes()
            got[0] += 1

        sub = session.declare_subscriber("floor/**", on_sample)
        print("ready", flush=True)
        stop.wait()
        sub.undeclare()
        print(json.dumps({"received": got[0]}), flush=True)
    else:
        base = max(rate for rate, _ in streams.values())  # the tick: the fastest stream's
        pubs = {k: (session.declare_publisher(f"floor/{k}", express=True,
                                              congestion_control=zenoh.CongestionControl.DROP),
                    bytes(size), round(base / rate)) for k, (rate, size) in streams.items()}
        print("ready", flush=True)
        tick, next_t, sent = 0, time.monotonic(), 0
        while not stop.is_set():
            for pub, payload, every in pubs.values():
                if tick % every == 0:
                    pub.put(payload)
                    sent += 1
            tick += 1
            next_t += 1.0 / base
            stop.wait(max(0.0, next_t - time.monotonic()))
        print(json.dumps({"sent": sent}), flush=True)
    session.close()
    return 0


def run_floor(args: argparse.Namespace, sizes: dict[str, int]) -> dict[str, Any]:
    streams = {t.key: (float(t.rate_hz or 1), max(sizes.get(t.key, 0), 1))
               for t in FLOOR_TOPICS}
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    spec = json.dumps(streams)
    procs: dict[str, subprocess.Popen[str]] = {}
    for role in ("pub", "sub"):
        p = procs[role] = subprocess.Popen(
            [sys.executable, "-m", "bench.cpu", "--floor-role", role, "--endpoint", endpoint,
             "--spec", spec], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        assert p.stdout is not None
        p.stdout.readline()  # "ready"
        time.sleep(0.5)
    try:
        time.sleep(min(args.warmup, 10.0))
        res = _measure({r: p.pid for r, p in procs.items()}, None, args.window, args.slices)
    finally:
        counts = {}
        for p in procs.values():
            out, _ = p.communicate("", timeout=20)
            counts.update(json.loads(out.strip().splitlines()[-1]))
    res["streams"] = {k: {"rate_hz": r, "payload_bytes": s} for k, (r, s) in streams.items()}
    res["msgs_per_s"] = round(sum(r for r, _ in streams.values()), 1)
    res.update(counts)
    return res


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--window", type=float, default=60.0, help="measured seconds per case")
    ap.add_argument("--warmup", type=float, default=15.0, help="seconds before measuring")
    ap.add_argument("--slices", type=int, default=6, help="slices of the window (medians)")
    ap.add_argument("--cases", default="idle,driving,floor")
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument("--keep", action="store_true", help="keep the work dir (logs, recordings)")
    ap.add_argument("--floor-role", choices=("pub", "sub"), help=argparse.SUPPRESS)
    ap.add_argument("--endpoint", help=argparse.SUPPRESS)
    ap.add_argument("--spec", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.floor_role:
        return floor_role(args.floor_role, args.endpoint, args.spec)
    cases = args.cases.split(",")
    work = Path(tempfile.mkdtemp(prefix="autochair-cpu-"))
    res: dict[str, Any] = {"cpus": os.cpu_count(), "python": sys.version.split()[0],
                           "window_s": args.window, "warmup_s": args.warmup,
                           "slices": args.slices, "load_before": os.getloadavg()}
    sizes: dict[str, int] = {}
    try:
        for case in cases:
            print(f"--- {case}", flush=True)
            if case == "floor":
                if not sizes:  # no idle case ran: the sizes of a short idle stack
                    run_stack("sizes", argparse.Namespace(**{**vars(args), "window": 2.0,
                                                             "slices": 1, "warmup": 5.0}),
                              work, sizes)
                res["floor"] = run_floor(args, sizes)
            else:
                res[case] = run_stack(case, args, work, sizes if case == "idle" else None)
            print(json.dumps({k: v for k, v in res[case].items() if k != "streams"}, indent=1),
                  flush=True)
    finally:
        if args.keep:
            print(f"work dir kept: {work}")
        else:
            shutil.rmtree(work, ignore_errors=True)
    res["load_after"] = os.getloadavg()
    if "floor" in res:  # a loaded machine inflates every figure alike; ratios compare runs
        floor = res["floor"]["total_median_pct"]
        res["ratio_to_floor"] = {c: round(res[c]["total_median_pct"] / floor, 2)
                                 for c in ("idle", "driving") if c in res and floor > 0}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(res, indent=2) + "\n")
    print(table(res))
    return 1 if any(res.get(c, {}).get("died") for c in ("idle", "driving")) else 0


def table(res: dict[str, Any]) -> str:
    lines = ["| service | idle % | driving % |", "|---|---|---|"]
    idle, drv = res.get("idle", {}), res.get("driving", {})
    names = list(idle.get("services", drv.get("services", {})))
    for n in names:
        a = idle.get("services", {}).get(n, {}).get("median_pct", "")
        b = drv.get("services", {}).get(n, {}).get("median_pct", "")
        lines.append(f"| {n} | {a} | {b} |")
    lines.append(f"| **total** | {idle.get('total_median_pct', '')} | "
                 f"{drv.get('total_median_pct', '')} |")
    lines.append(f"| recording MB/h | {idle.get('recording_mb_per_h', '')} | "
                 f"{drv.get('recording_mb_per_h', '')} |")
    if "floor" in res:
        f = res["floor"]["services"]
        lines.append(f"floor ({res['floor']['msgs_per_s']} msg/s): pub "
                     f"{f['pub']['median_pct']} %, sub {f['sub']['median_pct']} %")
    if res.get("ratio_to_floor"):
        lines.append("total / floor: " + ", ".join(
            f"{c} {r}" for c, r in res["ratio_to_floor"].items()))
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
