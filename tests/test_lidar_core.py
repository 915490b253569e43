"""Ingest core ↔ simulated URG-04LX core, in process (no pty, no Zenoh)."""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from autochair.backoff import Backoff
from autochair.geometry import mount_mismatch
from autochair.lidar.core import (
    WRAP,
    ClockSync,
    IngestPolicy,
    LaserParams,
    LidarClient,
    LidarTimeout,
    Link,
    ScanDecoder,
    Unwrapper,
)
from autochair.lidar.node import LidarConfig, mount_transform
from autochair.protocol import scip
from autochair.runtime.config import ChairGeometry
from autochair.sim.lidar.scanner import UrgDevice, UrgParams, ray_scan
from autochair.sim.world import World, WorldError, load_world, parse_world, raycast
from autochair_msgs import LaserScan

MOUNT = ChairGeometry().laser_mount  # (0.8636, 0.2032, 0.0), the [chair] default


class FakeLink:
    """A transport wired to a UrgDevice, on a simulated clock advanced by reads."""

    def __init__(self, dev: UrgDevice, step_s: float = 0.01) -> None:
        self.dev, self.t, self.step_s, self.out = dev, 0.0, step_s, b""
        self.drop_next_scans = 0

    def write(self, data: bytes) -> None:
        for line in data.split(b"\n")[:-1]:
            self.out += self.dev.handle(line, self.t)

    def read(self, timeout_s: float) -> bytes:
        if not self.out:
            self.t += self.step_s
            for block in self.dev.poll(self.t):
                if self.drop_next_scans:
                    self.drop_next_scans -= 1
                    continue
                self.out += block
        out, self.out = self.out, b""
        return out

    def close(self) -> None:
        pass


def make(clock_start_ms: int = 0, noise: float = 0.0, rate: float = 10.0
         ) -> tuple[FakeLink, LidarClient, dict[str, int]]:
    world, params = load_world(), UrgParams(scan_rate_hz=rate)
    rng = np.random.default_rng(1)
    dev = UrgDevice(params, lambda _t: ray_scan(world, params, (0, 0, 0), MOUNT, noise, rng),
                    clock_start_ms)
    link = FakeLink(dev)
    counts: dict[str, int] = {}

    def count(k: str, n: int) -> None:
        counts[k] = counts.get(k, 0) + n

    return link, LidarClient(link, count, lambda: link.t), counts


def run_scans(link: FakeLink, client: LidarClient, dec: ScanDecoder, n: int) -> list[LaserScan]:
    out: list[LaserScan] = []
    while len(out) < n:
        for block in client.scan_blocks(0.1):
            out.append(dec.decode(block, 1_700_000_000_000_000_000 + int(link.t * 1e9)))
    return out


def test_handshake_switches_from_scip11_and_reads_pp() -> None:
    link, client, counts = make()
    assert link.dev.handle(b"QT", 0) == b"QT\nE\n\n"  # boots in SCIP 1.1
    params, req = client.start(None, None, 1, 0)
    assert (params.dmin_mm, params.dmax_mm, params.ares, params.amin, params.amax,
            params.afrt, params.scan_rpm) == (20, 5600, 1024, 44, 725, 384, 600)
    assert req == scip.ScanRequest("MD", 44, 725, 1, 0, 0)
    assert link.dev.scip2 and link.dev.stream is not None
    assert counts == {}


def test_scans_are_metres_with_nan_errors_and_right_angles() -> None:
    link, client, counts = make()
    params, req = client.start(None, None, 1, 0)
    dec = ScanDecoder(params, req, "laser", lambda k, n: counts.__setitem__(k, n))
    (scan,) = run_scans(link, client, dec, 1)
    r = np.array(scan.ranges_m)
    assert r.size == 682
    assert scan.angle_min_rad == pytest.approx((44 - 384) * 2 * math.pi / 1024)
    a = scan.angle_min_rad + scan.angle_increment_rad * np.arange(682)
    left = int(np.argmin(abs(a - math.pi / 2)))
    assert r[left] == pytest.approx(1.4 - 0.2032, abs=0.002)  # the left wall, no noise
    assert np.isnan(r[int(np.argmin(abs(a)))])  # 21 m down the hallway: beyond DMAX
    assert np.nanmin(r) >= 0.02 and np.nanmax(r) <= 5.6


