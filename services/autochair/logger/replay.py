"""Replay plan (pure): recorded JSON back to the msgpack bytes services consume, with the time
offset at which to publish each, scaled by the replay rate. Derived foxglove.* channels are
not Zenoh keys and are skipped.

A replay must never move a chair: where a drive-chain service is alive it is refused
(`refusal`); `autochair replay` publishes into a namespace of its own by default.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import NamedTuple

from autochair_msgs import keys

from .reader import Msg
from .schema import Codec, codec_for


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
                codecs[m.topic] = codec_for(row.type) if row.kind == "pub" else None
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


# Services whose liveliness token means a chair can move: the gateway drives the joystick
# output; the PID turns velocity commands into joystick commands.
DRIVE_CHAIN = ("gateway", "pid")


def drive_chain_alive(alive: Iterable[str]) -> list[str]:
    """The drive-chain services among the names of `autochair/alive/<name>` tokens."""
    return sorted(set(alive) & set(DRIVE_CHAIN))


def refusal(alive: Iterable[str]) -> str:
    """One line: who is alive, why a replay there is refused, and the way out."""
    names = drive_chain_alive(alive)
    return (f"drive-chain service{'s' if len(names) > 1 else ''} alive on this bus "
            f"({', '.join(f'autochair/alive/{n}' for n in names)}): a recording's drive "
            "commands, e-stop \"released\" states, limits, odometry or scans would act on the "
            "live chair; replay under a namespace instead (--namespace NAME publishes "
            "NAME/autochair/...), or on a bus without the drive chain")
