"""Recordings read with Foxglove's own MCAP reader (npm @mcap/core), and every foxglove.*
message validates against Foxglove's published JSON Schemas (npm @foxglove/schemas).

The npm packages are installed here (`npm ci` into tests/js/node_modules from the committed
package-lock.json), so a fresh clone needs only node/npm and the npm registry.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any

import msgspec
import pytest
from mcap.writer import Writer

from autochair.logger import foxglove
from autochair.logger.writer import LoggerConfig, Recorder
from tests.helpers import npm_ready
from tests.logger_samples import T0, samples


@pytest.fixture(scope="session")
def node_check() -> Path:
    return npm_ready() / "check_mcap.js"


def run_check(script: Path, path: Path, *args: str) -> dict[str, Any]:
    r = subprocess.run(["node", str(script), str(path), *args], capture_output=True, text=True,
                       timeout=120)
    assert r.stdout, r.stderr
    out: dict[str, Any] = json.loads(r.stdout)
    assert "fatal" not in out, out["fatal"]
    return out


def test_recording_reads_in_foxglove_reader_and_validates(node_check: Path,
                                                          tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    rec = Recorder(LoggerConfig(path=str(path)), T0, 0.0)
    n = 0
    for i in range(20):
        for key, msg in samples(i).items():
            assert rec.write(key, msgspec.msgpack.encode(msg), T0 + i * 1000)
            n += 1
    rec.finish()
    out = run_check(node_check, path)
    assert out["errors"] == []
    assert out["indexed"] and out["statistics_count"] == sum(
        c["count"] for c in out["channels"].values())
    raw = sum(c["count"] for t, c in out["channels"].items() if not t.startswith("/"))
    assert raw == n
    schemas = {c["schema"] for c in out["channels"].values()}
    assert set(foxglove.DERIVED.values()) <= schemas
    # the raw scan channel is validated against Foxglove's own LaserScan schema
    assert out["channels"]["autochair/lidar/scan"]["schema"] == "foxglove.LaserScan"


def test_unfinished_recording_reads_with_stream_reader(node_check: Path,
                                                       tmp_path: Path) -> None:
    path = tmp_path / "killed.mcap"
    rec = Recorder(LoggerConfig(path=str(path)), T0, 0.0)
    for key, msg in samples().items():
        rec.write(key, msgspec.msgpack.encode(msg), T0)
    rec.tick(5.0)  # flushed chunk, no summary (as after SIGKILL)
    out = run_check(node_check, path, "--stream")
    assert out["errors"] == [] and out["complete"] is False
    assert out["channels"]["autochair/lidar/scan"]["count"] == 1


def test_checker_rejects_an_invalid_foxglove_message(node_check: Path, tmp_path: Path) -> None:
    """The validation above can fail: a Log with a level outside the enum is reported."""
    path = tmp_path / "bad.mcap"
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema("foxglove.Log", "jsonschema",
                                json.dumps(foxglove.SCHEMAS["foxglove.Log"]).encode())
        cid = w.register_channel("/log", "json", sid)
        bad = foxglove.log_message(T0, "info", "x", "y") | {"level": 9}
        w.add_message(cid, T0, json.dumps(bad).encode(), T0)
        w.finish()  # type: ignore[no-untyped-call]
    out = run_check(node_check, path)
    assert len(out["errors"]) == 1 and "foxglove.Log" in out["errors"][0]
