"""Benchmarks: `python -m bench [NAME ...]` (or `./dev bench`); results in bench/results/."""
