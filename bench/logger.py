"""Logger benchmark: throughput with zero drops and CPU at the stack's normal load.

A publisher (this process) → the logger process over loopback Zenoh via a private hub.
- Throughput: step up the publish rate (5 s per step, drive-chain message mix); a step passes
  if the logger drops nothing with a small queue (queue_size = 5000, i.e. 0.25 s at 20 k/s, so
  a writer that falls behind must drop) and has written everything 3 s after the step.
- CPU: the logger's CPU % of one core (psutil) at the stack's normal load (the drive-chain mix
  at its table rates, ~1300 msg/s) and idle (baseline, same run).
- Writer ceiling: Recorder.write alone in this process (no Zenoh), msg/s.
Results: bench/results/logger.json. Goals: ≥ 20 000 msg/s zero drops; ≤ 10 % of a core.
"""

from __future__ import annotations

import json
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any, cast

import msgspec
import psutil
import zenoh
from tests.logger_samples import samples

from autochair.logger.writer import LoggerConfig, Recorder
from autochair.runtime.config import ConfigError, ZenohSettings
from autochair.runtime.session import open_session
from autochair_msgs import Health, keys

RESULTS = Path(__file__).parent / "results" / "logger.json"
# The stack's logged 100 Hz streams and tf (logged rows only: the writer knows no other).
MIX: list[keys.Topic[Any]] = [keys.ENCODERS, keys.JOYSTICK_OUT, keys.ODOM, keys.TF,
                              keys.PID_STATUS, keys.SIM_TRUTH]
RATES = [2000, 5000, 10000, 15000, 20000, 30000, 45000, 60000]
QUEUE = 5000
ENC = msgspec.msgpack.Encoder()


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait(cond: Any, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.02)
    return False


class Bench:
    def __init__(self, tmp: Path) -> None:
        self.hub = f"tcp/127.0.0.1:{free_port()}"
        py = sys.executable
        self.router = subprocess.Popen([py, "-m", "autochair.router.node", "--listen", self.hub],
                                       stderr=subprocess.DEVNULL)
        self.logger = subprocess.Popen(
            [py, "-m", "autochair.logger.node", "--connect", self.hub, "--set",
             f"path={tmp}/bench.mcap", "--set", f"queue_size={QUEUE}", "--log-level",
             "WARNING"], stderr=subprocess.DEVNULL)
        self.proc = psutil.Process(self.logger.pid)
        wait(lambda: self._open(ZenohSettings(connect=[self.hub])), 15)
        self.health: Health | None = None
        dec = msgspec.msgpack.Decoder(Health)

        def on_health(s: zenoh.Sample) -> None:
            self.health = dec.decode(s.payload.to_bytes())

        self.session.declare_subscriber("autochair/health/logger", on_health)
        self.pubs = {t.key: self.session.declare_publisher(
            t.key, congestion_control=zenoh.CongestionControl.BLOCK) for t in MIX}
        assert wait(lambda: all(cast(Any, p.matching_status).matching
                                for p in self.pubs.values()), 20)
        self.payloads = {t.key: ENC.encode(samples(1)[t.key]) for t in MIX}

    def _open(self, settings: ZenohSettings) -> bool:
        try:
            self.session = open_session(settings)
            return True
        except ConfigError:
            return False

    def counter(self, name: str) -> int:
        return self.health.counters.get(name, 0) if self.health else 0

    def publish(self, rate: float, seconds: float, weights: dict[str, float]) -> int:
        """Publish the mix at `rate` msg/s total (in 1 ms batches); returns messages sent."""
        keys_ = list(weights)
        total = sum(weights.values())
        cum = [0.0] * len(keys_)
        sent = 0
        start = time.monotonic()
        tick = 0
        while True:
            tick += 1
            target = start + tick * 0.001
            if target - start > seconds:
                break
            while time.monotonic() < target:
                time.sleep(0.0002)
            for i, k in enumerate(keys_):
                cum[i] += rate * weights[k] / total * 0.001
                while cum[i] >= 1.0:
                    self.pubs[k].put(self.payloads[k])
                    cum[i] -= 1.0
                    sent += 1
        return sent

    def cpu_percent(self, fn: Any) -> tuple[float, Any]:
        c0 = self.proc.cpu_times()
        t0 = time.monotonic()
        out = fn()
        c1 = self.proc.cpu_times()
        used = (c1.user - c0.user) + (c1.system - c0.system)
        return 100.0 * used / (time.monotonic() - t0), out

    def close(self) -> None:
        self.session.close()
        for p in (self.logger, self.router):
            p.terminate()
            try:
                p.wait(20)
            except subprocess.TimeoutExpired:
                p.kill()


def writer_ceiling(tmp: Path, n: int = 30000) -> float:
    rec = Recorder(LoggerConfig(path=str(tmp / "ceiling.mcap")), 0, 0.0)
    items = [(t.key, ENC.encode(samples(i)[t.key])) for i in range(10) for t in MIX]
    t0 = time.perf_counter()
    for i in range(n):
        k, p = items[i % len(items)]
        rec.write(k, p, i)
    rec.finish()
    return n / (time.perf_counter() - t0)


def main(argv: list[str] | None = None) -> int:
    out: dict[str, Any] = {"queue_size": QUEUE, "cpu_count": psutil.cpu_count(),
                           "mix": [t.key for t in MIX]}
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        out["writer_ceiling_msg_s"] = round(statistics.median(
            writer_ceiling(tmp) for _ in range(3)))
        print(f"writer alone (no Zenoh): {out['writer_ceiling_msg_s']} msg/s", flush=True)
        b = Bench(tmp)
        try:
            assert wait(lambda: b.health is not None, 10), "no logger health"
            idle, _ = b.cpu_percent(lambda: time.sleep(5))
            table = {t.key: float(t.rate_hz or 0) for t in MIX}
            stack, sent = b.cpu_percent(lambda: b.publish(sum(table.values()), 10, table))
            out["idle_cpu_pct"] = round(idle, 2)
            out["stack_load_msg_s"] = round(sent / 10)
            out["stack_cpu_pct"] = round(stack, 2)
            print(f"logger CPU: idle {idle:.1f} %, stack load ~{sent / 10:.0f} msg/s "
                  f"{stack:.1f} % of a core", flush=True)
            steps = []
            equal = {k: 1.0 for k in table}
            best = 0
            for rate in RATES:
                written0, dropped0 = b.counter("written"), b.counter("dropped")
                t0 = time.monotonic()
                cpu, sent = b.cpu_percent(lambda rate=rate: b.publish(rate, 5, equal))
                achieved = sent / (time.monotonic() - t0)
                drained = wait(lambda sent=sent, w0=written0: b.counter("written") - w0 >= sent,
                               3.5)
                dropped = b.counter("dropped") - dropped0
                ok = drained and dropped == 0
                steps.append({"target_msg_s": rate, "published_msg_s": round(achieved),
                              "dropped": dropped, "drained": drained,
                              "logger_cpu_pct": round(cpu, 1), "pass": ok})
                print(f"  {rate:>6} msg/s target, {achieved:>7.0f} published: "
                      f"dropped {dropped}, drained {drained}, logger CPU {cpu:.0f} %",
                      flush=True)
                if not ok:
                    break
                best = round(achieved)
            out["steps"] = steps
            out["max_zero_drop_msg_s"] = best
        finally:
            b.close()
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(out, indent=2) + "\n")
    print(f"max zero-drop throughput {out['max_zero_drop_msg_s']} msg/s (goal 20000); "
          f"stack CPU {out['stack_cpu_pct']} % (goal ≤ 10 %) → {RESULTS}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
