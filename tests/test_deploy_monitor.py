"""`autochair monitor` from a view-only laptop over mutual TLS, and its pure state."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from autochair.cli import main as cli
from autochair.commands.certs import make_all
from autochair.commands.monitor_core import MonitorState
from autochair.runtime.client import declare_alive
from autochair.runtime.node import encode
from autochair_msgs import Health, LaserScan, LogEvent, Odometry, keys
from tests.test_deploy_tls import Chair


def sample_msgs() -> tuple[Health, Odometry, LaserScan, LogEvent]:
    t = time.time_ns()
    return (Health(stamp_ns=t, service="odometry", state="ok", uptime_s=12.0,
                   last_fault="encoder gap"),
            Odometry(stamp_ns=t, x_m=1.25, y_m=-0.5, yaw_rad=math.pi / 2, v_mps=0.3,
                     omega_radps=-0.1, distance_m=4.0),
            LaserScan(stamp_ns=t, frame_id="laser", angle_min_rad=-math.pi / 2,
                      angle_increment_rad=math.pi / 2, range_min_m=0.02, range_max_m=5.6,
                      ranges_m=[2.0, math.nan, 0.75], scan_seq=7),
            LogEvent(stamp_ns=t, service="gateway", level="error", message="serial lost"))


def test_state_renders_services_pose_scan_and_faults() -> None:
    h, o, s, e = sample_msgs()
    st = MonitorState(["router", "odometry", "pid"])
    st.on_alive("odometry", True)
    st.on_alive("router", True)
    st.on_alive("router", False)
    st.on_health(h, 10.0)
    st.on_odom(o, 10.0)
    st.on_scan(s, 10.0)
    st.on_log(e)
    st.on_log(LogEvent(stamp_ns=0, service="x", level="info", message="chatter"))
    text = st.render(10.5)
    assert "odometry      up    ok" in text and "encoder gap" in text
    assert "router        DOWN" in text and "pid           DOWN" in text
    assert "x   +1.250 m" in text and "yaw   +90.0 deg" in text
    assert "2/3 valid, nearest 0.75 m at +90 deg" in text
    assert "gateway: error: serial lost" in text and "chatter" not in text
    assert "drive  " not in text  # positive control for the line below
    st.on_health(Health(stamp_ns=0, service="pid", state="ok", uptime_s=5.0,
                        detail="owner autonomy: e-stop latched"), 10.0)
    assert "drive  owner autonomy: e-stop latched" in st.render(10.5)
    stale = st.render(20.0)  # old health and pose are not shown as current
    assert "(no odometry)" in stale and "(no scan)" in stale and "encoder gap" not in stale


@pytest.fixture()
def chair(tmp_path: Path) -> Iterator[Chair]:
    make_all(tmp_path, [], [("bob", "view")], "tls/127.0.0.1:1")  # port given by --connect
    c = Chair(tmp_path)
    try:
        yield c
    finally:
        c.close()


def test_monitor_once_over_tls_as_view_only_laptop(chair: Chair, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    svc = chair.service
    token = declare_alive(svc, "odometry")
    stop = threading.Event()
    h, o, s, e = sample_msgs()

    def feed() -> None:
        while not stop.wait(0.05):
            svc.put(keys.HEALTH.for_service("odometry"), encode(h))
            svc.put(keys.ODOM_SLOW.key, encode(o))
            svc.put(keys.SCAN.key, encode(s))
            svc.put(keys.LOG.key, encode(e))

    t = threading.Thread(target=feed, daemon=True)
    t.start()
    try:
        rc = cli(["monitor", "--once", "--wait", "2",
                  "--zenoh-config", str(tmp_path / "bob.json5"),
                  "--connect", f"tls/127.0.0.1:{chair.tls}"])
    finally:
        stop.set()
        t.join()
        token.undeclare()
    out = capsys.readouterr().out
    assert rc == 0
    assert "odometry      up    ok" in out
    assert "x   +1.250 m" in out and "nearest 0.75 m" in out
    assert "serial lost" in out
