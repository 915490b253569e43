"""Fault injection on the simulated stack, run under supervisord from the generated config.

`python -m bench.faults` starts the sim stack (every process of the list) under supervisord
(deploy.supervisord_conf, autorestart; the PID requires the safety limit), keeps the chair
turning in place (ω = 0.5 rad/s, free of the walls) as load, and injects, one at a time:
SIGKILL of each service (time to neutral, time to standstill, time until supervisord has it
back: its liveliness token reappears), a serial unplug/replug and garbage (the sim's fault
query), a lidar unplug/replug (the lidar sim's SIGUSR1), a malformed payload on every pub key,
and a logger SIGKILL (is the file readable, how many seconds were lost). After each fault that
stopped the chair the OLD command stream goes on for `HOLD_S`: any command frame written then is
an unexpected restart (ISO 14118); a new stream (a deliberate act) then measures "driving on a
new command". Results: bench/results/faults.json and a Markdown table on stdout.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import msgspec
import zenoh

from autochair import deploy
from autochair.logger.reader import Recording
from autochair.processes import by_name
from autochair.runtime.client import (
    Publisher,
    RequestError,
    open_client,
    request,
    subscribe,
    watch_alive,
)
from autochair_msgs import (
    Health,
    VelocityCommand,
    keys,
)
from autochair_msgs.sim import SimFault, SimFaultReply

BIN = Path(sys.executable).parent
RESULTS = Path(__file__).parent / "results" / "faults.json"
STACK = ["router", "estop", "sim", "gateway", "odometry", "pid", "control", "logger",
         "lidar-sim", "lidar", "mapping", "safety"]
DRIVE_CHAIN = ["estop", "gateway", "odometry", "pid"]  # a failure here must give neutral
ENC = msgspec.msgpack.Encoder()
HOLD_S = 2.0  # the old stream goes on this long after the fault has passed


def free_port() -> int:
    import socket
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def poll(cond: Callable[[], Any], timeout: float, interval: float = 0.005) -> Any:
    """`cond()` once it is truthy, or None after `timeout` seconds."""
    deadline = time.monotonic() + timeout
    while True:  # at least once, even with timeout 0
        v = cond()
        if v:
            return v
        if time.monotonic() >= deadline:
            return None
        time.sleep(interval)


class Tap:
    """Latest and recent messages of one key-table row, with receive times (the runtime's typed
    subscription: our own junk, in the malformed-payload test, is skipped)."""

    def __init__(self, session: zenoh.Session, topic: Any, keep: int = 4000) -> None:
        self.items: list[tuple[int, Any]] = []  # (receive time ns, message)
        self.keep = keep
        self.lock = threading.Lock()

        def cb(msg: Any) -> None:
            with self.lock:
                self.items.append((time.time_ns(), msg))
                if len(self.items) > 2 * self.keep:
                    del self.items[:-self.keep]

        self.sub = subscribe(session, topic, cb)

    def since(self, t_ns: int) -> list[Any]:
        with self.lock:
            return [m for t, m in self.items if t >= t_ns]

    def latest(self) -> Any:
        with self.lock:
            return self.items[-1][1] if self.items else None


class Stack:
    """The sim stack under supervisord (autorestart) from the generated config."""

    def __init__(self, work: Path, names: list[str]) -> None:
        self.work, self.names = work, names
        self.hub = f"tcp/127.0.0.1:{free_port()}"
        run = work / "run"
        run.mkdir(parents=True, exist_ok=True)
        self.record = run / "rec.mcap"
        self.config = work / "chair.toml"
        self.config.write_text(f'[zenoh]\nconnect = ["{self.hub}"]\n')
        values = {**deploy.CHAIR_VALUES, "hub": self.hub, "hub_port": self.hub.rsplit(":")[-1],
                  "run_dir": str(run), "serial_port": str(run / "arduino"),
                  "lidar_url": str(run / "lidar"), "record_path": str(self.record),
                  "state_dir": str(run)}
        paths = deploy.Paths(bin_dir=str(BIN), config=str(self.config), log_dir=str(work),
                             run_dir=str(work))
        self.conf = work / "supervisord.conf"
        self.conf.write_text(deploy.supervisord_conf([by_name(n) for n in names], values,
                                                     paths))
        self.proc = subprocess.Popen([str(BIN / "supervisord"), "-c", str(self.conf)],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)

    def ctl(self, *args: str) -> str:
        return subprocess.run([str(BIN / "supervisorctl"), "-c", str(self.conf), *args],
                              capture_output=True, text=True, timeout=20).stdout

    def pid(self, name: str) -> int:
        out = self.ctl("pid", name).strip()
        return int(out) if out.isdigit() else 0

    def stop(self) -> None:
        self.proc.send_signal(signal.SIGTERM)
        try:
            self.proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


class Probe:
    """A client on the hub: load generator, taps, liveliness and health."""

    def __init__(self, hub: str) -> None:
        self.session = open_client(hub, timeout_ms=10000)
        self.out = Tap(self.session, keys.JOYSTICK_OUT)
        self.truth = Tap(self.session, keys.SIM_TRUTH)
        self.limit = Tap(self.session, keys.SAFETY_LIMIT)
        self.scan = Tap(self.session, keys.SCAN, keep=100)
        self.health: dict[str, Health] = {}
        self.alive: dict[str, int] = {}  # service → time its token (re)appeared, ns
        self.gone: dict[str, int] = {}
        def on_health(h: Health) -> None:
            self.health[h.service] = h

        def on_token(name: str, alive: bool) -> None:
            (self.alive if alive else self.gone)[name] = time.time_ns()

        self.hsub = subscribe(self.session, keys.HEALTH, on_health)
        self.lsub = watch_alive(self.session, on_token)
        self.cmd = Publisher(self.session, keys.CMD_VEL)
        self.omega = 0.5
        self.stream_start_ns = time.time_ns()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._load, daemon=True)
        self._thread.start()

    def _load(self) -> None:
        while not self._stop.wait(0.05):  # 20 Hz, the rate of the command stream
            self.cmd.put(VelocityCommand(
                stamp_ns=time.time_ns(), v_mps=0.0, omega_radps=self.omega, source="faults",
                stream_start_ns=self.stream_start_ns))

    def new_stream(self) -> int:
        """A deliberate act: a command stream begun now (as a new `drive` would)."""
        self.stream_start_ns = time.time_ns()
        return self.stream_start_ns

    def resumes(self, since_ns: int) -> dict[str, Any]:
        """After a stop: the old stream goes on for HOLD_S (a command frame = unexpected
        restart); then a new stream, timed to its first command frame."""
        time.sleep(HOLD_S)  # the old stream keeps publishing meanwhile (the load thread)
        unexpected = self.driving_after(since_ns, 0.0) is not None
        t = self.new_stream()
        resumed = self.driving_after(t, 30)
        return {"unexpected_restart": unexpected,
                "new_command_drives_s": None if resumed is None else round((resumed - t) / 1e9,
                                                                           2)}

    def driving(self) -> bool:
        m = self.out.latest()
        return m is not None and m.reason == "command" and m.enable

    def turning(self) -> bool:
        """Driving, and the chair has spun up (a standstill then means something)."""
        t = self.truth.latest()
        return self.driving() and t is not None and abs(t.omega_radps) > 0.2

    def first_neutral(self, t_ns: int, timeout: float) -> float | None:
        """ms from t_ns to the first neutral output: a gateway frame, else the sim's voltages."""

        def find() -> float | None:
            outs = [m.stamp_ns for m in self.out.since(t_ns) if not m.enable]
            tru = [m.stamp_ns for m in self.truth.since(t_ns)
                   if m.longitudinal_v == 2.5 and m.angular_v == 2.5]
            cands = [s for s in outs + tru if s >= t_ns]
            return float(min(cands) - t_ns) / 1e6 if cands else None

        r: float | None = poll(find, timeout, 0.02)
        return r

    def standstill(self, t_ns: int, timeout: float) -> float | None:
        def find() -> float | None:
            for m in self.truth.since(t_ns):
                if abs(m.v_mps) < 0.01 and abs(m.omega_radps) < 0.01 and m.stamp_ns > t_ns:
                    return float(m.stamp_ns - t_ns) / 1e6
            return None

        r: float | None = poll(find, timeout, 0.02)
        return r

    def driving_after(self, t_ns: int, timeout: float) -> int | None:
        """Stamp of the first command frame written after t_ns (None: not within timeout)."""

        def find() -> int | None:
            return next((m.stamp_ns for m in self.out.since(t_ns)
                         if m.enable and m.reason == "command" and m.stamp_ns > t_ns), None)

        r: int | None = poll(find, timeout, 0.02)
        return r

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
        self.session.close()


