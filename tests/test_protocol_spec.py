"""docs/arduino-protocol.md cannot drift from the code: its hex examples must equal encode()."""

from __future__ import annotations

import re
from pathlib import Path

from autochair.protocol import arduino as proto

SPEC = Path(__file__).resolve().parent.parent / "docs" / "arduino-protocol.md"
BLOCK = re.compile(r"^```hex (\w+) ([^\n]*)\n(.*?)\n```", re.M | re.S)


def examples() -> list[tuple[str, dict[str, int], bytes]]:
    out = []
    for kind, fields, hexdump in BLOCK.findall(SPEC.read_text()):
        values = {k: int(v, 0) for k, v in (f.split("=") for f in fields.split())}
        out.append((kind, values, bytes.fromhex(hexdump)))
    return out


def test_spec_has_both_examples() -> None:
    assert sorted(k for k, _, _ in examples()) == ["command", "telemetry"]


def test_spec_examples_equal_encode_and_decode() -> None:
    for kind, values, wire in examples():
        frame: proto.Frame = (proto.Telemetry(**values) if kind == "telemetry"
                              else proto.Command(**values))
        assert proto.encode(frame) == wire, kind
        assert proto.FrameDecoder().feed(wire) == [frame]


def test_spec_bodies_and_crcs() -> None:
    """The spec's body and CRC lines match the decoded wire bytes too."""
    text = SPEC.read_text()
    bodies = re.findall(r"Body `([0-9a-f ]+)`, CRC 0x([0-9A-F]{4}) \(sent `([0-9a-f ]+)`\)", text)
    assert len(bodies) == 2
    for body_hex, crc_hex, sent in bodies:
        body = bytes.fromhex(body_hex)
        assert proto.crc16(body) == int(crc_hex, 16)
        assert bytes.fromhex(sent) == int(crc_hex, 16).to_bytes(2, "little")
    assert proto.crc16(b"123456789") == 0x29B1 and "0x29B1" in text
