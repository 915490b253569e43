"""`autochair tune`: relay auto-tune of the velocity loops (Åström–Hägglund, with hysteresis),
per axis, run inside the velocity PID (a `autochair/pid/probe` request), so every gate of the
PID still holds: e-stop, stale stream, safety limit, owner, no unexpected start-up.

Per axis: hold the setpoint with the loop, an open-loop effort step (→ SOPDT model of the drive
chain), hold again, a relay (→ Ku, Tu), then stop. Prints Ku/Tu, the model, gains by ZN (the
thesis), Tyreus–Luyben and SIMC, and writes the chosen rule's [pid] snippet (--out) and a JSON
result that `autochair report --tune FILE` plots (step responses before/after).

On a real chair (no simulator running) it needs the e-stop service up and released, keeps the
setpoint, amplitude and speed bound small, and asks before it moves (--yes skips the prompt).
`--lockstep` runs the same probes in process against the simulated chair model (no stack).
"""

from __future__ import annotations

import argparse
import json
import math
import threading
import time
from pathlib import Path
from typing import Any

from autochair.cli import CliError
from autochair.commands.link import add_link_args

REAL_MAX = {"setpoint": 0.6, "relay": 0.25, "step": 0.15, "speed_bound": 1.0}


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "tune", help="relay auto-tune of the velocity loops (Ku, Tu, model, gains)",
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--axis", choices=("longitudinal", "angular", "both"), default="both")
    p.add_argument("--setpoint", type=float, default=0.5, help="operating point, m/s or rad/s")
    p.add_argument("--relay", type=float, default=0.2, help="relay amplitude d, effort")
    p.add_argument("--hysteresis", type=float, default=None,
                   help="relay ε (default: 4× the measured noise, at least 0.005)")
    p.add_argument("--step", type=float, default=0.1, help="step probe Δ, effort")
    p.add_argument("--speed-bound", type=float, default=1.0,
                   help="|measured| above this aborts the probe and stops the chair")
    p.add_argument("--settle", type=float, default=6.0, help="seconds to hold before a probe")
    p.add_argument("--rule", choices=("simc", "zn", "tl"), default="simc",
                   help="gain rule written to the snippet")
    p.add_argument("--out", default="tune.toml", help="[pid] snippet file")
    p.add_argument("--json", default="tune.json", help="result file (autochair report --tune)")
    p.add_argument("--yes", action="store_true", help="do not ask before moving the chair")
    p.add_argument("--lockstep", action="store_true",
                   help="run against the simulated chair model in process (no stack)")
    add_link_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    axes = ["longitudinal", "angular"] if args.axis == "both" else [args.axis]
    if not (0.1 <= args.setpoint <= 1.0 and 0 < args.relay <= 0.5 and 0 < args.step <= 0.5
            and 0 < args.speed_bound <= 1.5 and args.speed_bound > args.setpoint):
        raise CliError("want 0.1 ≤ --setpoint ≤ 1, 0 < --relay, --step ≤ 0.5 and "
                       "--setpoint < --speed-bound ≤ 1.5")
    if args.lockstep:
        results = {axis: lockstep_axis(args, axis) for axis in axes}
    else:
        results = stack_axes(args, axes)
    return report(args, results)


# --- the two ways to run the probes ----------------------------------------------------------

def lockstep_axis(args: argparse.Namespace, axis: str) -> dict[str, Any]:
    from autochair.tune.core import Probe, ProbeKind
    from autochair.tune.lockstep import Rig, run_probe

    eps = 0.005 if args.hysteresis is None else args.hysteresis
    step = run_probe(Rig(), Probe(ProbeKind.STEP, axis, args.step, duration_s=4.0,
                                  speed_bound=args.speed_bound), args.setpoint, args.settle)
    relay = run_probe(Rig(), Probe(ProbeKind.RELAY, axis, args.relay, eps, duration_s=30.0,
                                   speed_bound=args.speed_bound), args.setpoint, args.settle)
    return {"step": _probe_dict(step), "relay": _probe_dict(relay), "hysteresis": eps}


def _probe_dict(p: Any) -> dict[str, Any]:
    return {"state": p.state.value, "reason": p.reason, "setpoint": p.setpoint,
            "bias": p.bias, "trace": p.trace}


def stack_axes(args: argparse.Namespace, axes: list[str]) -> dict[str, dict[str, Any]]:
    from autochair.commands.link import tool_session
    from autochair.runtime.client import alive_services

    session = tool_session(args)
    try:
        alive = alive_services(session)
        if "pid" not in alive:
            raise CliError("no velocity PID is running (see `autochair status`)")
        simulated = "sim" in alive
        if not simulated:
            check_real_chair(args, session, alive)
        if not args.yes:
            confirm(args, axes, simulated)
        return {axis: stack_axis(args, session, axis) for axis in axes}
    finally:
        session.close()


