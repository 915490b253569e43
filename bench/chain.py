"""Control-chain latency and sustained encoder rate, against a raw Zenoh 3-hop baseline.

Chain: this process plays the Arduino on a pty. It writes a telemetry frame into the gateway's
port and times the joystick frame that comes back with that frame's sequence number as its
ack (gateway → odometry → velocity PID → gateway: three Zenoh hops and two pty crossings).
Baseline, same run, same hub: this process publishes an equal-size payload that two relay
processes pass on (three Zenoh hops) back to it.

    python -m bench.chain [--duration 60] [--rates 100,200,400,800,1600] [--samples 3000]

Latency runs at the drive chain's rate (keys.DRIVE_RATE_HZ); the sustained rates go above it.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import tty
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import msgspec
import zenoh

from autochair.launcher import Launcher, free_port
from autochair.processes import PROCESSES, local_values
from autochair.protocol import arduino
from autochair.runtime.config import ZenohSettings
from autochair_msgs import EncoderSample, Health, VelocityCommand, keys

RESULTS = Path(__file__).parent / "results" / "chain.json"
BLOCKS = 6  # latency runs alternate chain / baseline blocks
RATE = keys.DRIVE_RATE_HZ  # the Arduino's telemetry rate


def percentile(xs: list[float], q: float) -> float:
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(q * len(xs)))]


def paced(n: int, rate_hz: float) -> Iterator[int]:
    """Yield 0..n-1 at `rate_hz` on the monotonic clock (sleep, then spin the last 0.2 ms)."""
    period = 1e9 / rate_hz
    t0 = time.perf_counter_ns()
    for i in range(n):
        target = t0 + i * period
        while (now := time.perf_counter_ns()) < target:
            if target - now > 300_000:
                time.sleep((target - now - 200_000) / 1e9)
        yield i


class FakeArduino:
    """The bench side of the pty: writes telemetry, reads joystick frames with their acks.
    Between runs it goes on sending at 20 Hz, as a real MCU never stops: a silent link is an
    odometry gap (a stop for the PID) and, after 2 s, a reopen by the gateway."""

    IDLE_S = 0.05

    def __init__(self) -> None:
        self.master, slave = os.openpty()
        tty.setraw(slave)
        self.slave_path = os.ttyname(slave)
        self._slave = slave  # keep open so the pty exists before the gateway opens it
        self.sent: dict[int, int] = {}  # frame index → perf_counter_ns at write
        self.acked: dict[int, int] = {}  # frame index → perf_counter_ns of its first ack
        self.frames_in = 0
        self.frame_index = 0
        self.mcu_us = 0.0
        self.counts = 0
        self._stop = threading.Event()
        self._busy = threading.Lock()  # held by a run; the idle sender yields to it
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        threading.Thread(target=self._idle, daemon=True).start()

    def _read(self) -> None:
        dec = arduino.FrameDecoder()
        while not self._stop.is_set():
            try:
                data = os.read(self.master, 4096)
            except OSError:
                time.sleep(0.01)
                continue
            now = time.perf_counter_ns()
            for f in dec.feed(data):
                if isinstance(f, arduino.Command):
                    self.frames_in += 1
                    # acks are 16-bit: unwrap against the newest frame written
                    idx = self.frame_index + arduino.wrap_delta(
                        self.frame_index & 0xFFFF, f.ack_seq, 16)
                    if f.enable and idx not in self.acked:
                        self.acked[idx] = now

    def _write(self, period_s: float, counts: int) -> None:
        """The next telemetry frame, `period_s` of MCU time after the last, wheels `counts`
        further."""
        self.frame_index += 1
        self.mcu_us += period_s * 1e6
        self.counts += counts
        seq = self.frame_index & 0xFFFF
        frame = arduino.encode(arduino.Telemetry(seq, int(self.mcu_us), self.counts,
                                                 self.counts, 0))
        os.write(self.master, frame)

    def _idle(self) -> None:
        while not self._stop.wait(self.IDLE_S):
            if self._busy.acquire(blocking=False):
                try:
                    self._write(self.IDLE_S, 0)
                finally:
                    self._busy.release()

    def run(self, rate_hz: float, n: int, counts_per_frame: int = 50) -> None:
        """Write `n` telemetry frames at `rate_hz`. Sequence, clock and counters carry on
        from the previous run, as a real MCU's would."""
        with self._busy:
            self.sent.clear()
            self.acked.clear()
            for _ in paced(n, rate_hz):
                self.sent[self.frame_index + 1] = time.perf_counter_ns()
                self._write(1.0 / rate_hz, counts_per_frame)

    def close(self) -> None:
        self._stop.set()
        os.close(self._slave)


