"""2D worlds for the simulated lidar: a small text format and a vectorised ray caster.

Format (docs/world-format.md): one shape per line, metres, `#` starts a comment::

    wall x1 y1 x2 y2      # a line segment
    box cx cy w h         # a solid axis-aligned rectangle (4 segments)
    circle cx cy r        # a solid disc (pillar, bin)
    person x1 y1 x2 y2 speed [radius]   # walks the segment back and forth (0.25 m disc)

`World.at(t)` is the world at time t (s) with each person as a disc where they are then.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

F64 = npt.NDArray[np.float64]

DEFAULT_WORLD = Path(__file__).with_name("worlds") / "hallway.world"


class WorldError(ValueError):
    """A world file that does not parse; the message names the line."""


PERSON_RADIUS_M = 0.25


@dataclass(frozen=True)
class World:
    segments: F64  # (S, 4): x1 y1 x2 y2
    circles: F64  # (C, 3): cx cy r
    people: F64 = field(default_factory=lambda: np.zeros((0, 6)))  # (K, 6): x1 y1 x2 y2 v r
    # The people's walks as at this time (s) when the world's clock reads 0 (a benchmark case
    # that meets them at another point of their walk)
    phase_s: float = 0.0

    def people_state(self, t: float) -> F64:
        """(K, 5): x, y, vx, vy, radius of each person at time t (ping-pong on the segment)."""
        out = np.zeros((len(self.people), 5))
        for i, (x1, y1, x2, y2, speed, radius) in enumerate(self.people):
            length = float(np.hypot(x2 - x1, y2 - y1))
            if length <= 0 or speed <= 0:
                out[i] = (x1, y1, 0.0, 0.0, radius)
                continue
            s = (speed * (t + self.phase_s)) % (2 * length)
            sign = 1.0 if s <= length else -1.0
            f = (s if s <= length else 2 * length - s) / length
            ux, uy = (x2 - x1) / length, (y2 - y1) / length
            out[i] = (x1 + f * (x2 - x1), y1 + f * (y2 - y1), sign * speed * ux,
                      sign * speed * uy, radius)
        return out

    def at(self, t: float) -> World:
        """The static world with every person as a disc where they are at time t."""
        if not len(self.people):
            return self
        p = self.people_state(t)
        return World(self.segments, np.concatenate([self.circles, p[:, [0, 1, 4]]]))

    def distance_to(self, pts: F64) -> F64:
        """Distance of each (N, 2) point to the nearest shape boundary."""
        p = np.asarray(pts, dtype=np.float64).reshape(-1, 1, 2)
        best = np.full(p.shape[0], np.inf)
        if len(self.segments):
            a, b = self.segments[None, :, :2], self.segments[None, :, 2:]
            ab = b - a
            t = np.clip(((p - a) * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12), 0, 1)
            d = np.linalg.norm(p - (a + t[..., None] * ab), axis=-1)
            best = np.minimum(best, d.min(axis=1))
        if len(self.circles):
            c, r = self.circles[None, :, :2], self.circles[None, :, 2]
            best = np.minimum(best, np.abs(np.linalg.norm(p - c, axis=-1) - r).min(axis=1))
        return best


def parse_world(text: str, name: str = "<world>") -> World:
    segs: list[list[float]] = []
    circles: list[list[float]] = []
    people: list[list[float]] = []
    arity = {"wall": 4, "box": 4, "circle": 3, "person": 5}
    for n, raw in enumerate(text.splitlines(), 1):
        words = raw.split("#", 1)[0].split()
        if not words:
            continue
        kind, args = words[0], words[1:]
        if kind not in arity:
            raise WorldError(f"{name}:{n}: unknown shape {kind!r} (wall, box, circle, person)")
        if kind == "person" and len(args) == 6:
            pass  # optional radius
        elif len(args) != arity[kind]:
            raise WorldError(f"{name}:{n}: {kind} wants {arity[kind]} numbers, got {len(args)}")
        try:
            v = [float(a) for a in args]
        except ValueError:
            raise WorldError(f"{name}:{n}: not a number in {raw.strip()!r}") from None
        if not all(np.isfinite(v)):
            raise WorldError(f"{name}:{n}: non-finite number")
        if kind == "person":
            if not (0.0 <= v[4] <= 3.0) or (len(v) == 6 and v[5] <= 0):
                raise WorldError(f"{name}:{n}: person speed must be in [0, 3] m/s and "
                                 "radius > 0")
            people.append(v if len(v) == 6 else [*v, PERSON_RADIUS_M])
        elif kind == "wall":
            segs.append(v)
        elif kind == "box":
            cx, cy, w, h = v
            if w <= 0 or h <= 0:
                raise WorldError(f"{name}:{n}: box size must be > 0")
            x0, x1, y0, y1 = cx - w / 2, cx + w / 2, cy - h / 2, cy + h / 2
            segs += [[x0, y0, x1, y0], [x1, y0, x1, y1], [x1, y1, x0, y1], [x0, y1, x0, y0]]
        else:
            if v[2] <= 0:
                raise WorldError(f"{name}:{n}: circle radius must be > 0")
            circles.append(v)
    return World(np.array(segs, dtype=np.float64).reshape(-1, 4),
                 np.array(circles, dtype=np.float64).reshape(-1, 3),
                 np.array(people, dtype=np.float64).reshape(-1, 6))


def load_world(path: str | Path = DEFAULT_WORLD) -> World:
    try:
        text = Path(path).read_text()
    except OSError as e:
        raise WorldError(f"cannot read world {path}: {e.strerror}") from None
    return parse_world(text, str(path))


def raycast(world: World, x: float | F64, y: float | F64, angles: F64, max_range: float) -> F64:
    """Distance along each ray from (x, y) at world-frame `angles` to the first hit (inf if none
    within `max_range`). `x`, `y`: one origin, or one per ray (a sweeping laser on a moving
    chair). Vectorised over rays × shapes."""
    dx, dy = np.cos(angles)[:, None], np.sin(angles)[:, None]
    x0 = np.broadcast_to(np.asarray(x, dtype=np.float64), angles.shape)[:, None]
    y0 = np.broadcast_to(np.asarray(y, dtype=np.float64), angles.shape)[:, None]
    best = np.full(angles.shape[0], np.inf)
    segments, circles = _within(world, x0, y0, max_range)
    if len(segments):
        s = segments
        ex, ey = (s[:, 2] - s[:, 0])[None, :], (s[:, 3] - s[:, 1])[None, :]
        qx, qy = s[None, :, 0] - x0, s[None, :, 1] - y0
        den = dx * ey - dy * ex
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (qx * ey - qy * ex) / den
            u = (qx * dy - qy * dx) / den
        ok = (np.abs(den) > 1e-12) & (t > 1e-9) & (u >= 0) & (u <= 1)
        best = np.minimum(best, np.where(ok, t, np.inf).min(axis=1))
    if len(circles):
        c = circles
        ox, oy = x0 - c[None, :, 0], y0 - c[None, :, 1]
        b = dx * ox + dy * oy
        disc = b * b - (ox * ox + oy * oy - (c[:, 2] ** 2)[None, :])
        root = np.sqrt(np.maximum(disc, 0))
        t1, t2 = -b - root, -b + root
        t = np.where(t1 > 1e-9, t1, t2)
        best = np.minimum(best, np.where((disc >= 0) & (t > 1e-9), t, np.inf).min(axis=1))
    return np.where(best <= max_range, best, np.inf)


def _within(world: World, x0: F64, y0: F64, max_range: float) -> tuple[F64, F64]:
    """The segments and circles that some ray from the origins `x0`, `y0` can hit within
    `max_range`: the others (farther than that from a disc holding every origin) are left
    out of `raycast`, whose result they cannot change (a hit beyond `max_range` is none)."""
    if not x0.size:
        return world.segments, world.circles
    cx, cy = float(x0.mean()), float(y0.mean())
    reach = max_range + float(np.hypot(x0 - cx, y0 - cy).max()) + 1e-6
    s = world.segments
    if len(s):
        ax, ay, ex, ey = s[:, 0] - cx, s[:, 1] - cy, s[:, 2] - s[:, 0], s[:, 3] - s[:, 1]
        t = np.clip(-(ax * ex + ay * ey) / np.maximum(ex * ex + ey * ey, 1e-300), 0.0, 1.0)
        s = s[np.hypot(ax + t * ex, ay + t * ey) <= reach]
    c = world.circles
    if len(c):
        c = c[np.hypot(c[:, 0] - cx, c[:, 1] - cy) - c[:, 2] <= reach]
    return s, c