def sim_fault(session: zenoh.Session, fault: SimFault) -> bool:
    try:
        return request(session, keys.SIM_FAULT, fault, SimFaultReply, timeout_s=5.0).ok
    except RequestError:
        return False


def junk_every_key(session: zenoh.Session) -> list[str]:
    """Publish an undecodable payload on every pub key of the table; returns the keys used."""
    used = []
    for t in keys.TOPICS:
        if t.kind != "pub":
            continue
        key = t.for_service("junk") if t.key.endswith("/*") else t.key
        for payload in (b"\xc1", b"\xff\x00garbage", b"\x92\x01"):  # never valid msgpack structs
            session.put(key, payload)
        used.append(t.key)
    return used


def decode_errors(health: dict[str, Health]) -> dict[str, dict[str, int]]:
    """key → {service: decode_errors count} from the services' health."""
    out: dict[str, dict[str, int]] = {}
    for svc, h in health.items():
        for name, n in h.counters.items():
            if name.startswith("decode_errors:"):
                out.setdefault(name.split(":", 1)[1], {})[svc] = n
    return out


def kill_one(stack: Stack, probe: Probe, name: str) -> dict[str, Any]:
    """SIGKILL one service while driving: neutral, standstill, restart, driving again."""
    if not poll(probe.turning, 30, 0.05):
        return {"service": name, "error": "not driving before the kill"}
    pid = stack.pid(name)
    spin = probe.truth.latest().omega_radps
    t = time.time_ns()
    os.kill(pid, signal.SIGKILL)
    neutral = probe.first_neutral(t, 3.0)
    still = probe.standstill(t, 5.0)
    back = poll(lambda: probe.alive.get(name, 0) > t and probe.alive[name], 20, 0.01)
    row = {"service": name, "in_drive_chain": name in DRIVE_CHAIN,
           "omega_before_radps": round(spin, 3),
           "neutral_ms": None if neutral is None else round(neutral, 1),
           "standstill_ms": None if still is None else round(still, 1),
           "restart_s": None if not back else round((back - t) / 1e9, 3)}
    if neutral is not None:  # it stopped: does it start by itself?
        since = t + int(neutral * 1e6)
        poll(lambda: stack.pid(name) is not None and probe.alive.get(name, 0) > t, 20, 0.05)
        row.update(probe.resumes(since))
    else:
        row.update(unexpected_restart=None, new_command_drives_s=None, still_driving=True)
    print(row, flush=True)
    return row


