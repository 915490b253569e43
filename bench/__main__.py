"""Run the benchmarks: `python -m bench` runs all, `python -m bench chain` one of them."""

from __future__ import annotations

import importlib
import sys

BENCHES = ("chain", "lidar_decode", "logger", "control_eval", "cpu", "tune",
           "control_stack", "nav_eval", "loc_eval", "people")


def main(argv: list[str]) -> int:
    names = argv or list(BENCHES)
    unknown = [n for n in names if n not in BENCHES]
    if unknown:
        print(f"unknown benchmark(s): {', '.join(unknown)}; known: {', '.join(BENCHES)}")
        return 2
    failed = 0
    for name in names:
        print(f"=== bench {name}", flush=True)
        module = importlib.import_module(f"bench.{name}")
        failed += int(module.main([]) or 0)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
