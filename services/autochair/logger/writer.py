"""The logger's pure core: decoded samples in, an MCAP file (or a rotated series) out.

One channel per concrete key (JSON + JSON Schema), derived foxglove.* channels alongside,
zstd chunks. log_time = receive time (the node passes the sample's Zenoh arrival
timestamp), publish_time = the message's own stamp. Time is passed
in: `write` gets the receive time, `tick` the monotonic time that drives the periodic chunk
flush (so a killed writer loses at most `flush_period_s` of data) and duration rotation uses
receive times.

Nothing recorded is ever overwritten: every file is created exclusively (O_EXCL); a name that
is taken (a restart within the same second, a fixed `x.mcap` that exists) gets a suffix:
NAME-1.mcap, NAME-2.mcap, ... (rotation parts of NAME-1 are NAME-1-001.mcap, ...).
"""

from __future__ import annotations

import datetime
import os
import re
from pathlib import Path
from typing import IO, Annotated, Any, Literal

import mcap.writer
import msgspec
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.writer import CompressionType, Writer

from autochair.timing import Decimator
from autochair_msgs import EStopState, Health, keys

from . import foxglove
from .schema import Codec, codec_for

_JSON = msgspec.json.Encoder()
DEFAULT_DIR = "recordings/"


NonNegative = Annotated[float, msgspec.Meta(ge=0)]


class LoggerConfig(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    """[logger] section. Sizes in MiB, times in seconds."""

    # A directory (ends with "/" or exists as one): a new autochair-<UTC time>.mcap per run.
    # A path ending in .mcap: that file. Rotated parts get -001, -002, ... before ".mcap".
    path: str = DEFAULT_DIR
    max_size_mib: NonNegative = 1024.0  # rotate when the file reaches this size; 0 = never
    max_duration_s: NonNegative = 0.0  # rotate after this much receive time; 0 = never
    # close the open chunk at least this often (crash loss bound)
    flush_period_s: Annotated[float, msgspec.Meta(gt=0)] = 1.0
    chunk_size_kib: Annotated[int, msgspec.Meta(ge=1)] = 1024  # ...or at this much data
    # samples waiting per logged key expression (Zenoh's ring for it) before its oldest
    # are dropped (and counted); maps: at most logger.node.MAP_RING
    queue_size: Annotated[int, msgspec.Meta(ge=1)] = 100_000
    compression: Literal["zstd", "lz4", "none"] = "zstd"
    # Maps (keys.MAP_GRID and its /map) recorded at most this often (by
    # receive time; the node's intake): each is the whole map (~240 kB), republished every
    # second for live viewers; 0 = every one.
    map_period_s: NonNegative = 5.0
    # Status that repeats unchanged, recorded when it changes, else at most this often: a
    # service's health (state, detail, last fault; its counters are cumulative, so only the
    # time resolution of their rates is given up) and the e-stop state (latch and causes,
    # repeated at 10 Hz as a heartbeat); 0 = every one.
    repeat_period_s: NonNegative = 5.0


ZSTD_LEVEL = 9


class _Zstd:
    """mcap's Writer compresses each chunk with `zstandard.compress`, at zstd's default level 3.
    Level 9 makes our recordings 16 % smaller (1 s chunks of the simulated stack) for ~0.5 % of
    a core; the module attribute is the only hook the Writer offers."""

    @staticmethod
    def compress(data: bytes) -> bytes:
        return zstandard.ZstdCompressor(level=ZSTD_LEVEL).compress(data)


mcap.writer.zstandard = _Zstd  # type: ignore[attr-defined,assignment]


class Intake:
    """Which received samples the logger records: all, except a whole map again within
    map_period_s of the last one recorded (by receive time)."""

    def __init__(self, cfg: LoggerConfig) -> None:
        self._maps = {keys.MAP_GRID.key: Decimator(int(cfg.map_period_s * 1e9))}

    def take(self, key: str, recv_ns: int) -> bool:
        every = self._maps.get(key)
        return every is None or every(recv_ns)


def _what(msg: msgspec.Struct) -> tuple[str, object] | None:
    """(whose, what it says) of a status message that repeats unchanged, else None."""
    if isinstance(msg, Health):
        return msg.service, (msg.state, msg.detail, msg.last_fault_stamp_ns)
    if isinstance(msg, EStopState):
        return "estop", (msg.latched, msg.causes)
    return None


class RepeatGate:
    """Which repeating status messages the logger records (LoggerConfig.repeat_period_s)."""

    def __init__(self, period_s: float) -> None:
        self.period_ns = int(period_s * 1e9)
        self._last: dict[str, tuple[object, int]] = {}

    def take(self, msg: msgspec.Struct, recv_ns: int) -> bool:
        status = _what(msg)
        if status is None:
            return True
        whose, what = status
        last = self._last.get(whose)
        if last is not None and last[0] == what and 0 <= recv_ns - last[1] < self.period_ns:
            return False
        if len(self._last) > 256:  # bounded: service names come from the wire
            self._last.clear()
        self._last[whose] = (what, recv_ns)
        return True


_COMPRESSION = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4,
                "none": CompressionType.NONE}