def test_clock_wraps_and_gaps_count_dropped_scans() -> None:
    link, client, counts = make(clock_start_ms=WRAP - 250)

    def count(k: str, n: int) -> None:
        counts[k] = counts.get(k, 0) + n

    params, req = client.start(None, None, 1, 0)
    dec = ScanDecoder(params, req, "laser", count)
    scans = run_scans(link, client, dec, 5)
    times = [s.device_time_ms for s in scans]
    assert times[-1] > WRAP and all(
        abs(b - a - 100) <= 1 for a, b in pairwise(times))
    link.drop_next_scans = 3
    scans += run_scans(link, client, dec, 1)
    assert abs(scans[-1].device_time_ms - times[-1] - 400) <= 1
    assert counts.get("dropped_scans") == 3
    stamps = [s.stamp_ns for s in scans]
    assert all(b > a for a, b in pairwise(stamps))


def test_a_stalled_device_says_which_gaps_are_its_own() -> None:
    """A device whose process stalls past its slots skips them (not bunched) and counts them:
    the ingest's dropped_scans is those plus what the link lost, so a system test can tell
    a stalled simulator from scans lost on the way."""
    link, client, counts = make()

    def count(k: str, n: int) -> None:
        counts[k] = counts.get(k, 0) + n

    params, req = client.start(None, None, 1, 0)
    dec = ScanDecoder(params, req, "laser", count)
    scans = run_scans(link, client, dec, 3)
    assert link.dev.skipped_scans == 0 and "dropped_scans" not in counts
    link.t += 0.35  # stalled 0.35 s just after a scan (10 Hz): the next two slots pass
    scans += run_scans(link, client, dec, 1)
    assert scans[-1].device_time_ms - scans[-2].device_time_ms == 300
    assert link.dev.skipped_scans == 2 and counts["dropped_scans"] == 2
    link.drop_next_scans = 3  # lost on the link: the device sent them
    scans += run_scans(link, client, dec, 1)
    assert link.dev.skipped_scans == 2 and counts["dropped_scans"] == 5
    # Every second scan (interval 1): only skipped scans it would have sent count.
    dev = UrgDevice(UrgParams(), lambda _t: np.full(682, 1000, dtype=np.int64))
    dev.handle(b"SCIP2.0", 0)
    dev.handle(b"MD0044072501100", 0)
    sent = [len(dev.poll(t + 1e-9)) for t in (0.1, 0.2, 0.3, 0.4, 1.0)]
    assert sent == [1, 0, 1, 0, 0] and dev.skipped_scans == 3  # scans 5, 7, 9 of 1..10
    assert dev.poll(1.1 + 1e-9) and dev.skipped_scans == 3  # scan 11, on time


def test_clock_sync_min_filter_ignores_latency_spikes() -> None:
    sync = ClockSync(window=20, period_ns=0)
    rng = np.random.default_rng(0)
    true_offset = 1_000_000_000_000
    for k in range(100):
        dev_ms = 5000 + 100 * k
        latency = 2_000_000 + int(rng.integers(0, 1_000_000))
        if k % 7 == 0:
            latency += 300_000_000  # a 300 ms spike
        sync.update(dev_ms, dev_ms * 1_000_000 + true_offset + latency)
    assert abs(sync.offset_ns - true_offset - 2_000_000) < 1_000_000


def test_unwrapper_handles_wrap() -> None:
    u = Unwrapper()
    assert u.update(WRAP - 10) == (WRAP - 10, 0)
    assert u.update(5) == (WRAP + 5, 15)


def test_backoff_grows_caps_and_jitters() -> None:
    b = Backoff(0.1, 2.0, 1.0, 0.25)
    delays = [b.next_s(0.5) for _ in range(8)]
    assert delays[:4] == pytest.approx([0.1, 0.2, 0.4, 0.8]) and max(delays) == 1.0
    assert Backoff(0.1, 2.0, 1.0, 0.25).next_s(0.0) == pytest.approx(0.075)
    b.reset()
    assert b.next_s(0.5) == pytest.approx(0.1)


