"""Maps as files in the ROS map_server format: NAME.pgm (8-bit P5 image, top row = largest y)
and NAME.yaml (image, resolution, origin, negate, occupied_thresh, free_thresh, mode), so maps
interchange with ROS tools (map_server, nav2, map_saver_cli). Pure file I/O, no Zenoh.

Written in "trinary" mode like map_saver: occupied 0 (black), free 254 (white), unknown 205.
Read in any mode with map_server's rule: p = (255 - pixel) / 255 (or pixel / 255 if negate);
occupied if p > occupied_thresh, free if p < free_thresh, else unknown.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from autochair.files import write_atomic

BoolGrid = npt.NDArray[np.bool_]
NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


class MapFileError(ValueError):
    pass


@dataclass(frozen=True)
class MapFile:
    """A map: grids are (H, W), row 0 at origin_y (the occupancy grids' convention)."""

    occupied: BoolGrid
    free: BoolGrid
    resolution_m: float
    origin_x_m: float  # map position of cell (0, 0)'s corner; the grid's axes are the map's
    origin_y_m: float


def map_path(directory: str | Path, name: str) -> Path:
    """NAME.yaml in `directory`; MapFileError for a name that could escape it."""
    if not NAME_RE.match(name) or name.endswith((".yaml", ".pgm")):
        raise MapFileError(f"map name {name!r}: letters, digits, _ . - (no extension)")
    return Path(directory) / f"{name}.yaml"


def save_map(m: MapFile, yaml_path: str | Path) -> Path:
    yaml_path = Path(yaml_path)
    pgm = yaml_path.with_suffix(".pgm")
    pix = np.full(m.occupied.shape, 205, dtype=np.uint8)
    pix[m.free] = 254
    pix[m.occupied] = 0
    h, w = m.occupied.shape
    # Each file whole or not at all (saving over a map in use must not leave a torn one);
    # the image first, so a YAML never names a half-written image.
    write_atomic(pgm, f"P5\n# autochair map\n{w} {h}\n255\n".encode() + pix[::-1].tobytes())
    write_atomic(yaml_path, (
        f"image: {pgm.name}\nmode: trinary\nresolution: {m.resolution_m:.6f}\n"
        f"origin: [{m.origin_x_m:.6f}, {m.origin_y_m:.6f}, 0.000000]\n"
        "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n").encode())  # as map_saver
    return yaml_path


def _yaml(text: str, where: str) -> dict[str, str]:
    """The flat `key: value` subset map_server YAML uses (no PyYAML needed)."""
    out: dict[str, str] = {}
    for n, raw in enumerate(text.splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        key, sep, value = line.partition(":")
        if not sep:
            raise MapFileError(f"{where}:{n}: want 'key: value', got {raw.strip()!r}")
        out[key.strip()] = value.strip().strip("'\"")
    return out


def _pgm(data: bytes, where: str) -> npt.NDArray[np.uint8]:
    tokens: list[bytes] = []
    pos = 0
    while len(tokens) < 4:
        m = re.compile(rb"\s*(#[^\n]*\n\s*)*(\S+)").match(data, pos)
        if m is None:
            raise MapFileError(f"{where}: truncated PGM header")
        tokens.append(m.group(2))
        pos = m.end()
    if tokens[0] != b"P5":
        raise MapFileError(f"{where}: not a binary PGM (P5), got {tokens[0]!r}")
    w, h, maxval = (int(t) for t in tokens[1:])
    if maxval > 255:
        raise MapFileError(f"{where}: 16-bit PGM not supported")
    body = data[pos + 1:pos + 1 + w * h]
    if len(body) != w * h:
        raise MapFileError(f"{where}: {len(body)} pixel bytes, want {w}×{h}")
    return np.frombuffer(body, np.uint8).reshape(h, w)


def load_map(yaml_path: str | Path) -> MapFile:
    yaml_path = Path(yaml_path)
    try:
        meta = _yaml(yaml_path.read_text(), str(yaml_path))
        image = Path(meta["image"])
        pix = _pgm((yaml_path.parent / image).read_bytes(), str(image))
        res = float(meta["resolution"])
        origin = [float(v) for v in meta["origin"].strip("[]").split(",")]
        occ_t, free_t = float(meta["occupied_thresh"]), float(meta["free_thresh"])
        negate = int(meta.get("negate", "0"))
    except KeyError as e:
        raise MapFileError(f"{yaml_path}: missing {e.args[0]}") from None
    except OSError as e:
        raise MapFileError(f"cannot read map {e.filename}: {e.strerror}") from None
    except ValueError as e:
        raise MapFileError(f"{yaml_path}: {e}") from None
    if len(origin) != 3 or not res > 0 or not all(math.isfinite(v) for v in origin):
        raise MapFileError(f"{yaml_path}: bad origin or resolution")
    # Localization, navigation and the keep-out zones all take the grid's axes as the map's
    # (Nav2's map_server ignores the yaw too): a rotated map would be used unrotated by some
    # and rotated by others, so it is refused rather than half-honoured.
    if origin[2] != 0.0:
        raise MapFileError(f"{yaml_path}: origin yaw {origin[2]:g} rad: rotated maps are not "
                           "supported (the map frame is the grid's axes; set it to 0)")
    p = (pix if negate else 255 - pix.astype(np.int32)) / 255.0
    p = p[::-1]
    return MapFile(np.ascontiguousarray(p > occ_t), np.ascontiguousarray(p < free_t), res,
                   origin[0], origin[1])