def run(work: Path, names: list[str], kill: list[str]) -> dict[str, Any]:
    res: dict[str, Any] = {"supervisor": "supervisord (generated by autochair.deploy, "
                                         "autorestart=true, startsecs=1)",
                           "load": "turning in place at 0.5 rad/s (CMD_VEL 20 Hz)"}
    stack = Stack(work, names)
    probe: Probe | None = None
    try:
        probe = Probe(stack.hub)
        # The PID obeys only streams begun after it heard the e-stop and the safety limit:
        # begin anew until it drives (as a person would press again).
        if not poll(lambda: set(names) - {"router"} <= set(probe.alive) and (
                probe.driving() or probe.new_stream() < 0), 90, 0.5):
            raise SystemExit(f"stack did not come up driving: alive {sorted(probe.alive)}; "
                             f"see {work}")
        time.sleep(2.0)  # let the chair spin up (load)
        kills = [kill_one(stack, probe, name) for name in kill if name != "sim"]
        res["sigkill"] = kills

        # --- serial unplug and replug (sim fault hook) --------------------------------------
        poll(probe.turning, 30, 0.05)
        t = time.time_ns()
        ok = sim_fault(probe.session, SimFault(kind="unplug", duration_s=2.0))
        neutral = probe.first_neutral(t, 3.0)
        poll(lambda: next((m for m in probe.out.since(t + 2_000_000_000)), None), 20, 0.05)
        res["serial_unplug"] = {
            "injected": ok, "unplugged_s": 2.0,
            "neutral_ms": None if neutral is None else round(neutral, 1),
            **probe.resumes(t + int((neutral or 0) * 1e6))}
        print(res["serial_unplug"], flush=True)

        # --- garbage into serial ---------------------------------------------------------------
        poll(probe.turning, 30, 0.05)
        before = dict(probe.health.get("gateway", Health(stamp_ns=0, service="", state="",
                                                         uptime_s=0)).counters)
        t = time.time_ns()
        ok = sim_fault(probe.session, SimFault(kind="garbage", count=4096))
        time.sleep(2.5)  # two health periods (1 Hz) for the counters to show
        after = probe.health["gateway"].counters
        outs = probe.out.since(t)
        res["serial_garbage"] = {
            "injected": ok, "bytes": 4096,
            "gateway_bad_frames": after.get("bad_frames", 0) - before.get("bad_frames", 0),
            "gateway_garbage_counters": {k: after[k] - before.get(k, 0) for k in after
                                         if "garbage" in k or "bad" in k},
            "neutral_frames_after": sum(1 for m in outs if not m.enable),
            "still_driving": probe.driving()}
        print(res["serial_garbage"], flush=True)

        # --- lidar unplug and replug (lidar sim: SIGUSR1 = unplugged for unplug_s = 3 s) -----
        poll(probe.turning, 30, 0.05)
        t = time.time_ns()
        os.kill(stack.pid("lidar-sim"), signal.SIGUSR1)
        stop_lim = poll(lambda: next((m for m in probe.limit.since(t)
                                      if m.reason == "scan stale"), None), 5, 0.01)
        still = probe.standstill(t, 6.0)
        scans_back = poll(lambda: next((m for m in probe.scan.since(t + 3_000_000_000)), None),
                          30, 0.05)
        since = t + int((still or 0) * 1e6)
        res["lidar_unplug"] = {
            "unplugged_s": 3.0,
            "stop_limit_ms": None if stop_lim is None else
            round((stop_lim.stamp_ns - t) / 1e6, 1),
            "standstill_ms": None if still is None else round(still, 1),
            "scans_back_after_replug_s": None if scans_back is None else
            round((scans_back.stamp_ns - t) / 1e9 - 3.0, 2),
            **probe.resumes(since)}
        print(res["lidar_unplug"], flush=True)

        # --- a malformed payload on every key -----------------------------------------------
        pids = {n: stack.pid(n) for n in names}
        uptimes = {n: h.uptime_s for n, h in probe.health.items()}
        before_err = decode_errors(probe.health)
        used = junk_every_key(probe.session)
        time.sleep(2.5)  # two health periods
        after_err = decode_errors(probe.health)
        counted = {k: {s: n - before_err.get(k, {}).get(s, 0) for s, n in v.items()
                       if n - before_err.get(k, {}).get(s, 0) > 0}
                   for k, v in after_err.items()}
        counted = {k: v for k, v in counted.items() if v}
        subscribed_keys = set(counted)
        died = [n for n in names if stack.pid(n) != pids[n]]
        restarted = [n for n, h in probe.health.items() if h.uptime_s < uptimes.get(n, 0)]
        res["malformed_payload"] = {
            "keys": len(used), "keys_counted": len(subscribed_keys),
            "keys_no_decoding_subscriber": sorted(set(used) - subscribed_keys),
            "counted": counted, "died": died, "restarted": restarted,
            "still_driving": probe.driving()}
        print({k: v for k, v in res["malformed_payload"].items() if k != "counted"}, flush=True)

        # --- logger SIGKILL: file readable, seconds lost ------------------------------------
        rec = sorted(stack.record.parent.glob("*.mcap"))
        t = time.time_ns()
        os.kill(stack.pid("logger"), signal.SIGKILL)
        time.sleep(1.0)
        out: dict[str, Any] = {"files": [str(p.name) for p in rec]}
        if rec:
            copy = work / "killed.mcap"
            shutil.copy(rec[-1], copy)
            r = Recording(copy)
            last, n = 0, 0
            for m in r.messages():
                n += 1
                last = max(last, m.log_ns)
            out.update(readable=n > 0, messages=n, reader_error=r.error,
                       seconds_lost=round((t - last) / 1e9, 3) if last else None)
        res["logger_sigkill"] = out
        print(out, flush=True)
        if "sim" in kill:  # last: the simulated chair itself (its state restarts from zero)
            res["sigkill"].append(kill_one(stack, probe, "sim"))
    finally:
        if probe is not None:
            probe.close()
        stack.stop()
    return res


