"""Fuzz the Arduino frame decoder and the SCIP scan parser (mutated valid inputs + random bytes)
and the safety monitor's scan assessment (mutated scan fields and beams).

`python -m bench.fuzz [--n N] [--seed S]` feeds N inputs (default 1 000 000) into each parser,
counts every outcome by reason, and fails (exit 1) on any crash: an exception other than the
documented ones (FrameDecoder: none at all; SCIP: ScipError and its subclasses). The monitor
costs ~7 ms a scan, so it gets N/100 inputs; for it a "crash" is also a limit that is not
finite, negative or above the caps, a rejected scan that is not a stop in every direction, or a
scan without one valid beam that leaves any direction open. Results: bench/results/fuzz.json.
"""

from __future__ import annotations

import argparse
import json
import math
import random
import sys
import time
import traceback
from collections import Counter
from collections.abc import Callable
from pathlib import Path

import numpy as np

from autochair.protocol import arduino, scip
from autochair.runtime.config import ChairGeometry
from autochair.safety.core import SafetyCore, SafetyParams, Scan

MOUNT = ChairGeometry().laser_mount

RESULTS = Path(__file__).parent / "results" / "fuzz.json"


def mutate(rng: random.Random, seed: bytes, corpus: list[bytes]) -> bytes:
    """One mutation of `seed`: flips, byte sets, inserts, deletes, truncation, splices."""
    b = bytearray(seed)
    for _ in range(rng.choice((1, 1, 1, 2, 3, 8))):
        op = rng.randrange(7)
        i = rng.randrange(len(b) + 1)
        if op == 0 and b:
            b[min(i, len(b) - 1)] ^= 1 << rng.randrange(8)
        elif op == 1 and b:
            b[min(i, len(b) - 1)] = rng.choice((0, 0x0A, 0x30, 0x6F, 0xFF, rng.randrange(256)))
        elif op == 2:
            b[i:i] = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 5)))
        elif op == 3 and b:
            del b[i:i + rng.randrange(1, 5)]
        elif op == 4:
            del b[i:]
        elif op == 5:
            other = rng.choice(corpus)
            j = rng.randrange(len(other) + 1)
            b[i:] = other[j:]
        elif op == 6 and b:
            j = rng.randrange(len(b))
            b[i:i] = b[j:j + rng.randrange(1, 16)]  # repeat a piece
    return bytes(b)


def inputs(rng: random.Random, corpus: list[bytes], n: int, max_random: int) -> list[bytes]:
    out = []
    for _ in range(n):
        r = rng.random()
        if r < 0.8:
            out.append(mutate(rng, rng.choice(corpus), corpus))
        elif r < 0.9:
            out.append(rng.randbytes(rng.randrange(max_random)))
        else:
            out.append(rng.choice(corpus))  # valid, as a control: must be accepted
    return out


def arduino_corpus(rng: random.Random) -> list[bytes]:
    frames: list[bytes] = []
    for _ in range(200):
        frames.append(arduino.encode(arduino.Telemetry(
            rng.randrange(1 << 16), rng.randrange(1 << 32), rng.randrange(1 << 32),
            rng.randrange(1 << 32), rng.randrange(256))))
        frames.append(arduino.encode(arduino.Command(
            rng.randrange(1 << 16), rng.randrange(1 << 16), rng.randrange(1000, 4000),
            rng.randrange(1000, 4000), rng.randrange(256))))
    return frames + [frames[i] + frames[i + 1] for i in range(0, 40, 2)]


def fuzz_arduino(rng: random.Random, n: int, batch: int) -> dict[str, object]:
    corpus = arduino_corpus(rng)
    outcomes: Counter[str] = Counter()
    crashes: list[str] = []
    fields = ("bad_crc", "bad_cobs", "bad_length", "unknown_type", "oversize")
    done, t0 = 0, time.perf_counter()
    while done < n:
        for data in inputs(rng, corpus, min(batch, n - done), 80):
            dec = arduino.FrameDecoder()
            try:
                # The trailing delimiter ends the input: every byte is then judged.
                frames = dec.feed(data + b"\x00")
            except Exception:  # no exception is documented: any is a crash
                crashes.append(f"{data.hex()}: {traceback.format_exc(limit=1)}")
                continue
            s = dec.stats
            for f in fields:
                if getattr(s, f):
                    outcomes[f"rejected:{f}"] += getattr(s, f)
            if frames:
                outcomes["accepted_input"] += 1
                outcomes["frames"] += len(frames)
                for fr in frames:  # a frame that decodes re-encodes to bytes of the input
                    if arduino.encode(fr)[:-1] not in data:
                        crashes.append(f"{data.hex()}: decoded {fr} not in input")
            elif s.bad_frames:
                outcomes["rejected_input"] += 1
            elif not data.strip(b"\x00"):
                outcomes["idle_input"] += 1  # only delimiters: no frame, nothing to reject
            else:
                outcomes["uncounted"] += 1  # bytes dropped with no reason: a bug
            if s.garbage_bytes:
                outcomes["garbage_bytes"] += s.garbage_bytes
        done += min(batch, n - done)
    dt = time.perf_counter() - t0
    return {"inputs": n, "seconds": round(dt, 2), "inputs_per_s": round(n / dt),
            "crashes": len(crashes), "crash_examples": crashes[:5],
            "outcomes": dict(sorted(outcomes.items()))}


