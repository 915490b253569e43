"""JSON Schemas from the msgspec types and the msgpack ⇄ JSON transcoding the logger records.

Foxglove plays JSON with a JSON Schema, not msgpack, so every payload is recorded as JSON:
the Struct's own fields, except where Foxglove has a well-known type for the message
(`codec_for`): the laser scan is recorded as a foxglove.LaserScan carrying every raw field too
(`ScanCodec`), transforms as foxglove.FrameTransform (`TransformCodec`: the fields are the
same plus a {sec, nsec} timestamp). Foxglove's 3D panel then draws the full-rate channels
themselves, and no derived copies of them are recorded.

Lossless by construction:
- floats: msgspec writes the shortest repr that parses back to the same float64; JSON has no
  NaN/±inf (msgspec would write `null`, which is lossy: NaN vs inf vs a None), so non-finite
  floats are written as the strings "NaN", "Infinity", "-Infinity" (what JavaScript's
  `Number("NaN")` etc. parse) and read back in msgspec's lax mode, which turns those strings
  into floats. This holds for every float anywhere, e.g. invalid LaserScan beams. The schemas
  keep `"type": "number"` for float fields (Foxglove uses schemas for field types; a union
  confuses plotting), so a value that is non-finite shows as a string and is not plotted.
- bytes: base64 strings (`contentEncoding: base64`), what Foxglove expects.
- ints: exact in the file; note JavaScript (Foxglove) reads integers above 2^53 (e.g.
  `stamp_ns`) rounded to ~256 ns, so the derived foxglove.* channels use {sec, nsec}.
Re-encoding the decoded Struct with msgspec.msgpack gives back the exact bytes the publisher
sent (services use the same encoder), which is what `autochair replay` relies on.
"""

from __future__ import annotations

import copy
import json
import math
from importlib import resources
from typing import Any

import msgspec

from autochair import geometry
from autochair_msgs import FrameTransform, LaserScan, People

_NON_FINITE = {math.inf: "Infinity", -math.inf: "-Infinity"}
_JSON = msgspec.json.Encoder()
_MSGPACK = msgspec.msgpack.Encoder()
# Foxglove's own schemas (copied from npm `@foxglove/schemas`), by name.
FOXGLOVE_SCHEMAS: dict[str, dict[str, Any]] = json.loads(
    resources.files(__package__).joinpath("foxglove_schemas.json").read_text())


def schema_name(type_: type[msgspec.Struct]) -> str:
    return f"autochair_msgs.{type_.__name__}"


def _inline(node: Any, defs: dict[str, Any]) -> Any:
    if isinstance(node, dict):
        ref = node.get("$ref")
        if isinstance(ref, str) and ref.startswith("#/$defs/"):
            merged = dict(defs[ref.removeprefix("#/$defs/")])
            merged.update({k: v for k, v in node.items() if k != "$ref"})
            return _inline(merged, defs)
        return {k: _inline(v, defs) for k, v in node.items()}
    if isinstance(node, list):
        return [_inline(v, defs) for v in node]
    return node


def json_schema(type_: type[msgspec.Struct]) -> dict[str, Any]:
    """A self-contained JSON Schema of `type_`: msgspec's schema with every `$ref` inlined
    (our types are not recursive), titled with the schema name."""
    raw = msgspec.json.schema(type_)
    out: dict[str, Any] = _inline(raw, raw.get("$defs", {}))
    out.pop("$defs", None)
    out["title"] = schema_name(type_)
    out["$comment"] = ('Non-finite floats are the strings "NaN", "Infinity", "-Infinity"; '
                       "generated from the msgspec type by autochair.logger.schema")
    return out


