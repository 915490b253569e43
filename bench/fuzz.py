"""Fuzz the Arduino frame decoder and the SCIP scan parser: mutated valid inputs + random bytes.

`python -m bench.fuzz [--n N] [--seed S]` feeds N inputs (default 1 000 000) into each parser,
counts every outcome by reason, and fails (exit 1) on any crash: an exception other than the
documented ones (FrameDecoder: none at all; SCIP: ScipError and its subclasses). Results go to
bench/results/fuzz.json.
"""

from __future__ import annotations

import argparse
import json
import random
import sys
import time
import traceback
from collections import Counter
from collections.abc import Callable
from pathlib import Path

import numpy as np

from autochair.protocol import arduino, scip

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


TARGETS: dict[str, Callable[[random.Random, int, int], dict[str, object]]] = {
    "arduino_frame_decoder": fuzz_arduino, "scip_reader_parse_scan": fuzz_scip}


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