def table(res: dict[str, Any]) -> str:
    rows = ["| fault | neutral (ms) | standstill (ms) | restart (s) | old stream restarts "
            "the chair | a new command drives (s) |", "|---|---|---|---|---|---|"]

    def f(v: Any) -> str:
        return "—" if v is None else ("**yes**" if v is True else "no" if v is False else str(v))

    def end(k: dict[str, Any]) -> str:
        if k.get("still_driving"):
            return "— (never stopped) | — |"
        return f"{f(k.get('unexpected_restart'))} | {f(k.get('new_command_drives_s'))} |"

    for k in res.get("sigkill", []):
        name = f"SIGKILL {k['service']}" + (" (drive chain)" if k.get("in_drive_chain") else "")
        rows.append(f"| {name} | {f(k.get('neutral_ms'))} | {f(k.get('standstill_ms'))} | "
                    f"{f(k.get('restart_s'))} | {end(k)}")
    s = res.get("serial_unplug", {})
    rows.append(f"| serial unplug 2 s | {f(s.get('neutral_ms'))} | — | — | {end(s)}")
    ld = res.get("lidar_unplug", {})
    rows.append(f"| lidar unplug 3 s | stop limit {f(ld.get('stop_limit_ms'))} | "
                f"{f(ld.get('standstill_ms'))} | scans back "
                f"{f(ld.get('scans_back_after_replug_s'))} after replug | {end(ld)}")
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", type=Path, default=RESULTS)
    ap.add_argument("--kill", default=",".join(n for n in STACK if n not in ("router",
                                                                              "logger")),
                    help="services to SIGKILL, comma-separated")
    ap.add_argument("--keep", action="store_true", help="keep the work dir (logs)")
    args = ap.parse_args(argv)
    if not (BIN / "supervisord").exists():
        print("faults: supervisord is not installed in this venv (pip install supervisor)",
              file=sys.stderr)
        return 2
    work = Path(tempfile.mkdtemp(prefix="autochair-faults-"))
    try:
        res = run(work, STACK, [k for k in args.kill.split(",") if k])
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(res, indent=2) + "\n")
    print(table(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