def scip_corpus(rng: random.Random) -> list[tuple[bytes, bytes, int]]:
    """(block, echo prefix, nchars) of valid scan blocks of varied sizes and encodings."""
    out = []
    for _ in range(60):
        cmd = rng.choice(("MD", "MS"))
        start = rng.randrange(44, 600)
        end = min(725, start + rng.choice((2, 10, 40, 120, 681)))
        req = scip.ScanRequest(cmd, start, end, 1, 0, 0)
        top = 4095 if cmd == "MS" else 5600
        values = np.array([rng.randrange(0, top) for _ in range(end - start + 1)])
        block = scip.encode_scan(req, 0, rng.randrange(1 << 24), values)
        out.append((block, block[:2], req.nchars))
    return out


def fuzz_scip(rng: random.Random, n: int, batch: int) -> dict[str, object]:
    corpus = scip_corpus(rng)
    blocks = [c[0] for c in corpus]
    meta = {c[0]: c for c in corpus}
    outcomes: Counter[str] = Counter()
    crashes: list[str] = []
    done, t0 = 0, time.perf_counter()
    while done < n:
        for data in inputs(rng, blocks, min(batch, n - done), 300):
            _, prefix, nchars = meta.get(data) or rng.choice(corpus)
            reader = scip.ReplyReader()
            try:
                # As the ingest does: the reader splits replies at LF LF, then each is parsed;
                # the trailing LF LF ends the input so every byte is judged.
                found = reader.feed(data + b"\n\n")
            except Exception:
                crashes.append(f"{data[:200]!r}: {traceback.format_exc(limit=2)}")
                continue
            if reader.discarded:
                outcomes["rejected:reader_overflow"] += 1
            if not found:
                outcomes["no_reply"] += 1  # only line feeds: nothing to parse
            for block in found:
                try:
                    scan = scip.parse_scan(block, prefix, nchars)
                except scip.ScipError as e:  # documented: each one is a counted rejection
                    outcomes[f"rejected:{type(e).__name__}"] += 1
                    continue
                except Exception:
                    crashes.append(f"{data[:200]!r}: {traceback.format_exc(limit=2)}")
                    continue
                outcomes["accepted"] += 1
                if scan.values.size and (scan.values.min() < 0
                                         or scan.values.max() >= 1 << 18):
                    crashes.append(f"{data[:200]!r}: value out of range")
        done += min(batch, n - done)
    dt = time.perf_counter() - t0
    return {"inputs": n, "seconds": round(dt, 2), "inputs_per_s": round(n / dt),
            "crashes": len(crashes), "crash_examples": crashes[:5],
            "outcomes": dict(sorted(outcomes.items()))}


def scan_corpus(rng: random.Random) -> list[Scan]:
    """Simulated URG-04LX scans of the hallway, as the ingest delivers them."""
    from autochair.sim.lidar.scanner import UrgParams, ray_scan
    from autochair.sim.world import DEFAULT_WORLD, load_world

    world, urg = load_world(DEFAULT_WORLD), UrgParams()
    inc = 2 * math.pi / urg.ares
    nrng = np.random.default_rng(rng.randrange(1 << 30))
    out = []
    for _ in range(20):
        pose = (rng.uniform(0, 18), rng.uniform(-0.4, 0.4), rng.uniform(-math.pi, math.pi))
        raw = ray_scan(world, urg, pose, MOUNT, 0.01, nrng)
        r = np.where((raw < urg.dmin_mm) | (raw > urg.dmax_mm), np.nan, raw * 1e-3)
        out.append(Scan(r, (urg.amin - urg.afrt) * inc, inc, urg.dmin_mm * 1e-3,
                        urg.dmax_mm * 1e-3))
    return out