# (service, health counter) along the chain, in order
HOPS = [("gateway", "frames_in"), ("gateway", "dropped_frames"), ("gateway", "bad_frames"),
        ("gateway", "disconnects"), ("odometry", "samples"), ("pid", "updates"),
        ("gateway", "commands")]


def clean_row(row: dict[str, Any]) -> bool:
    hops = row["hops"]
    return not (row["unanswered"] or hops["gateway.dropped_frames"] or hops["gateway.bad_frames"])


def chain_latencies(arduino_: FakeArduino) -> list[float]:
    return [(arduino_.acked[s] - t) / 1000 for s, t in arduino_.sent.items()
            if s in arduino_.acked]


class Baseline:
    """Three raw Zenoh hops: here → relay 1 → relay 2 → here, equal payloads, same hub."""

    def __init__(self, hub: str, payload_size: int) -> None:
        env = {**os.environ, "AUTOCHAIR_CONNECT": hub}
        self.relays = [subprocess.Popen(
            [sys.executable, "-m", "bench.relay", f"bench/k{i}", f"bench/k{i + 1}"], env=env,
            stdout=subprocess.PIPE, text=True) for i in (0, 1)]
        for r in self.relays:
            # Zenoh's own log lines may come first on stdout (open_session initialises them),
            # and more may follow: drain the pipe so a relay never blocks on it.
            lines = iter(r.stdout.readline, "") if r.stdout is not None else iter(())
            if not any(line.strip() == "relay ready" for line in lines):
                self._stop_relays()
                raise RuntimeError("a baseline relay did not start")
            threading.Thread(target=lambda it=lines: all(True for _ in it), daemon=True).start()
        self.session = zenoh.open(ZenohSettings(connect=[hub]).to_zenoh())
        self.got: dict[int, int] = {}
        self.session.declare_subscriber(
            "bench/k2", lambda s: self.got.setdefault(
                int.from_bytes(s.payload.to_bytes()[:4], "little"), time.perf_counter_ns()))
        self.pub = self.session.declare_publisher("bench/k0", express=True)
        self.pad = b"x" * (payload_size - 4)
        self.next = 0
        deadline = time.monotonic() + 10  # warm up until the path works end to end
        while not self.got and time.monotonic() < deadline:
            self.pub.put((0xFFFFFFFF).to_bytes(4, "little") + self.pad)
            time.sleep(0.05)

    def run(self, n: int, rate_hz: float) -> list[float]:
        sent: dict[int, int] = {}
        for _ in paced(n, rate_hz):
            self.next += 1
            sent[self.next] = time.perf_counter_ns()
            self.pub.put(self.next.to_bytes(4, "little") + self.pad)
        time.sleep(0.5)
        return [(self.got[i] - t) / 1000 for i, t in sent.items() if i in self.got]

    def close(self) -> None:
        self.session.close()
        self._stop_relays()

    def _stop_relays(self) -> None:
        for r in self.relays:
            r.terminate()
            r.wait(5)


