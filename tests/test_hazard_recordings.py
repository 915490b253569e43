"""Hazard: a recording (the evidence of what a chair did) overwritten by the next run. Files are
created exclusively (O_EXCL); a taken name gets a suffix (NAME-1.mcap, ...), rotation parts stay
NAME-001.mcap, ... and a logger restart starts a new file. Every test keeps the old files and
checks them byte for byte."""

from __future__ import annotations

from pathlib import Path

import msgspec
import pytest

from autochair.logger.node import start
from autochair.logger.reader import Recording, is_indexed
from autochair.logger.writer import (
    LoggerConfig,
    Recorder,
    create_exclusive,
    free_base,
    suffixed,
)
from autochair.runtime import Node
from autochair.runtime.client import Publisher, subscribe
from autochair.runtime.config import ZenohSettings
from autochair_msgs import LogEvent, keys
from tests.helpers import wait_for
from tests.logger_samples import T0, samples

ENC = msgspec.msgpack.Encoder()
ODOM = ENC.encode(samples()[keys.ODOM.key])


def recording(path: Path | str, n: int = 5, start_ns: int = T0, **cfg: object) -> Recorder:
    rec = Recorder(LoggerConfig(path=str(path), **cfg), start_ns, 0.0)  # type: ignore[arg-type]
    for i in range(n):
        assert rec.write(keys.ODOM.key, ODOM, start_ns + i * 10_000_000)
    rec.finish()
    return rec


def odom_count(path: Path) -> int:
    return Recording(path).summary().channels[keys.ODOM.key].count


def snapshot(directory: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(directory.iterdir()) if p.is_file()}


def test_fixed_file_that_exists_is_kept_and_the_new_one_suffixed(tmp_path: Path) -> None:
    old = recording(tmp_path / "x.mcap", n=3)
    assert old.files == [tmp_path / "x.mcap"]  # control: a free name is used as given
    before = snapshot(tmp_path)
    new = recording(tmp_path / "x.mcap", n=7)
    assert new.requested == tmp_path / "x.mcap" and new.files == [tmp_path / "x-1.mcap"]
    assert {k: v for k, v in snapshot(tmp_path).items() if k in before} == before
    assert odom_count(tmp_path / "x.mcap") == 3 and odom_count(tmp_path / "x-1.mcap") == 7
    third = recording(tmp_path / "x.mcap", n=1)
    assert third.files == [tmp_path / "x-2.mcap"]
    assert odom_count(tmp_path / "x-1.mcap") == 7


def test_restart_within_the_same_second_in_a_directory(tmp_path: Path) -> None:
    first = recording(str(tmp_path) + "/", n=4)
    before = snapshot(tmp_path)
    second = recording(str(tmp_path) + "/", n=2)  # same start second: same generated name
    assert second.requested == first.files[0]
    assert second.files == [suffixed(first.files[0], 1)]
    assert second.files[0].name.endswith("-1.mcap")
    assert {k: v for k, v in snapshot(tmp_path).items() if k in before} == before
    assert odom_count(first.files[0]) == 4 and odom_count(second.files[0]) == 2


def test_rotation_parts_never_collide_with_an_earlier_series(tmp_path: Path) -> None:
    old = recording(tmp_path / "big.mcap", n=30, max_duration_s=0.1)
    assert len(old.files) == 3 and old.files[1] == tmp_path / "big-001.mcap"
    before = snapshot(tmp_path)
    new = recording(tmp_path / "big.mcap", n=30, max_duration_s=0.1)
    assert new.files[0] == tmp_path / "big-1.mcap"
    assert new.files[1] == tmp_path / "big-1-001.mcap"  # the parts scheme, on the new name
    assert {k: v for k, v in snapshot(tmp_path).items() if k in before} == before
    assert [odom_count(p) for p in new.files] == [10, 10, 10]
    assert [odom_count(p) for p in old.files] == [10, 10, 10]


def test_left_over_parts_without_their_first_file_are_kept(tmp_path: Path) -> None:
    (tmp_path / "run-001.mcap").write_bytes(b"part of an earlier run")
    assert free_base(tmp_path / "run.mcap") == tmp_path / "run-1.mcap"
    assert free_base(tmp_path / "other.mcap") == tmp_path / "other.mcap"  # control
    rec = Recorder(LoggerConfig(path=str(tmp_path / "run.mcap"), max_duration_s=0.05), T0, 0.0)
    for i in range(3):
        rec.write(keys.ODOM.key, ODOM, T0 + i * 60_000_000)  # rotates twice
    rec.finish()
    assert rec.files[:2] == [tmp_path / "run-1.mcap", tmp_path / "run-1-001.mcap"]
    assert (tmp_path / "run-001.mcap").read_bytes() == b"part of an earlier run"


