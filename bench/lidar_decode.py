"""Lidar decode benchmark: one 1081-step MD scan (UTM-30LX-like, 3-char values), whole reply
bytes → range array, with autochair's vectorised decoder vs the `hokuyolx` package's decoder on
the same bytes (same run, same machine). Both check every sum char.

- autochair: `scip.parse_scan` (echo/status/timestamp/data checks, numpy decode); also the full
  ingest step `ScanDecoder.decode` (→ LaserScan with metres, NaN masks, clock sync).
- hokuyolx: what `HokuyoLX._send_req` + `get_dist` do after receiving the bytes: ascii decode and
  split, header compare, `_check_sum` of status and timestamp, `_convert2int`,
  `_process_scan_data` (its own functions, called unmodified).
Results: bench/results/lidar_decode.json. Goal: ≥ 20× faster than hokuyolx.
"""

from __future__ import annotations

import json
import statistics
import sys
import time
from codecs import decode
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from autochair.lidar.core import LaserParams, ScanDecoder
from autochair.protocol import scip

RESULTS = Path(__file__).parent / "results" / "lidar_decode.json"
RUNS = 2000


def make_scan() -> tuple[bytes, scip.ScanRequest, np.ndarray[Any, Any]]:
    rng = np.random.default_rng(0)
    values = rng.integers(23, 30000, 1081)
    values[::97] = 1  # a few error codes
    req = scip.ScanRequest("MD", 0, 1080, 1, 0, 0)
    return scip.encode_scan(req, 0, 0xABCDEF, values), req, values


def hokuyolx_decoder() -> Callable[[bytes], Any] | None:
    try:
        from hokuyolx import HokuyoLX  # type: ignore[import-untyped]
    except ImportError:
        return None
    dummy = HokuyoLX.__new__(HokuyoLX)  # no socket: only its decoding methods are used

    def run(raw: bytes) -> Any:
        lines = decode(raw[:-2], "ascii").split("\n")  # as HokuyoLX._recv
        if lines.pop(0) != "MD0000108001000":
            raise ValueError("header")
        if HokuyoLX._check_sum(lines.pop(0)) != "99":
            raise ValueError("status")
        HokuyoLX._convert2int(HokuyoLX._check_sum(lines.pop(0)))  # timestamp
        return HokuyoLX._process_scan_data(dummy, lines, False)

    return run


def median_ns(fn: Callable[[], object], runs: int = RUNS) -> float:
    for _ in range(20):
        fn()
    times = []
    for _ in range(runs):
        t = time.perf_counter_ns()
        fn()
        times.append(time.perf_counter_ns() - t)
    return statistics.median(times)


def main(argv: list[str] | None = None) -> int:
    raw, req, values = make_scan()
    block = raw[:-2]
    prefix = req.echo()[:13]
    ours = scip.parse_scan(block, prefix, 3).values
    assert ours.tolist() == values.tolist()
    params = LaserParams(23, 30000, 1440, 0, 1080, 540, 2400, "UTM-30LX (synthetic)")
    dec = ScanDecoder(params, req, "laser", lambda k, n: None)
    theirs_fn = hokuyolx_decoder()
    if theirs_fn is None:
        print("hokuyolx not installed: pip install 'autochair[bench]'")
        return 1
    theirs = theirs_fn(raw)
    assert theirs.tolist() == values.tolist(), "decoders disagree"

    t_ours = median_ns(lambda: scip.parse_scan(block, prefix, 3))
    t_ingest = median_ns(lambda: dec.decode(block, 1_700_000_000_000_000_000))
    t_theirs = median_ns(lambda: theirs_fn(raw), RUNS // 4)
    ratio = t_theirs / t_ours
    result = {
        "scan": {"steps": 1081, "encoding": "MD 3-char", "bytes": len(raw)},
        "runs": RUNS,
        "autochair_parse_scan_us": round(t_ours / 1e3, 2),
        "autochair_ingest_to_laserscan_us": round(t_ingest / 1e3, 2),
        "hokuyolx_us": round(t_theirs / 1e3, 2),
        "speedup_parse": round(ratio, 1),
        "speedup_ingest_step": round(t_theirs / t_ingest, 1),
        "goal_speedup": 20,
        "goal_met": ratio >= 20,
        "python": sys.version.split()[0],
        "numpy": np.__version__,
    }
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(result, indent=2) + "\n")
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