def health_counters(session: zenoh.Session, since_ns: int) -> dict[str, int]:
    """The HOPS counters from the first health messages stamped after `since_ns`."""
    got: dict[str, Health] = {}
    dec = msgspec.msgpack.Decoder(Health)

    def on(sample: zenoh.Sample) -> None:
        h = dec.decode(sample.payload.to_bytes())
        if h.stamp_ns > since_ns:
            got.setdefault(h.service, h)

    sub = session.declare_subscriber(keys.HEALTH.key, on)
    services = {svc for svc, _ in HOPS}
    deadline = time.monotonic() + 3
    while not services <= set(got) and time.monotonic() < deadline:
        time.sleep(0.02)
    sub.undeclare()
    return {f"{svc}.{c}": got[svc].counters.get(c, 0) if svc in got else -1 for svc, c in HOPS}


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.chain", description=__doc__)
    ap.add_argument("--samples", type=int, default=3000, help="frames for the latency runs")
    ap.add_argument("--duration", type=float, default=60.0, help="seconds per sustained rate")
    ap.add_argument("--rates", default=f"{RATE},200,400,800,1600",
                    help="sustained rates to try, Hz")
    args = ap.parse_args(argv)

    hub = f"tcp/127.0.0.1:{free_port()}"
    run_dir = Path(tempfile.mkdtemp(prefix="autochair-bench-"))
    fake = FakeArduino()
    names = {"router", "estop", "gateway", "odometry", "pid"}
    procs = [p for p in PROCESSES if p.name in names]
    launcher = Launcher(procs, local_values(run_dir, hub, serial_port=fake.slave_path), run_dir,
                        restart=False)
    results: dict[str, object] = {"python": sys.version.split()[0], "cpus": os.cpu_count()}
    stop_cmd = threading.Event()
    try:
        launcher.start(ready_timeout_s=30)
        session = zenoh.open(ZenohSettings(connect=[hub]).to_zenoh())
        cmd_pub = session.declare_publisher(keys.CMD_VEL.key)
        enc = msgspec.msgpack.Encoder()

        def command() -> None:  # keep the PID active, as the control law would
            # The PID obeys a stream begun after it heard the e-stop (10 Hz): begin after that.
            stop_cmd.wait(0.5)
            start_ns = time.time_ns()
            while not stop_cmd.wait(0.05):
                cmd_pub.put(enc.encode(VelocityCommand(stamp_ns=time.time_ns(), v_mps=0.3,
                                                       omega_radps=0.0, source="bench",
                                                       stream_start_ns=start_ns)))

        threading.Thread(target=command, daemon=True).start()
        fake.run(RATE, 2 * RATE)  # warm-up: connections, caches, the PID becoming active
        time.sleep(0.5)

        # Chain and baseline alternate in blocks, so both see the same machine noise.
        payload = len(enc.encode(EncoderSample(stamp_ns=time.time_ns(), seq=1, mcu_time_us=1,
                                               left_counts=1, right_counts=1, status=0)))
        base_run = Baseline(hub, payload)
        lat, base = [], []
        try:
            for _ in range(BLOCKS):
                fake.run(RATE, args.samples // BLOCKS)
                time.sleep(0.5)
                lat += chain_latencies(fake)
                base += base_run.run(args.samples // BLOCKS, RATE)
        finally:
            base_run.close()
        chain_p50, chain_p99 = statistics.median(lat), percentile(lat, 0.99)
        base_p50, base_p99 = statistics.median(base), percentile(base, 0.99)
        results["latency_us"] = {
            "rate_hz": RATE, "samples": args.samples, "blocks": BLOCKS, "answered": len(lat),
            "baseline_answered": len(base),
            "chain_p50": round(chain_p50, 1), "chain_p99": round(chain_p99, 1),
            "baseline_3hop_p50": round(base_p50, 1), "baseline_3hop_p99": round(base_p99, 1),
            "p99_ratio_to_baseline": round(chain_p99 / base_p99, 2),
            "p50_ratio_to_baseline": round(chain_p50 / base_p50, 2),
        }
        print(json.dumps(results["latency_us"]), flush=True)

        sustained: list[dict[str, Any]] = []
        for rate in (float(r) for r in args.rates.split(",")):
            before = health_counters(session, time.time_ns())
            n = int(rate * args.duration)
            print(f"sustained {rate:.0f} Hz for {args.duration:.0f} s ...", flush=True)
            fake.run(rate, n)
            time.sleep(0.5)
            after = health_counters(session, time.time_ns())
            lat = chain_latencies(fake)
            missing = sorted(set(fake.sent) - set(fake.acked))
            row = {
                "rate_hz": rate, "frames": n, "answered": len(lat),
                "unanswered": n - len(lat), "unanswered_frames": missing[:10],
                # where frames went missing, hop by hop (serial in, Zenoh hops, serial out)
                "hops": {k: v - before[k] for k, v in after.items()},
                "p50_us": round(statistics.median(lat), 1) if lat else None,
                "p99_us": round(percentile(lat, 0.99), 1) if lat else None,
            }
            print(json.dumps(row), flush=True)
            sustained.append(row)
            if not clean_row(row):
                break
        clean = [r for r in sustained if clean_row(r)]
        results["sustained"] = sustained
        results["max_clean_rate_hz"] = max((r["rate_hz"] for r in clean), default=0.0)
        stop_cmd.set()
        time.sleep(0.1)  # let the command thread see it before the session closes
        session.close()
    finally:
        stop_cmd.set()
        launcher.stop()
        fake.close()
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(results, indent=2) + "\n")
    print(f"results in {RESULTS}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