def check_real_chair(args: argparse.Namespace, session: Any, alive: set[str]) -> None:
    """A real chair: the e-stop service up and heard (armed), and every bound small."""
    from autochair.runtime.client import subscribe
    from autochair_msgs import EStopState, keys

    for name, limit in REAL_MAX.items():
        value = getattr(args, name.replace("-", "_"))
        if value > limit:
            raise CliError(f"on a real chair --{name.replace('_', '-')} must be ≤ {limit:g}")
    if "estop" not in alive:
        raise CliError("real chair: the e-stop service must run (it is the stop you hold)")
    heard: list[EStopState] = []
    subscribe(session, keys.ESTOP_STATE, heard.append)
    deadline = time.monotonic() + 2.0
    while not heard and time.monotonic() < deadline:
        time.sleep(0.05)
    if not heard:
        raise CliError("real chair: no e-stop heartbeat heard: the e-stop is not armed")
    if heard[-1].latched:
        raise CliError("real chair: the e-stop is latched: release it (autochair release)")


def confirm(args: argparse.Namespace, axes: list[str], simulated: bool) -> None:
    where = "the SIMULATED chair" if simulated else "the REAL chair"
    moves = {"longitudinal": f"drive forward at about {args.setpoint:g} m/s (it travels "
                             f"roughly {args.setpoint * 45:.0f} m)",
             "angular": f"turn in place at about {args.setpoint:g} rad/s"}
    print(f"autochair tune will move {where}. Per axis, for about 45 s, it will "
          + "; then ".join(moves[a] for a in axes)
          + f", pushing the joystick ±{args.relay:g} effort around that; it stops at once "
            f"beyond {args.speed_bound:g}, on any e-stop or lost stream. Clear the space and "
            "keep the e-stop at hand.", flush=True)
    if input("Type 'yes' to start: ").strip().lower() != "yes":
        raise CliError("not started")


def stack_axis(args: argparse.Namespace, session: Any, axis: str) -> dict[str, Any]:
    """Hold the setpoint (a fresh command stream), step probe, hold, relay probe, stop."""
    from autochair.runtime.client import Publisher, subscribe
    from autochair_msgs import Odometry, VelocityCommand, keys

    pair = (args.setpoint, 0.0) if axis == "longitudinal" else (0.0, args.setpoint)
    pub = Publisher(session, keys.CMD_VEL)
    start_ns, stop = time.time_ns(), threading.Event()
    want = [pair]
    measured: list[float] = []

    def stream() -> None:
        while not stop.is_set():
            v, w = want[0]
            pub.put(VelocityCommand(stamp_ns=time.time_ns(), v_mps=v, omega_radps=w,
                                    source="cli", stream_start_ns=start_ns))
            time.sleep(0.05)

    def on_odom(o: Odometry) -> None:
        measured.append(o.v_mps if axis == "longitudinal" else o.omega_radps)

    subscribe(session, keys.ODOM, on_odom)
    sender = threading.Thread(target=stream, daemon=True)
    sender.start()
    try:
        print(f"{axis}: holding {args.setpoint:g} for {args.settle:g} s", flush=True)
        time.sleep(args.settle)
        step = probe(session, axis, "step", args.step, 0.0, 4.0, args.speed_bound)
        time.sleep(args.settle)
        last_s = measured[-keys.DRIVE_RATE_HZ:]  # the last second of odometry
        eps = args.hysteresis if args.hysteresis is not None else noise_band(last_s)
        relay = probe(session, axis, "relay", args.relay, eps, 30.0, args.speed_bound)
    finally:
        want[0] = (0.0, 0.0)  # an explicit stop, not just silence
        time.sleep(0.5)
        stop.set()
        sender.join()
    return {"step": step, "relay": relay, "hysteresis": eps}


def noise_band(samples: list[float]) -> float:
    """Relay hysteresis: 4σ of the measurement at the held setpoint, at least 0.005."""
    if len(samples) < 10:
        return 0.01
    mean = sum(samples) / len(samples)
    sd = math.sqrt(sum((s - mean) ** 2 for s in samples) / len(samples))
    return max(0.005, 4.0 * sd)


