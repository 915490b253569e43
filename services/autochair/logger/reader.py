"""Reading recordings back: complete (indexed) files and files whose writer was killed.

A killed writer leaves no summary; the seeking reader then fails, so such files are read
front to back with the non-seeking reader, keeping every complete chunk and stopping at the
torn one.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO, NamedTuple

import numpy as np
import numpy.typing as npt
from mcap.reader import NonSeekingReader, SeekingReader
from mcap.records import ChunkIndex
from mcap.writer import Writer


class Msg(NamedTuple):
    topic: str
    schema: str  # schema name, e.g. autochair_msgs.Odometry or foxglove.LaserScan
    log_ns: int
    publish_ns: int
    data: bytes  # JSON
    derived: bool  # a foxglove.* channel made by the logger (not a Zenoh key)


@dataclass
class ChannelInfo:
    topic: str
    schema: str
    derived: bool
    count: int = 0
    first_ns: int = 0
    last_ns: int = 0

    @property
    def rate_hz(self) -> float:
        span = (self.last_ns - self.first_ns) / 1e9
        return (self.count - 1) / span if self.count > 1 and span > 0 else 0.0


@dataclass
class Summary:
    path: Path
    indexed: bool  # has a summary section (clean finish)
    channels: dict[str, ChannelInfo] = field(default_factory=dict)
    error: str = ""  # why reading stopped early (torn chunk of a killed writer)

    @property
    def count(self) -> int:
        return sum(c.count for c in self.channels.values())

    @property
    def start_ns(self) -> int:
        return min((c.first_ns for c in self.channels.values() if c.count), default=0)

    @property
    def end_ns(self) -> int:
        return max((c.last_ns for c in self.channels.values() if c.count), default=0)

    @property
    def duration_s(self) -> float:
        return (self.end_ns - self.start_ns) / 1e9


def is_indexed(path: Path) -> bool:
    with open(path, "rb") as f:
        try:
            summary = SeekingReader(f).get_summary()
        except Exception:  # torn or missing footer: mcap raises several error types
            return False
        return summary is not None and summary.statistics is not None


class Recording:
    """Iterate a recording's messages in log-time order; `error` tells why it ended early."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise FileNotFoundError(f"no such recording: {self.path}")
        self.indexed = is_indexed(self.path)
        self.error = ""

    def _raw(self) -> Iterator[Msg]:
        with open(self.path, "rb") as f:
            if self.indexed:
                it = SeekingReader(f).iter_messages(log_time_order=True)
            else:
                it = NonSeekingReader(f).iter_messages(log_time_order=False)
            try:
                for schema, channel, message in it:
                    name = schema.name if schema else ""
                    yield Msg(channel.topic, name, message.log_time, message.publish_time,
                              message.data, channel.metadata.get("autochair.derived") == "true")
            except Exception as e:  # torn tail of a killed writer: keep what was complete
                self.error = f"{type(e).__name__}: {e}" if str(e) else type(e).__name__

    def messages(self) -> Iterator[Msg]:
        if self.indexed:
            yield from self._raw()
        else:
            # Chunks hold messages in write order, which can differ slightly from receive
            # order across Zenoh threads: sort (loads the file; only for unindexed files).
            yield from sorted(self._raw(), key=lambda m: m.log_ns)

    def summary(self) -> Summary:
        """Channels, counts, first and last log times. A complete (indexed) file: from its
        summary section and the message indexes of each channel's first and last chunks, no
        message read; otherwise (or without message indexes) every message is read."""
        if self.indexed:
            fast = indexed_summary(self.path)
            if fast is not None:
                return fast
        return self.scanned_summary()

    def scanned_summary(self) -> Summary:
        """The summary from reading every message (any file, torn ones included)."""
        out = Summary(self.path, self.indexed)
        for m in self._raw():
            c = out.channels.get(m.topic)
            if c is None:
                c = out.channels[m.topic] = ChannelInfo(m.topic, m.schema, m.derived,
                                                        first_ns=m.log_ns)
            c.count += 1
            c.first_ns = min(c.first_ns, m.log_ns)
            c.last_ns = max(c.last_ns, m.log_ns)
        out.error = self.error
        return out


def _index_times(f: BinaryIO, offset: int) -> npt.NDArray[np.uint64]:
    """Log times of one MessageIndex record (opcode, u64 length, u16 channel, u32 byte length,
    then (u64 log time, u64 offset) pairs)."""
    f.seek(offset + 1 + 8 + 2)
    size = int.from_bytes(f.read(4), "little")
    return np.frombuffer(f.read(size), dtype="<u8")[0::2]


def indexed_summary(path: Path) -> Summary | None:
    """`Recording.summary` of a complete file from its indexes, or None when it lacks them."""
    with open(path, "rb") as f:
        summary = SeekingReader(f).get_summary()
        if summary is None or summary.statistics is None:
            return None
        out = Summary(path, True)
        chunks: dict[int, list[ChunkIndex]] = {}
        for ci in summary.chunk_indexes:
            for cid in ci.message_index_offsets:
                chunks.setdefault(cid, []).append(ci)
        for cid, n in summary.statistics.channel_message_counts.items():
            ch = summary.channels.get(cid)
            if not n or ch is None:
                continue
            have = chunks.get(cid)
            if not have:
                return None  # no message indexes: the caller reads the messages
            # The first (last) time is in the chunk that starts (ends) first (last), or in
            # one that overlaps it in time.
            head = min(have, key=lambda c: c.message_start_time)
            first = int(_index_times(f, head.message_index_offsets[cid]).min())
            first = min([first] + [int(_index_times(f, c.message_index_offsets[cid]).min())
                                   for c in have
                                   if c is not head and c.message_start_time <= first])
            tail = max(have, key=lambda c: c.message_end_time)
            last = int(_index_times(f, tail.message_index_offsets[cid]).max())
            last = max([last] + [int(_index_times(f, c.message_index_offsets[cid]).max())
                                 for c in have if c is not tail and c.message_end_time >= last])
            schema = summary.schemas.get(ch.schema_id)
            out.channels[ch.topic] = ChannelInfo(
                ch.topic, schema.name if schema else "",
                ch.metadata.get("autochair.derived") == "true", n, first, last)
        return out


def recover(src: str | Path, out: str | Path) -> Summary:
    """Write an indexed copy of `src` (every readable message, same channels and schemas) to a
    NEW file `out`: FileExistsError if it exists (nothing recorded is ever overwritten, the
    source included)."""
    rec = Recording(src)
    with open(out, "xb") as f:
        w = Writer(f)
        w.start(profile="", library="autochair-recover")
        schemas: dict[str, int] = {}
        channels: dict[str, int] = {}
        with open(rec.path, "rb") as src_f:
            reader = (SeekingReader(src_f).iter_messages(log_time_order=True) if rec.indexed
                      else NonSeekingReader(src_f).iter_messages(log_time_order=False))
            try:
                for schema, channel, message in reader:
                    if channel.topic not in channels:
                        sname = schema.name if schema else ""
                        if schema is not None and sname not in schemas:
                            schemas[sname] = w.register_schema(sname, schema.encoding,
                                                               schema.data)
                        channels[channel.topic] = w.register_channel(
                            channel.topic, channel.message_encoding,
                            schemas.get(sname, 0), dict(channel.metadata))
                    w.add_message(channels[channel.topic], message.log_time, message.data,
                                  message.publish_time, message.sequence)
            except Exception as e:  # torn tail: everything before it is kept
                rec.error = f"{type(e).__name__}: {e}"
        w.finish()  # type: ignore[no-untyped-call]
    summary = Recording(out).summary()
    summary.error = rec.error
    return summary
