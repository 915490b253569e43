"""JSON Schemas from the msgspec types and the msgpack ⇄ JSON transcoding the logger records.

Foxglove plays JSON with a JSON Schema, not msgpack, so every payload is recorded as JSON.

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

import math
from typing import Any

import msgspec

_NON_FINITE = {math.inf: "Infinity", -math.inf: "-Infinity"}
_JSON = msgspec.json.Encoder()
_MSGPACK = msgspec.msgpack.Encoder()


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