def base_path(path: str, start_ns: int) -> Path:
    """The first file of a recording for the configured `path`."""
    p = Path(path)
    if path.endswith(".mcap"):
        return p
    if p.exists() and not p.is_dir():
        raise ValueError(f"{path} exists and is not a directory (a file path must end in .mcap)")
    utc = datetime.datetime.fromtimestamp(start_ns / 1e9, datetime.UTC)
    return p / f"autochair-{utc:%Y%m%d-%H%M%S}.mcap"


def part_path(base: Path, part: int) -> Path:
    return base if part == 0 else base.with_name(f"{base.stem}-{part:03d}{base.suffix}")


def suffixed(path: Path, n: int) -> Path:
    """The n-th name tried for `path` when it is taken: NAME.mcap, NAME-1.mcap, NAME-2.mcap..."""
    return path if n == 0 else path.with_name(f"{path.stem}-{n}{path.suffix}")


def _has_parts(base: Path) -> bool:
    """Rotation parts of `base` (NAME-001.mcap, ...) already on disk."""
    part = re.compile(re.escape(base.stem) + r"-\d{3,}" + re.escape(base.suffix))
    try:
        return any(part.fullmatch(n) for n in os.listdir(base.parent))
    except FileNotFoundError:
        return False


def free_base(base: Path) -> Path:
    """The first of NAME.mcap, NAME-1.mcap, ... for which neither the file nor rotation parts
    exist, so a new recording (and its parts) never collides with an old one."""
    n = 0
    while os.path.lexists(suffixed(base, n)) or _has_parts(suffixed(base, n)):
        n += 1
    return suffixed(base, n)


