"""Auto-tune and step responses, in lockstep with the simulated chair (deterministic).

Per axis: the relay probe's Ku/Tu against the thesis's table 5.1 (the baseline), the SOPDT fit
and its own Ku/Tu, the gains by ZN/TL/SIMC, and 0.5 steps (true velocity of the simulator):
the thesis's ZN PID (the baseline, same run) against the configured [pid] (the defaults: tuned
gains + feed-forward, from `autochair tune --lockstep`, which the process stack confirmed), the
gains and model identified in this run (+ feed-forward), and the plain rules without a model.
Ku both as 4d/(πa) and from the first harmonics (1/|G(jω)|), and the model against that point.

    .venv/bin/python -m bench tune
"""

from __future__ import annotations

import argparse
import cmath
import json
import math
import time
from pathlib import Path
from typing import Any

import msgspec

from autochair.pid.core import PidConfig, VelocityPidCore, make_core
from autochair.tune.core import AXES, simc, tyreus_luyben, ziegler_nichols
from autochair.tune.lockstep import core_for, identify, step_response, summary

RESULTS = Path(__file__).parent / "results" / "tune.json"
THESIS = {"longitudinal": (1.5, 1.75), "angular": (1.2, 1.33)}


def _s(x: float | None) -> str:
    return "never" if x is None else f"{x:.2f} s"


def main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(description=__doc__.split("\n")[0]).parse_args(argv)
    t0 = time.perf_counter()
    cfg = msgspec.structs.replace(PidConfig(), require_safety_limit=False, require_estop=False)
    out: dict[str, Any] = {}
    for axis in AXES:
        tu = identify(axis)
        r, m = tu.relay, tu.model
        g_m = m.frequency_response(2.0 * math.pi / r.tu_s)
        mku, mtu = m.ultimate()
        ku0, tu0 = THESIS[axis]
        steps: dict[str, Any] = {
            "thesis ZN (baseline)": summary(step_response(
                VelocityPidCore(require_estop=False), axis)),
            "configured [pid] (defaults + feed-forward)": summary(step_response(
                make_core(cfg), axis)),
        }
        steps["SIMC + feed-forward, both from this run"] = summary(step_response(
            core_for(axis, simc(m).as_tuple(), m, cfg.prefilter_s), axis))
        for g in (ziegler_nichols(r.ku, r.tu_s), tyreus_luyben(r.ku, r.tu_s), simc(m)):
            steps[f"{g.rule} from this run, no model"] = summary(step_response(
                core_for(axis, g.as_tuple()), axis))
        out[axis] = {
            "relay": {"ku": round(r.ku, 3), "tu_s": round(r.tu_s, 3),
                      "ku_error_pct": round(100 * (r.ku / ku0 - 1), 1),
                      "tu_error_pct": round(100 * (r.tu_s / tu0 - 1), 1),
                      "ku_first_harmonic": round(r.ku_h1, 3),
                      "ku_first_harmonic_error_pct": round(100 * (r.ku_h1 / ku0 - 1), 1),
                      "phase_deg": round(math.degrees(cmath.phase(r.point)), 1),
                      "thesis": {"ku": ku0, "tu_s": tu0}},
            "model": {"gain": round(m.gain, 3), "dead_band": round(m.dead_band, 3),
                      "tau1_s": round(m.tau1_s, 3), "tau2_s": round(m.tau2_s, 3),
                      "delay_s": round(m.delay_s, 3), "ku": round(mku, 3),
                      "tu_s": round(mtu, 3),
                      # the model against the relay's measured point (same frequency)
                      "gain_vs_relay_pct": round(100 * (abs(g_m) / abs(r.point) - 1), 1),
                      "phase_vs_relay_deg": round(math.degrees(cmath.phase(g_m / r.point)), 1)},
            "step_0.5": steps,
        }
        rel, mod = out[axis]["relay"], out[axis]["model"]
        print(f"{axis}: Ku {r.ku:.3f} ({rel['ku_error_pct']:+.1f} %), first harmonic "
              f"{r.ku_h1:.3f} ({rel['ku_first_harmonic_error_pct']:+.1f} %), Tu {r.tu_s:.3f} s "
              f"({rel['tu_error_pct']:+.1f} %); model Ku {mku:.3f} Tu {mtu:.3f} s, at the relay's "
              f"point {mod['gain_vs_relay_pct']:+.1f} % / {mod['phase_vs_relay_deg']:+.1f}°")
        for name, s in steps.items():
            print(f"  {name:42s} overshoot {s['overshoot_pct']:5.1f} %  settle ±5 % "
                  f"{_s(s['settle_5pct_s'])}  ±10 % {_s(s['settle_10pct_s'])}")
    out["wall_time_s"] = round(time.perf_counter() - t0, 1)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