def test_ingest_policy_gives_up_on_bad_or_silent_links_and_backs_off() -> None:
    p = IngestPolicy(3, 1.0, Backoff(0.1, 2.0, 1.0, 0.0))
    # An outage is reported once, with growing delays.
    delays = [p.open_failed(0.5) for _ in range(2)]
    assert [d for d, _ in delays] == pytest.approx([0.1, 0.2])
    assert [r for _, r in delays] == [True, False]
    states = [p.state]
    assert p.opened() is False  # the first link: no reconnect
    p.streaming(10.0)
    states.append(p.state)
    assert states == [Link.WAITING, Link.STREAMING] and not p.stalled(11.0) and p.stalled(11.01)
    # Bad scans in a row: reported at the 1st, given up at the 3rd; a good one resets.
    assert p.scan_bad() == (True, False) and p.scan_bad() == (False, False)
    p.scan_ok(10.5)
    assert p.scan_bad() == (True, False) and p.scan_bad() == (False, False)
    assert p.scan_bad() == (True, True)
    # A link that streamed is retried quickly; one that never did keeps backing off.
    assert p.lost(0.5) == pytest.approx(0.1) and p.state is Link.RECONNECTING
    assert p.opened() is True
    assert p.lost(0.5) == pytest.approx(0.2)


def test_stale_scans_before_the_handshake_are_skipped() -> None:
    link, client, counts = make()
    client.start(None, None, 1, 0)
    for _ in range(30):  # stream on, nobody reading: blocks pile up
        link.t += 0.01
        for blk in link.dev.poll(link.t):
            link.out += blk
    client2 = LidarClient(link, lambda k, n: counts.__setitem__(k, counts.get(k, 0) + n),
                          lambda: link.t)
    client2.start(None, None, 1, 0)
    assert counts["stale_blocks"] >= 2


def test_timeout_when_device_is_silent() -> None:
    class Silent:
        t = 0.0

        def write(self, data: bytes) -> None:
            pass

        def read(self, timeout_s: float) -> bytes:
            self.t += timeout_s
            return b""

        def close(self) -> None:
            pass

    s = Silent()
    with pytest.raises(LidarTimeout, match=r"no reply to SCIP2\.0"):
        LidarClient(s, lambda k, n: None, lambda: s.t).start(None, None, 1, 0)


def test_device_commands() -> None:
    dev = UrgDevice(UrgParams(), lambda _t: np.full(682, 1000, dtype=np.int64))
    dev.handle(b"SCIP2.0", 0)
    assert dev.handle(b"SCIP2.0", 0) == b"SCIP2.0\n0Ee\n\n"
    assert dev.handle(b"XX", 0) == b"XX\n0Ee\n\n"
    vv = scip.parse_info(scip.parse_reply(dev.handle(b"VV;ab", 0)[:-2], b"VV;ab"))
    assert vv["PROT"] == "SCIP 2.0"
    assert dev.handle(b"BM", 0) == b"BM\n00P\n\n"
    assert dev.handle(b"BM", 0) == b"BM\n02R\n\n"
    ii = scip.parse_info(scip.parse_reply(dev.handle(b"II", 0)[:-2], b"II"))
    assert ii["LASR"] == "ON"
    assert dev.handle(b"QT", 0) == b"QT\n00P\n\n" and not dev.laser_on
    assert dev.handle(b"TM0", 0) == b"TM0\n00P\n\n"
    tm1 = scip.parse_reply(dev.handle(b"TM1", 1.234)[:-2], b"TM1")
    assert scip.decode_value(scip.check_line(tm1.lines[0])) == 1234
    assert dev.handle(b"TM2", 0) == b"TM2\n00P\n\n"
    assert dev.handle(b"RS", 0) == b"RS\n00P\n\n"
    assert dev.handle(b"MD0044080001000", 0).split(b"\n")[1] == scip.with_sum(b"04")
    assert dev.handle(b"MD0100005001000", 0).split(b"\n")[1][:2] == b"05"
    assert dev.handle(b"MD00X4072501000", 0).split(b"\n")[1][:2] == b"01"


