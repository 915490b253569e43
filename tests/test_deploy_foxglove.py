"""The live Foxglove bridge, read by a real Foxglove client (npm @foxglove/ws-protocol)."""

from __future__ import annotations

import json
import math
import subprocess
import threading
import time

import pytest

from autochair.commands.foxglove import Bridge
from autochair.launcher import free_port
from autochair.runtime.node import encode
from autochair_msgs import FrameTransform, LaserScan, Odometry, Quaternion, Vector3, keys
from tests.helpers import JS, npm_ready
from tests.test_deploy_tls import open_json

foxglove = pytest.importorskip("foxglove", reason="foxglove-sdk (the `remote` extra) missing")


@pytest.mark.slow
def test_bridge_serves_pose_tf_scan_and_plots_to_a_foxglove_client() -> None:
    npm_ready()
    hub = f"tcp/127.0.0.1:{free_port()}"
    router = open_json({"mode": "router", "listen": {"endpoints": [hub]},
                        "scouting": {"multicast": {"enabled": False}}})
    client = {"mode": "client", "connect": {"endpoints": [hub]},
              "scouting": {"multicast": {"enabled": False}}}
    chair, laptop = open_json(client), open_json(client)
    Bridge(laptop)
    server = foxglove.start_server(host="127.0.0.1", port=0)
    stop = threading.Event()

    def feed() -> None:
        while not stop.wait(0.05):
            t = time.time_ns()
            chair.put(keys.ODOM.key, encode(Odometry(stamp_ns=t, x_m=1.5, y_m=2.0, yaw_rad=0.5,
                                                     v_mps=0.25, omega_radps=0.1)))
            chair.put(keys.TF.key, encode(FrameTransform(
                stamp_ns=t, parent_frame_id="odom", child_frame_id="chair",
                translation=Vector3(1.5, 2.0, 0.0), rotation=Quaternion())))
            chair.put(keys.SCAN.key, encode(LaserScan(
                stamp_ns=t, frame_id="laser", angle_min_rad=-1.0, angle_increment_rad=0.5,
                range_min_m=0.02, range_max_m=5.6, ranges_m=[1.0, math.nan, 2.5])))

    th = threading.Thread(target=feed, daemon=True)
    th.start()
    try:
        r = subprocess.run(["node", str(JS / "foxglove_ws.js"), f"ws://127.0.0.1:{server.port}",
                            "autochair/tf", "autochair/lidar/scan", "autochair/odom"],
                           capture_output=True, text=True, timeout=60)
    finally:
        stop.set()
        th.join()
        server.stop()
        for s in (laptop, chair, router):
            s.close()
    out = json.loads(r.stdout or "{}")
    assert "error" not in out, (out, r.stderr)
    ch, first = out["channels"], out["first"]
    assert ch["autochair/lidar/scan"]["schemaName"] == "foxglove.LaserScan"
    assert ch["autochair/tf"]["schemaName"] == "foxglove.FrameTransform"
    assert ch["autochair/odom"] == {"encoding": "json", "schemaName": "autochair_msgs.Odometry"}
    scan = first["autochair/lidar/scan"]
    assert scan["ranges"] == [1.0, 0.0, 2.5]  # NaN beam drawn at the sensor, its value kept:
    assert scan["nonfinite"] == {"1": "NaN"} and scan["range_max_m"] == 5.6
    assert first["autochair/tf"]["child_frame_id"] == "chair"
    assert first["autochair/tf"]["timestamp"]["sec"] > 0
    assert first["autochair/odom"]["v_mps"] == 0.25