WEIRD = (0.0, -0.0, -1.0, 1e-12, 1e12, math.nan, math.inf, -math.inf)


def mutate_scan(rng: random.Random, scan: Scan) -> Scan:
    """One scan with a few fields or beams broken."""
    fields = {"ranges": scan.ranges.copy(), "angle_min": scan.angle_min,
              "angle_inc": scan.angle_inc, "range_min": scan.range_min,
              "range_max": scan.range_max, "frame_id": scan.frame_id}
    for _ in range(rng.choice((1, 1, 2, 3))):
        op = rng.randrange(8)
        r = fields["ranges"]
        assert isinstance(r, np.ndarray)
        if op < 3 and r.size:  # a run of beams: blind, absurd or close
            i = rng.randrange(r.size)
            r[i:i + rng.randrange(1, r.size + 1)] = rng.choice((*WEIRD, 0.05, 0.3, 100.0))
        elif op == 3:
            fields["ranges"] = r[:rng.randrange(r.size + 1)]
        elif op == 4:
            fields["ranges"] = np.concatenate((r, r[:rng.randrange(r.size + 1)]))
        elif op == 5:
            name = rng.choice(("angle_min", "angle_inc", "range_min", "range_max"))
            fields[name] = rng.choice((*WEIRD, rng.uniform(-10, 10)))
        elif op == 6:
            fields["angle_inc"] = -float(fields["angle_inc"])  # type: ignore[arg-type]
        else:
            fields["frame_id"] = rng.choice(("map", "", "laser "))
    return Scan(**fields)  # type: ignore[arg-type]


def fuzz_safety(rng: random.Random, n: int, batch: int) -> dict[str, object]:
    n = max(1, n // 100)
    core = SafetyCore(SafetyParams(mount=MOUNT))
    caps = (core.p.v_max_fwd_mps, core.p.v_max_rev_mps, core.p.omega_max_radps)
    corpus = scan_corpus(rng)
    outcomes: Counter[str] = Counter()
    crashes: list[str] = []
    t0 = time.perf_counter()
    for k in range(n):
        base = rng.choice(corpus)
        scan = base if rng.random() < 0.1 else mutate_scan(rng, base)  # 10 % valid controls
        v, w = rng.uniform(-0.5, 1.2), rng.uniform(-1.0, 1.0)
        try:
            lim = core.assess(scan, v, w)
        except Exception:
            crashes.append(f"input {k}: {traceback.format_exc(limit=2)}")
            continue
        bounds = (lim.v_fwd, lim.v_rev, lim.omega)
        if not all(math.isfinite(b) and 0.0 <= b <= c + 1e-9
                   for b, c in zip(bounds, caps, strict=True)):
            crashes.append(f"input {k}: bounds {bounds}")
        if lim.rejected and any(bounds):
            crashes.append(f"input {k}: rejected ({lim.rejected}) but not a stop: {bounds}")
        if not lim.rejected and not scan.valid().any() and any(bounds):
            crashes.append(f"input {k}: no valid beam but not a stop: {bounds}")
        if lim.rejected:
            outcomes[f"rejected:{lim.rejected}"] += 1
        elif lim.blind:
            outcomes["blind:" + "+".join(sorted(b.split(":")[0].removeprefix("blind ")
                                                for b in lim.blind))] += 1
        else:
            outcomes["assessed"] += 1
    dt = time.perf_counter() - t0
    return {"inputs": n, "seconds": round(dt, 2), "inputs_per_s": round(n / dt),
            "crashes": len(crashes), "crash_examples": crashes[:5],
            "outcomes": dict(sorted(outcomes.items()))}


TARGETS: dict[str, Callable[[random.Random, int, int], dict[str, object]]] = {
    "arduino_frame_decoder": fuzz_arduino, "scip_reader_parse_scan": fuzz_scip,
    "safety_monitor_assess": fuzz_safety}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--n", type=int, default=1_000_000, help="inputs per parser")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args(argv)
    results: dict[str, object] = {"seed": args.seed}
    crashed = 0
    for name, fn in TARGETS.items():
        r = fn(random.Random(args.seed), args.n, 10_000)
        results[name] = r
        crashed += int(r["crashes"])  # type: ignore[call-overload]
        print(f"{name}: {r['inputs']} inputs, {r['inputs_per_s']}/s, {r['crashes']} crashes, "
              f"{r['outcomes']}", flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(results, indent=2) + "\n")
    return 1 if crashed else 0


if __name__ == "__main__":
    sys.exit(main())