def test_md_count_cluster_interval() -> None:
    vals = np.arange(682, dtype=np.int64) + 100
    dev = UrgDevice(UrgParams(), lambda _t: vals)
    dev.handle(b"SCIP2.0", 0)
    assert dev.handle(b"MD0044005403102", 0) == b"MD0044005403102\n00P\n\n"
    blocks = [b for k in range(1, 8) for b in dev.poll(k * 0.1 + 1e-9)]
    assert len(blocks) == 2  # every second scan, two scans, then the stream ends
    s0 = scip.parse_scan(blocks[0][:-2], b"MD00440054031", 3)
    s1 = scip.parse_scan(blocks[1][:-2], b"MD00440054031", 3)
    assert (s0.remaining, s1.remaining) == (1, 0)
    assert s0.values.tolist() == [100, 103, 106, 109]  # clusters of 3 report their minimum
    assert dev.stream is None


def test_laser_params_reject_nonsense() -> None:
    with pytest.raises(scip.FormatError, match="lacks DMIN"):
        LaserParams.from_pp({"DMAX": "1"})
    with pytest.raises(scip.FormatError, match="non-integer"):
        LaserParams.from_pp({k: "x" for k in ("DMIN", "DMAX", "ARES", "AMIN", "AMAX", "AFRT",
                                               "SCAN")})


def test_world_format_errors_name_the_line() -> None:
    with pytest.raises(WorldError, match=r"w:2: unknown shape 'door'"):
        parse_world("wall 0 0 1 1\ndoor 1 2 3 4\n", "w")
    with pytest.raises(WorldError, match=r"w:1: box wants 4 numbers, got 3"):
        parse_world("box 1 2 3", "w")
    with pytest.raises(WorldError, match="not a number"):
        parse_world("circle 1 a 3", "w")


def test_raycast_hits_box_wall_and_circle() -> None:
    w: World = parse_world("wall 5 -10 5 10\nbox 0 3 2 2\ncircle -4 0 1\n")
    r = raycast(w, 0.0, 0.0, np.array([0.0, math.pi / 2, math.pi, -math.pi / 2]), 30.0)
    assert r[:3] == pytest.approx([5.0, 2.0, 3.0])
    assert np.isinf(r[3])


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=80))
def test_device_never_crashes_on_random_requests(line: bytes) -> None:
    dev = UrgDevice(UrgParams(), lambda _t: np.full(682, 1000, dtype=np.int64))
    dev.handle(b"SCIP2.0", 0)
    reply = dev.handle(line.replace(b"\n", b""), 0.0)
    assert reply.endswith(b"\n\n")


def test_tf_static_is_the_chair_mount() -> None:
    """The ingest's chair→laser transform is the [chair] geometry, and the safety monitor's
    check accepts exactly that (and not a transform 2 mm or 0.2° off)."""
    chair = ChairGeometry(laser_x_m=0.7, laser_y_m=-0.1, laser_z_m=0.5, laser_yaw_rad=0.3)
    tf = mount_transform(LidarConfig(), chair, 123)
    assert (tf.parent_frame_id, tf.child_frame_id, tf.stamp_ns) == ("chair", "laser", 123)
    t, q = tf.translation, tf.rotation
    assert (t.x, t.y, t.z) == (0.7, -0.1, 0.5)
    assert 2 * math.atan2(q.z, q.w) == pytest.approx(0.3)
    want = ((0.7, -0.1, 0.5), 0.3)
    assert mount_mismatch("chair", (t.x, t.y, t.z), (q.x, q.y, q.z, q.w), *want) == ""
    assert mount_mismatch("chair", (t.x + 0.002, t.y, t.z), (q.x, q.y, q.z, q.w), *want)
    off = mount_transform(LidarConfig(), ChairGeometry(laser_x_m=0.7, laser_y_m=-0.1,
                                                       laser_z_m=0.5, laser_yaw_rad=0.3035), 0)
    r = off.rotation
    assert "rotation differs" in mount_mismatch("chair", (t.x, t.y, t.z),
                                                (r.x, r.y, r.z, r.w), *want)
