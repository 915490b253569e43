"""`autochair report FILE [--out DIR]`: PNG figures of a recorded run — velocity step
responses desired vs measured with rise time and overshoot (thesis Fig. 8.1), the trajectory
over the map (Fig. 8.2), and time series of acceleration, jerk and turn rate.

`autochair report --tune tune.json`: the 0.5 step responses before (the thesis's ZN PID) and
after (the gains and feed-forward model `autochair tune` found), per axis."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from autochair.cli import CliError


def register(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "report", help="PNG figures of a recorded run (step responses, trajectory, a/jerk/ω)",
        description=__doc__)
    p.add_argument("file", help="an .mcap recording, or with --tune the tune result (.json)")
    p.add_argument("--tune", action="store_true",
                   help="FILE is `autochair tune`'s JSON: plot its step responses")
    p.add_argument("--out", help="output directory (default: FILE without .mcap + _report)")
    p.set_defaults(func=run)


def load(path: str) -> dict[str, list[Any]]:
    """Decoded messages of the keys the report uses, by key, in log-time order."""
    from autochair.logger.reader import Recording
    from autochair.logger.schema import codec_for
    from autochair_msgs import keys

    wanted: list[keys.Topic[Any]] = [keys.PID_STATUS, keys.ODOM, keys.MAP_GRID, keys.SCAN,
                                     keys.TF_STATIC, keys.SIM_TRUTH]
    codecs = {t.key: codec_for(t.type) for t in wanted}
    out: dict[str, list[Any]] = {t.key: [] for t in wanted}
    for m in Recording(path).messages():
        codec = codecs.get(m.topic)
        if codec is not None:
            out[m.topic].append(codec.decode_json(m.data))
    return out


def run(args: argparse.Namespace) -> int:
    try:
        import matplotlib
    except ImportError:
        raise CliError("matplotlib is needed: pip install 'autochair[report]'") from None
    matplotlib.use("Agg")
    from autochair_msgs import keys

    src = Path(args.file)
    if not src.is_file():
        raise CliError(f"no such recording: {src}")
    out = Path(args.out) if args.out else src.with_name(src.stem + "_report")
    out.mkdir(parents=True, exist_ok=True)
    if args.tune:
        print(tune_figure(src, out / "tune_steps.png"))
        return 0
    data = load(str(src))
    written = []
    if data[keys.PID_STATUS.key]:
        written.append(step_figure(data[keys.PID_STATUS.key], out / "step_response.png"))
    if data[keys.ODOM.key]:
        written.append(trajectory_figure(data, out / "trajectory.png"))
        written.append(motion_figure(data[keys.ODOM.key], out / "motion.png"))
    if not written:
        raise CliError(f"{src}: no {keys.PID_STATUS.key} or {keys.ODOM.key} messages to plot")
    for p in written:
        print(p)
    return 0


def step_figure(status: list[Any], path: Path) -> Path:
    import matplotlib.pyplot as plt
    import numpy as np

    from autochair.logger.analysis import steps

    t0 = status[0].stamp_ns
    t = np.array([(s.stamp_ns - t0) / 1e9 for s in status])
    fig, axes = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    for ax, name, unit, d_attr, m_attr in (
            (axes[0], "v", "m/s", "v_desired_mps", "v_measured_mps"),
            (axes[1], "ω", "rad/s", "omega_desired_radps", "omega_measured_radps")):
        d = np.array([getattr(s, d_attr) for s in status])
        m = np.array([getattr(s, m_attr) for s in status])
        ax.plot(t, d, "k--", label=f"desired {name}")
        ax.plot(t, m, "C0", label=f"measured {name}")
        for st in steps(t, d, m):
            rise = f"{st.rise_s:.2f} s" if st.rise_s is not None else "—"
            ax.annotate(f"rise {rise}\novershoot {st.overshoot_pct:.0f} %",
                        (st.t_s, st.after), fontsize=8, xytext=(5, 5),
                        textcoords="offset points")
        ax.set_ylabel(f"{name} ({unit})")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right")
    axes[1].set_xlabel("time (s)")
    fig.suptitle("Velocity step responses (desired vs measured; 10–90 % rise time)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def tune_figure(src: Path, path: Path) -> Path:
    """Before/after 0.5 steps from `autochair tune`'s result, one panel per axis."""
    import json

    import matplotlib.pyplot as plt

    try:
        result = json.loads(src.read_text())
        axes_data = {a: result[a]["step_before_after"] for a in result}
    except (ValueError, KeyError, TypeError) as e:
        raise CliError(f"{src}: not an `autochair tune` result ({e})") from None
    fig, axes = plt.subplots(len(axes_data), 1, figsize=(10, 3.5 * len(axes_data)),
                             squeeze=False)
    for ax, (axis, runs) in zip(axes[:, 0], axes_data.items(), strict=True):
        for name, style in (("before", "C3"), ("after", "C0")):
            r = runs[name]
            settle = r["settle_5pct_s"]
            ax.plot(r["t"], r["y"], style, label=f"{name}: overshoot {r['overshoot_pct']:.0f} %,"
                    f" ±5 % in {'—' if settle is None else f'{settle:.2f} s'}")
        ax.axhline(0.5, color="k", ls="--", lw=1)
        for band in (0.475, 0.525):
            ax.axhline(band, color="0.6", ls=":", lw=1)
        ax.set_ylabel(f"{axis} ({'m/s' if axis == 'longitudinal' else 'rad/s'})")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="lower right")
    axes[-1, 0].set_xlabel("time after the step (s)")
    fig.suptitle("0.5 step, simulated chair: thesis ZN PID (before) vs tuned + feed-forward")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def trajectory_figure(data: dict[str, list[Any]], path: Path) -> Path:
    import matplotlib.pyplot as plt
    import numpy as np

    from autochair_msgs import keys

    odom = data[keys.ODOM.key]
    fig, ax = plt.subplots(figsize=(8, 8))
    grids = data[keys.MAP_GRID.key]
    if grids:
        g = grids[-1]
        cells = np.frombuffer(g.data, dtype=np.uint8).reshape(g.height, g.width).astype(float)
        cells[cells == 255] = np.nan  # unknown
        ax.imshow(cells, origin="lower", cmap="Greys", vmin=0, vmax=100, extent=(
            g.origin_x_m, g.origin_x_m + g.width * g.resolution_m,
            g.origin_y_m, g.origin_y_m + g.height * g.resolution_m))
    elif data[keys.SCAN.key]:
        xs, ys = scan_points(odom, data[keys.SCAN.key], data[keys.TF_STATIC.key])
        ax.scatter(xs, ys, s=0.5, c="0.4", label="laser hits")
    ax.plot([o.x_m for o in odom], [o.y_m for o in odom], "C0", label="odometry")
    truth = data[keys.SIM_TRUTH.key]
    if truth:
        ax.plot([g.x_m for g in truth], [g.y_m for g in truth], "C2--", label="ground truth")
    ax.plot(odom[0].x_m, odom[0].y_m, "go", label="start")
    ax.plot(odom[-1].x_m, odom[-1].y_m, "rs", label="end")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(True, alpha=0.3)
    ax.legend()
    ax.set_title("Trajectory over the map (odom frame)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def scan_points(odom: list[Any], scans: list[Any], statics: list[Any]
                ) -> tuple[list[float], list[float]]:
    """World-frame laser hits: each scan placed at the odometry pose nearest in time."""
    import bisect

    from autochair.geometry import quaternion_yaw

    lx = ly = lyaw = 0.0
    for tf in statics:
        if tf.child_frame_id == "laser":
            lx, ly = tf.translation.x, tf.translation.y
            q = tf.rotation
            lyaw = quaternion_yaw(q.x, q.y, q.z, q.w)
    stamps = [o.stamp_ns for o in odom]
    xs: list[float] = []
    ys: list[float] = []
    for s in scans[::max(1, len(scans) // 200)]:
        o = odom[min(bisect.bisect_left(stamps, s.stamp_ns), len(odom) - 1)]
        c, sn = math.cos(o.yaw_rad), math.sin(o.yaw_rad)
        for k, r in enumerate(s.ranges_m):
            if not s.range_min_m <= r <= s.range_max_m:
                continue
            a = s.angle_min_rad + k * s.angle_increment_rad + lyaw
            px, py = lx + r * math.cos(a), ly + r * math.sin(a)
            xs.append(o.x_m + c * px - sn * py)
            ys.append(o.y_m + sn * px + c * py)
    return xs, ys


def motion_figure(odom: list[Any], path: Path) -> Path:
    import matplotlib.pyplot as plt
    import numpy as np

    from autochair.logger.analysis import motion, resample

    t0 = odom[0].stamp_ns
    t = np.array([(o.stamp_ns - t0) / 1e9 for o in odom])
    tr, v, a, jerk = motion(t, np.array([o.v_mps for o in odom]))
    tw, w = resample(t, np.array([o.omega_radps for o in odom]), 0.05)
    fig, axes = plt.subplots(4, 1, figsize=(10, 9), sharex=True)
    for ax, x, y, label, limit in ((axes[0], tr, v, "v (m/s)", None),
                                   (axes[1], tr, a, "a (m/s²)", 1.0),
                                   (axes[2], tr, jerk, "jerk (m/s³)", 2.0),
                                   (axes[3], tw, w, "ω (rad/s)", None)):
        ax.plot(x, y)
        if limit is not None:  # comfort bounds from the literature (see REFERENCE)
            for s in (-limit, limit):
                ax.axhline(s, color="r", ls=":", lw=1)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("Motion from odometry (50 ms bins): speed, acceleration, jerk, turn rate")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
