"""The localization process on the simulated chair and lidar: map, save the map, restart on it,
find the chair with no initial pose, take a pose from `autochair localize`."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

from autochair.mapping.mapfile import load_map
from autochair.runtime.client import request
from autochair_msgs import (
    LocalizedPose,
    LocalizeReply,
    LocalizeRequest,
    MapSaveReply,
    MapSaveRequest,
    keys,
)
from tests.helpers import Recorder, session_when_up, spawned, stop_process, wait_for

pytestmark = pytest.mark.slow


def _tracking_near(rec: Recorder, x: float, y: float, after: int, tol: float = 0.08
                   ) -> LocalizedPose | None:
    for _, m in rec.items[after:]:
        if m.state == "tracking" and math.hypot(m.x_m - x, m.y_m - y) < tol:
            return m  # type: ignore[no-any-return]
    return None


def test_map_save_restart_and_localize(tmp_path: Path) -> None:
    maps = tmp_path / "maps"
    with spawned(tmp_path) as (hub, start):
        start("autochair.sim.chair.node", "--set", f"pty_link={tmp_path}/arduino")
        start("autochair.gateway.node", "--set", f"port={tmp_path}/arduino")
        start("autochair.odometry.node")
        start("autochair.sim.lidar.node", "--set", f"pty_link={tmp_path}/lidar")
        start("autochair.lidar.node", "--set", f"url={tmp_path}/lidar")
        loc = start("autochair.localization.node", "--set", f"maps_dir={maps}")
        session = session_when_up(hub)
        try:
            poses = Recorder(session, keys.LOC_POSE)
            tfs = Recorder(session, keys.TF)
            wait_for(lambda: len(poses.items) >= 10, 40, "mapping-mode poses")
            assert poses.items[-1][1].mode == "mapping"
            wait_for(lambda: any(t.parent_frame_id == "map" and t.child_frame_id == "odom"
                                 for _, t in tfs.items), 10, "map → odom transform")
            reply = request(session, keys.MAP_SAVE, MapSaveRequest(name="hall"), MapSaveReply)
            assert reply.ok, reply.error
            m = load_map(maps / "hall.yaml")
            # The hallway's left wall (y = 1.4) beside the chair is in the saved map.
            iy = int((1.4 - m.origin_y_m) / m.resolution_m)
            ix = int((1.0 - m.origin_x_m) / m.resolution_m)
            assert m.occupied[iy - 1:iy + 2, ix - 5:ix + 5].any()
            assert not m.occupied[int((0.0 - m.origin_y_m) / m.resolution_m), ix]
            bad = request(session, keys.MAP_SAVE, MapSaveRequest(name="../x"), MapSaveReply)
            assert not bad.ok and "map name" in bad.error

            stop_process(loc)
            n = len(poses.items)
            start("autochair.localization.node", "--set", f"maps_dir={maps}", "--map", "hall")
            # No initial pose: found by searching the whole map.
            found = wait_for(lambda: _tracking_near(poses, 0.0, 0.0, n), 40, "global fix")
            assert found.mode == "localization" and found.quality > 0.8
            # `autochair localize --global`: searched for again, found again.
            reply_g = request(session, keys.LOC_SET_POSE, LocalizeRequest(pose=None),
                              LocalizeReply)
            assert reply_g.ok and reply_g.state == "initializing"
            n = len(poses.items)
            wait_for(lambda: _tracking_near(poses, 0.0, 0.0, n), 20, "second global fix")
            n = len(poses.items)
            # The people's way: `autochair localize`, with a guess 36 cm and 5° off. A guess
            # is not tracked until a scan fits near it (hazards H33): searched for within 2σ
            # (the CLI's 30 cm), found on the next scan; the CLI waits for that and says so.
            proc = subprocess.run(
                [sys.executable, "-m", "autochair.cli", "localize", "0.3", "-0.2", "5",
                 "--connect", hub, "--wait", "30"], capture_output=True, text=True,
                timeout=60, stdin=subprocess.DEVNULL)
            assert proc.returncode == 0, proc.stdout + proc.stderr
            assert "localization: initializing (searching near the pose given)" in proc.stdout
            assert "tracking at" in proc.stdout and "from the pose given" in proc.stdout
            print(proc.stdout)

            def tracked() -> list[LocalizedPose]:
                return [m for _, m in poses.items[n:] if m.state == "tracking"]

            wait_for(lambda: len(tracked()) >= 3, 30, "tracking after a 36 cm wrong hint")
            # on the chair from the first, never near the hint (before: 10-20 cm off for
            # 10-25 scans, once > 40 s)
            assert max(math.hypot(m.x_m, m.y_m) for m in tracked()) < 0.05
        finally:
            session.close()