def _finite_only(obj: Any) -> Any:
    """Builtins with non-finite floats replaced by their JSON-safe strings."""
    if isinstance(obj, float):
        if math.isfinite(obj):
            return obj
        return "NaN" if math.isnan(obj) else _NON_FINITE[obj]
    if isinstance(obj, dict):
        return {k: _finite_only(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_finite_only(v) for v in obj]
    return obj


def to_json(msg: msgspec.Struct) -> bytes:
    """Encode for the recording (lossless, see the module doc)."""
    data = _JSON.encode(msg)
    # Fast path: msgspec writes a non-finite float as null; no null, nothing to fix. A null may
    # also be a real None (Optional field); the slow path keeps those as null.
    if b"null" not in data:
        return data
    return _JSON.encode(_finite_only(msgspec.to_builtins(msg)))


class Codec:
    """msgpack (wire) ⇄ Struct ⇄ JSON (recording) for one message type."""

    def __init__(self, type_: type[msgspec.Struct]) -> None:
        self.type = type_
        self.name = schema_name(type_)
        self.schema = _JSON.encode(json_schema(type_))
        self._from_msgpack = msgspec.msgpack.Decoder(type_)
        # Lax mode turns "NaN"/"Infinity" strings back into floats (and only where the type
        # says float, so a str field holding "NaN" stays a str).
        self._from_json = msgspec.json.Decoder(type_, strict=False)

    def decode_wire(self, payload: bytes) -> msgspec.Struct:
        msg: msgspec.Struct = self._from_msgpack.decode(payload)
        return msg

    def decode_json(self, data: bytes) -> msgspec.Struct:
        msg: msgspec.Struct = self._from_json.decode(data)
        return msg

    def json_to_wire(self, data: bytes) -> bytes:
        """What replay publishes: the bytes a service would have sent."""
        return _MSGPACK.encode(self.decode_json(data))

    def encode_json(self, msg: msgspec.Struct) -> bytes:
        """The recorded form (lossless, see the module doc)."""
        return to_json(msg)


class _Time(msgspec.Struct):
    sec: int
    nsec: int


ORIGIN = {"position": {"x": 0.0, "y": 0.0, "z": 0.0},
           "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}


def _with_schema(name: str, extra: type[msgspec.Struct], note: str) -> bytes:
    """Foxglove's schema `name` with the properties of `extra` it lacks (our raw fields)."""
    schema = copy.deepcopy(FOXGLOVE_SCHEMAS[name])
    raw = json_schema(extra)["properties"]
    schema["properties"].update({k: v for k, v in raw.items() if k not in schema["properties"]})
    schema["description"] += f"; autochair: {note}"
    return _JSON.encode(schema)


class TransformCodec(Codec):
    """keys.TF and keys.TF_STATIC recorded (and bridged) as foxglove.FrameTransform: our JSON
    with a {sec, nsec} timestamp added; read back by the plain decoder, which ignores it.
    A non-finite value stays a string (lossless; Foxglove then rejects that one transform)."""

    def __init__(self) -> None:
        super().__init__(FrameTransform)
        self.name = "foxglove.FrameTransform"
        self.schema = _with_schema(self.name, FrameTransform, "with stamp_ns (Unix ns)")

    def encode_json(self, msg: msgspec.Struct) -> bytes:
        assert isinstance(msg, FrameTransform)
        sec, nsec = divmod(max(msg.stamp_ns, 0), 1_000_000_000)
        return b'{"timestamp":{"sec":%d,"nsec":%d},' % (sec, nsec) + to_json(msg)[1:]


class ScanRecord(msgspec.Struct, kw_only=True):
    """A LaserScan as recorded: a valid foxglove.LaserScan (first seven fields) plus the raw
    fields. foxglove.LaserScan has no NaN and no range limits: a non-finite beam is 0 m in
    `ranges` (drawn at the sensor) and its value is kept in `nonfinite`."""

    timestamp: _Time
    frame_id: str
    pose: dict[str, Any]
    start_angle: float
    end_angle: float
    ranges: list[float]
    intensities: list[float]
    stamp_ns: int
    angle_min_rad: float
    angle_increment_rad: float
    range_min_m: float
    range_max_m: float
    scan_seq: int
    device_time_ms: int
    nonfinite: dict[int, float]  # beam index → its NaN / ±inf
    time_increment_s: float = 0.0  # (absent in recordings made before it existed)


def _finite(v: float) -> float:
    return v if math.isfinite(v) else 0.0


class ScanCodec(Codec):
    """keys.SCAN recorded (and bridged live) as foxglove.LaserScan, losslessly (`ScanRecord`)."""

    def __init__(self) -> None:
        super().__init__(LaserScan)
        self.name = "foxglove.LaserScan"
        self.schema = _with_schema(self.name, ScanRecord,
                                   "every raw LaserScan field too (lossless)")
        self._record = msgspec.json.Decoder(ScanRecord, strict=False)

    def encode_json(self, msg: msgspec.Struct) -> bytes:
        assert isinstance(msg, LaserScan)
        ranges, bad = msg.ranges_m, {}
        if not all(math.isfinite(r) for r in ranges):
            bad = {i: r for i, r in enumerate(ranges) if not math.isfinite(r)}
            ranges = [0.0 if i in bad else r for i, r in enumerate(ranges)]
        sec, nsec = divmod(max(msg.stamp_ns, 0), 1_000_000_000)
        last = max(len(ranges) - 1, 0)
        return to_json(ScanRecord(
            timestamp=_Time(sec, nsec), frame_id=msg.frame_id, pose=ORIGIN,
            start_angle=_finite(msg.angle_min_rad),
            end_angle=_finite(msg.angle_min_rad + last * msg.angle_increment_rad),
            ranges=ranges, intensities=[], stamp_ns=msg.stamp_ns,
            angle_min_rad=msg.angle_min_rad, angle_increment_rad=msg.angle_increment_rad,
            range_min_m=msg.range_min_m, range_max_m=msg.range_max_m, scan_seq=msg.scan_seq,
            device_time_ms=msg.device_time_ms, nonfinite=bad,
            time_increment_s=msg.time_increment_s))

    def decode_json(self, data: bytes) -> msgspec.Struct:
        try:
            r = self._record.decode(data)
        except msgspec.ValidationError:
            return super().decode_json(data)  # recorded before the scan was a ScanRecord
        ranges = r.ranges
        for i, v in r.nonfinite.items():
            if not 0 <= i < len(ranges):
                raise msgspec.ValidationError(f"nonfinite beam {i} outside the scan")
            ranges[i] = v
        return LaserScan(stamp_ns=r.stamp_ns, frame_id=r.frame_id,
                         angle_min_rad=r.angle_min_rad,
                         angle_increment_rad=r.angle_increment_rad,
                         range_min_m=r.range_min_m, range_max_m=r.range_max_m, ranges_m=ranges,
                         scan_seq=r.scan_seq, device_time_ms=r.device_time_ms,
                         time_increment_s=r.time_increment_s)


class PeopleCodec(Codec):
    """keys.PEOPLE recorded (and bridged) as foxglove.SceneUpdate: each person a 1.7 m
    cylinder and an arrow 1 s of their motion long, in one entity replaced by the next
    message (so people who have gone vanish); our fields added, read back by the plain
    decoder, which ignores the scene."""

    def __init__(self) -> None:
        super().__init__(People)
        self.name = "foxglove.SceneUpdate"
        self.schema = _with_schema(self.name, People, "the tracked people's fields too")

    def encode_json(self, msg: msgspec.Struct) -> bytes:
        assert isinstance(msg, People)
        sec, nsec = divmod(max(msg.stamp_ns, 0), 1_000_000_000)

        def pose(x: float, y: float, yaw: float, z: float) -> dict[str, Any]:
            q = dict(zip("xyzw", geometry.yaw_quaternion(_finite(yaw)), strict=True))
            return {"position": {"x": _finite(x), "y": _finite(y), "z": z}, "orientation": q}

        red = {"r": 1.0, "g": 0.2, "b": 0.2, "a": 0.6}
        cylinders = [{"pose": pose(p.x_m, p.y_m, 0.0, 0.85),
                      "size": {"x": _finite(2 * p.radius_m), "y": _finite(2 * p.radius_m),
                               "z": 1.7}, "bottom_scale": 1.0, "top_scale": 1.0, "color": red}
                     for p in msg.people]
        arrows = [{"pose": pose(p.x_m, p.y_m, math.atan2(p.vy_mps, p.vx_mps), 1.0),
                   "shaft_length": _finite(math.hypot(p.vx_mps, p.vy_mps)),
                   "shaft_diameter": 0.04, "head_length": 0.12, "head_diameter": 0.1,
                   "color": red} for p in msg.people]
        entity = {"timestamp": {"sec": sec, "nsec": nsec}, "frame_id": msg.frame_id,
                  "id": "people", "lifetime": {"sec": 0, "nsec": 0}, "frame_locked": False,
                  "metadata": [], "arrows": arrows, "cubes": [], "spheres": [],
                  "cylinders": cylinders, "lines": [], "triangles": [], "texts": [],
                  "models": []}
        return _JSON.encode({"deletions": [], "entities": [entity]})[:-1] + b"," + \
            to_json(msg)[1:]


def codec_for(type_: type[msgspec.Struct]) -> Codec:
    """How messages of `type_` are recorded and bridged to Foxglove."""
    if type_ is LaserScan:
        return ScanCodec()
    if type_ is FrameTransform:
        return TransformCodec()
    if type_ is People:
        return PeopleCodec()
    return Codec(type_)
