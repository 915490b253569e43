"""Replay plan (pure): recorded JSON back to the msgpack bytes services consume, with the time
offset at which to publish each, scaled by the replay rate. Derived foxglove.* channels are
not Zenoh keys and are skipped."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import NamedTuple

from autochair_msgs import keys

from .reader import Msg
from .schema import Codec


class Item(NamedTuple):
    offset_s: float  # when to publish, from the start of the replay
    key: str
    payload: bytes  # msgpack, as the original publisher sent it


def plan(messages: Iterable[Msg], rate: float, skipped: dict[str, int] | None = None
         ) -> Iterator[Item]:
    """Messages in log-time order → publish schedule. Unknown topics are counted in
    `skipped` (topic → count)."""
    if rate <= 0:
        raise ValueError("rate must be > 0")
    codecs: dict[str, Codec | None] = {}
    t0: int | None = None
    for m in messages:
        if m.derived:
            continue
        if m.topic not in codecs:
            try:
                row = keys.by_key(m.topic)
                codecs[m.topic] = Codec(row.type) if row.kind == "pub" else None
            except KeyError:
                codecs[m.topic] = None
        codec = codecs[m.topic]
        if codec is None:
            if skipped is not None:
                skipped[m.topic] = skipped.get(m.topic, 0) + 1
            continue
        if t0 is None:
            t0 = m.log_ns
        yield Item((m.log_ns - t0) / 1e9 / rate, m.topic, codec.json_to_wire(m.data))