def create_exclusive(path: Path) -> tuple[IO[bytes], Path]:
    """A new file at `path`, or at the next free suffixed name: never an existing file (O_EXCL,
    also against a name taken between a check and the open)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    n = 0
    while True:
        candidate = suffixed(path, n)
        try:
            return open(candidate, "xb"), candidate  # the caller closes it
        except FileExistsError:
            n += 1


class _File:
    """One open MCAP file and its channel ids. `path` is the name asked for; the file is
    created exclusively, so `self.path` may carry a suffix if that name was taken."""

    def __init__(self, path: Path, cfg: LoggerConfig) -> None:
        self.stream: IO[bytes]
        self.stream, self.path = create_exclusive(path)
        self.mcap = Writer(self.stream, chunk_size=cfg.chunk_size_kib * 1024,
                           compression=_COMPRESSION[cfg.compression])
        self.mcap.start(profile="", library="autochair-logger")
        self.schemas: dict[str, int] = {}
        self.channels: dict[str, int] = {}
        self.sequence: dict[int, int] = {}
        self.start_ns: int | None = None
        self._packed = 0  # chunk indexes already packed

    def channel(self, topic: str, schema_name: str, schema: bytes,
                metadata: dict[str, str]) -> int:
        cid = self.channels.get(topic)
        if cid is None:
            sid = self.schemas.get(schema_name)
            if sid is None:
                sid = self.schemas[schema_name] = self.mcap.register_schema(
                    schema_name, "jsonschema", schema)
            cid = self.channels[topic] = self.mcap.register_channel(
                topic, "json", sid, metadata)
        return cid

    def add(self, cid: int, log_ns: int, publish_ns: int, data: bytes) -> None:
        seq = self.sequence.get(cid, 0)
        self.sequence[cid] = seq + 1
        self.mcap.add_message(cid, log_ns, data, publish_ns, seq)
        if self.start_ns is None:
            self.start_ns = log_ns

    def flush(self) -> None:
        """Close the open chunk (crash safety) and pack the chunk indexes kept for the summary."""
        self.mcap.flush()  # type: ignore[no-untyped-call]
        # mcap's Writer keeps every chunk's ChunkIndex object, with a per-channel dict, until
        # finish(): ~5 KB a chunk, 31 MB over a one-hour soak at a chunk a second. Keep each as
        # its serialised record instead (~0.5 KB); the summary bytes are identical (tested).
        indexes: list[Any] = self.mcap._Writer__chunk_indices  # type: ignore[attr-defined]
        for i in range(self._packed, len(indexes)):
            indexes[i] = _PackedRecord(indexes[i])
        self._packed = len(indexes)

    def finish(self) -> None:
        self.mcap.finish()  # type: ignore[no-untyped-call]
        self.stream.close()


class _PackedRecord:
    """A record serialised once; `write` appends its bytes (the interface the summary uses)."""

    __slots__ = ("raw",)

    def __init__(self, record: Any) -> None:
        builder = RecordBuilder()
        record.write(builder)
        self.raw: bytes = builder.end()  # type: ignore[no-untyped-call]

    def write(self, stream: RecordBuilder) -> None:
        stream.write(self.raw)


class Recorder:
    """Writes samples `(key, msgpack payload, receive ns)` to MCAP. Not thread-safe: one
    writer thread owns it."""

    def __init__(self, cfg: LoggerConfig, start_ns: int, start_mono_s: float) -> None:
        self.cfg = cfg
        self.requested = base_path(cfg.path, start_ns)  # the configured name
        self.base = free_base(self.requested)  # never an existing recording's name
        self.files: list[Path] = []
        self.counters: dict[str, int] = {"written": 0, "derived": 0, "decode_errors": 0,
                                         "unknown_keys": 0, "flushes": 0, "rotations": 0,
                                         "repeats_held": 0}
        self._repeats = RepeatGate(cfg.repeat_period_s)
        self.last_error = ""
        self._codecs: dict[str, tuple[Codec, dict[str, str], str]] = {}
        self._deriver = foxglove.Deriver()

        self._fox_schemas = {n: _JSON.encode(s) for n, s in foxglove.SCHEMAS.items()}
        self._last_flush = start_mono_s
        self._since_size_check = 0
        self._file: _File | None = self._open()

    def _open(self) -> _File:
        f = _File(part_path(self.base, len(self.files)), self.cfg)
        self.files.append(f.path)
        return f

    def _codec(self, key: str) -> tuple[Codec, dict[str, str], str] | None:
        entry = self._codecs.get(key)
        if entry is None:
            try:
                topic = keys.by_key(key)
            except KeyError:
                return None
            meta = {"autochair.type": topic.type.__name__, "autochair.doc": topic.doc}
            entry = self._codecs[key] = (codec_for(topic.type), meta, topic.key)
        return entry

    def write(self, key: str, payload: bytes, recv_ns: int) -> bool:
        """Record one sample; False (and counted) if it cannot be decoded."""
        f = self._file
        assert f is not None, "write after finish"
        entry = self._codec(key)
        if entry is None:
            self.counters["unknown_keys"] += 1
            self.last_error = f"no row in keys.TOPICS for {key}"
            return False
        codec, meta, row = entry
        try:
            msg = codec.decode_wire(payload)
        except (msgspec.DecodeError, msgspec.ValidationError) as e:
            self.counters["decode_errors"] += 1
            self.last_error = f"{key}: {e}"
            return False
        if not self._repeats.take(msg, recv_ns):
            self.counters["repeats_held"] += 1
            return True
        if f.start_ns is not None and self.cfg.max_duration_s > 0 and \
                recv_ns - f.start_ns >= self.cfg.max_duration_s * 1e9:
            f = self._rotate()
        stamp = getattr(msg, "stamp_ns", recv_ns)
        cid = f.channel(key, codec.name, codec.schema, meta)
        f.add(cid, recv_ns, stamp, codec.encode_json(msg))
        self.counters["written"] += 1
        for topic, stamp_ns, obj in self._deriver.derive(row, msg):
            self._add_derived(f, topic, recv_ns, stamp_ns, obj)
        self._since_size_check += 1
        if self._since_size_check >= 256:
            self._check_size()
        return True

    def note(self, level: str, message: str, stamp_ns: int) -> None:
        """Write a foxglove.Log of the logger's own (e.g. drops), straight into the file."""
        if self._file is not None:
            self._add_derived(self._file, foxglove.TOPIC_LOG, stamp_ns, stamp_ns,
                              foxglove.log_message(stamp_ns, level, "logger", message))

    def _add_derived(self, f: _File, topic: str, log_ns: int, stamp_ns: int,
                     obj: dict[str, Any]) -> None:
        name = foxglove.DERIVED[topic]
        cid = f.channel(topic, name, self._fox_schemas[name], {"autochair.derived": "true"})
        f.add(cid, log_ns, stamp_ns, _JSON.encode(obj))
        self.counters["derived"] += 1

    def tick(self, mono_s: float) -> None:
        """Call often (at least a few times a second): flushes the open chunk on schedule."""
        if self._file is not None and mono_s - self._last_flush >= self.cfg.flush_period_s:
            self._last_flush = mono_s
            self._file.flush()
            self.counters["flushes"] += 1
            self._check_size()

    def _check_size(self) -> None:
        self._since_size_check = 0
        if self._file is not None and self.cfg.max_size_mib > 0 and \
                self._file.stream.tell() >= self.cfg.max_size_mib * 1024 * 1024:
            self._rotate()

    def _rotate(self) -> _File:
        assert self._file is not None
        self._file.finish()
        self.counters["rotations"] += 1
        self._file = self._open()
        return self._file

    @property
    def path(self) -> Path:
        return self.files[-1]

    def finish(self) -> None:
        """Write the summary and indexes (a complete, seekable file) and close."""
        if self._file is not None:
            self._file.finish()
            self._file = None