def test_a_part_name_taken_during_the_run_is_not_overwritten(tmp_path: Path) -> None:
    rec = Recorder(LoggerConfig(path=str(tmp_path / "r.mcap"), max_duration_s=0.05), T0, 0.0)
    rec.write(keys.ODOM.key, ODOM, T0)
    (tmp_path / "r-001.mcap").write_bytes(b"someone else's file")  # after the name was chosen
    rec.write(keys.ODOM.key, ODOM, T0 + 60_000_000)  # rotates: r-001.mcap is taken now
    rec.finish()
    assert rec.files == [tmp_path / "r.mcap", tmp_path / "r-001-1.mcap"]
    assert (tmp_path / "r-001.mcap").read_bytes() == b"someone else's file"
    assert odom_count(tmp_path / "r-001-1.mcap") == 1


def test_a_symlink_at_the_path_is_not_followed(tmp_path: Path) -> None:
    target = tmp_path / "precious.mcap"
    target.write_bytes(b"evidence")
    (tmp_path / "x.mcap").symlink_to(target)
    (tmp_path / "dangling.mcap").symlink_to(tmp_path / "nowhere.mcap")
    stream, path = create_exclusive(tmp_path / "x.mcap")
    stream.close()
    assert path == tmp_path / "x-1.mcap" and target.read_bytes() == b"evidence"
    rec = recording(tmp_path / "dangling.mcap", n=1)
    assert rec.files == [tmp_path / "dangling-1.mcap"]
    assert not (tmp_path / "nowhere.mcap").exists()


def test_logger_restart_starts_a_new_file(tmp_path: Path) -> None:
    """The logger node itself (in-process, isolated peer): run, stop, run again on the same
    fixed path: the first recording stays byte-identical, the second goes to x-1.mcap."""
    path = tmp_path / "x.mcap"

    def run_logger(n: int) -> tuple[Node, list[str]]:
        node = Node("logger", ZenohSettings(connect=[], listen=["tcp/127.0.0.1:0"]))
        events: list[str] = []

        def on_log(m: LogEvent) -> None:
            events.append(m.message)

        subscribe(node.session, keys.LOG, on_log)
        start(node, LoggerConfig(path=str(path)))
        pub = Publisher(node.session, keys.ODOM)
        for _ in range(n):
            pub.put_raw(ODOM)
        return node, events

    node, _ = run_logger(3)
    try:
        wait_for(lambda: node.health.counters.get("written", 0) >= 3, 10, "first run written")
    finally:
        node.close()
    wait_for(lambda: is_indexed(path), 10, "first recording finished")
    first = path.read_bytes()
    assert odom_count(path) == 3
    node, events = run_logger(2)
    try:
        wait_for(lambda: node.health.counters.get("written", 0) >= 2, 10, "second run written")
        assert path.read_bytes() == first  # not truncated while the second run records
        assert "x-1.mcap" in node.health.detail
        wait_for(lambda: any("never overwritten" in e for e in events), 5, "the event")
    finally:
        node.close()
    wait_for(lambda: is_indexed(tmp_path / "x-1.mcap"), 10, "second recording finished")
    assert path.read_bytes() == first
    assert odom_count(tmp_path / "x-1.mcap") == 2


def test_exclusive_create_fails_loudly_rather_than_overwriting(tmp_path: Path) -> None:
    """Control for the loop in create_exclusive: only FileExistsError moves on to the next
    name; any other error (here: the parent is a file) is raised, never swallowed."""
    (tmp_path / "file").write_text("x")
    with pytest.raises(OSError):
        create_exclusive(tmp_path / "file" / "x.mcap")


def test_recover_never_overwrites_the_recording_or_any_file(tmp_path: Path) -> None:
    import subprocess
    import sys

    src = tmp_path / "run.mcap"
    rec = Recorder(LoggerConfig(path=str(src)), T0, 0.0)
    rec.write(keys.ODOM.key, msgspec.msgpack.encode(samples()[keys.ODOM.key]), T0)
    rec.finish()
    before = src.read_bytes()
    cmd = [sys.executable, "-m", "autochair.cli", "info", str(src), "--recover"]
    same = subprocess.run([*cmd, str(src)], capture_output=True, text=True, timeout=60)
    assert same.returncode == 2 and "never overwrites" in same.stderr
    assert src.read_bytes() == before  # the source survives byte for byte
    fresh = subprocess.run([*cmd, str(tmp_path / "copy.mcap")], capture_output=True,
                           text=True, timeout=60)
    assert fresh.returncode == 0, fresh.stderr  # positive control
    assert (tmp_path / "copy.mcap").exists()