def probe(session: Any, axis: str, kind: str, amplitude: float, eps: float,
          duration_s: float, bound: float) -> dict[str, Any]:
    from autochair.runtime.client import request
    from autochair_msgs import PidProbeReply, PidProbeRequest, keys

    print(f"{axis}: {kind} probe", flush=True)
    r = request(session, keys.PID_PROBE, PidProbeRequest(
        action="start", kind=kind, axis=axis, amplitude=amplitude, hysteresis=eps,
        duration_s=duration_s, speed_bound=bound), PidProbeReply)
    if not r.ok:
        raise CliError(f"the PID refused the {kind} probe: {r.error}")
    deadline = time.monotonic() + duration_s + 5.0
    while time.monotonic() < deadline:
        time.sleep(0.25)
        r = request(session, keys.PID_PROBE, PidProbeRequest(action="get"), PidProbeReply)
        if r.state != "running":
            break
    else:
        request(session, keys.PID_PROBE, PidProbeRequest(action="stop"), PidProbeReply)
        raise CliError(f"{kind} probe on {axis} did not end in time")
    if r.state != "done":
        raise CliError(f"{kind} probe on {axis} {r.state}: {r.reason}")
    return {"state": r.state, "reason": r.reason, "setpoint": r.setpoint, "bias": r.bias,
            "trace": list(zip(r.t_s, r.measured, r.effort, strict=True))}


# --- analysis and output ---------------------------------------------------------------------

def report(args: argparse.Namespace, results: dict[str, dict[str, Any]]) -> int:
    from autochair.tune.core import (
        fit_step,
        relay_result,
        simc,
        snippet,
        tyreus_luyben,
        ziegler_nichols,
    )

    rules = {"simc": "SIMC", "zn": "ZN", "tl": "TL"}
    chosen, models, out = {}, {}, {}
    for axis, res in results.items():
        for name in ("step", "relay"):
            if res[name]["state"] != "done":
                raise CliError(f"{name} probe on {axis}: {res[name]['state']} "
                               f"({res[name]['reason']})")
        rr = relay_result([tuple(s) for s in res["relay"]["trace"]], args.relay)
        model = fit_step([tuple(s) for s in res["step"]["trace"]], res["step"]["bias"])
        gains = {g.rule: g for g in (ziegler_nichols(rr.ku, rr.tu_s),
                                     tyreus_luyben(rr.ku, rr.tu_s), simc(model))}
        chosen[axis], models[axis] = gains[rules[args.rule]], model
        mku, mtu = model.ultimate()
        print(f"{axis}: relay d {args.relay:g} ε {res['hysteresis']:.3f}: Ku {rr.ku:.3f} "
              f"(first harmonic {rr.ku_h1:.3f}), "
              f"Tu {rr.tu_s:.3f} s (a {rr.amplitude:.3f}, {rr.cycles} periods, spread "
              f"{rr.period_spread:.1%}); SOPDT K {model.gain:.3f}, u_db {model.dead_band:.3f}, "
              f"τ1 {model.tau1_s:.3f} s, τ2 {model.tau2_s:.3f} s, θ {model.delay_s:.3f} s "
              f"(its Ku {mku:.3f}, Tu {mtu:.3f} s)")
        for g in gains.values():
            print(f"  {g.rule:4s} Kp {g.kp:.3f}  Ki {g.ki:.3f}/s  Kd {g.kd:.3f} s")
        out[axis] = {"ku": rr.ku, "ku_first_harmonic": rr.ku_h1, "tu_s": rr.tu_s,
                     "model": model.__dict__,
                     "gains": {k: g.as_tuple() for k, g in gains.items()},
                     "step_before_after": before_after(axis, model, gains[rules[args.rule]])}
    text = snippet(chosen, models)
    Path(args.out).write_text(text)
    Path(args.json).write_text(json.dumps(out, indent=1) + "\n")
    print(text + f"(written to {args.out}; results in {args.json}: autochair report --tune "
          f"{args.json})")
    return 0


def before_after(axis: str, model: Any, gains: Any) -> dict[str, Any]:
    """0.5 step of the simulated chair with the thesis's PID and with the new gains and model
    (on a real chair: restart the PID with the snippet and record a `drive` step)."""
    from autochair.pid.core import PidConfig, VelocityPidCore
    from autochair.tune.lockstep import core_for, step_response, summary

    new = core_for(axis, gains.as_tuple(), model, PidConfig().prefilter_s)
    out = {}
    for name, core in (("before", VelocityPidCore(require_estop=False)), ("after", new)):
        m = step_response(core, axis)
        out[name] = {**summary(m), "t": m.t[::4], "y": m.y[::4]}
    return out
