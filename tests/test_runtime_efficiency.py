"""The runtime's cheaper paths (issue 11): `Node.latest` (newest message when asked, no Python
thread per sample), `Node.queued` (every message since the last ask, likewise), `Node.beat` (a
loop on a thread of its own, watched like `every`) and the per-process Zenoh mode
(`--zenoh-mode client`: one link, to the hub)."""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh

from autochair.launcher import free_port
from autochair.processes import PROCESSES
from autochair.runtime import Node, ZenohSettings
from autochair.runtime.client import Publisher
from autochair.runtime.node import zenoh_settings
from autochair.runtime.session import open_session
from autochair_msgs import GroundTruth, keys
from tests.helpers import wait_for


def truth(x: float) -> GroundTruth:
    return GroundTruth(stamp_ns=time.time_ns(), sim_time_s=x, x_m=x, y_m=0.0, yaw_rad=0.0,
                       v_mps=0.0, omega_radps=0.0, longitudinal_v=2.5, angular_v=2.5)


@pytest.fixture
def node_and_peer() -> Iterator[tuple[Node, Publisher, zenoh.Session]]:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    node = Node("efftest", ZenohSettings(connect=[], listen=[endpoint]))
    peer = open_session(ZenohSettings(connect=[endpoint], listen=[]))
    pub = Publisher(peer, keys.SIM_TRUTH, express=True)
    try:
        yield node, pub, peer
    finally:
        pub.undeclare()
        peer.close()
        node.close()


def test_latest_gives_the_newest_message_and_keeps_it_over_a_bad_one(
        node_and_peer: tuple[Node, Publisher, zenoh.Session]) -> None:
    node, pub, _ = node_and_peer
    get = node.latest(keys.SIM_TRUTH)
    assert get() is None  # nothing yet
    # Positive control: a message arrives and is returned.

    def first() -> GroundTruth | None:
        pub.put(truth(1.0))  # again until the peers are linked
        return get()

    wait_for(first, 10, "the first message")
    for x in (2.0, 3.0, 4.0):
        pub.put(truth(x))
    wait_for(lambda: (m := get()) is not None and m.x_m == 4.0, 5, "the newest message")
    got = get()
    assert got is not None and got.x_m == 4.0  # asked again: still the newest, not None
    pub.put_raw(b"\xc1 not msgpack")
    counter = f"decode_errors:{keys.SIM_TRUTH.key}"
    wait_for(lambda: (get(), node.health.counters.get(counter, 0))[1] >= 1, 5,
             "the malformed payload counted")
    got = get()
    assert got is not None and got.x_m == 4.0


def test_queued_gives_every_message_since_the_last_ask_in_order(
        node_and_peer: tuple[Node, Publisher, zenoh.Session]) -> None:
    node, pub, _ = node_and_peer
    take = node.queued(keys.SIM_TRUTH, 8)
    assert take() == []  # nothing yet
    got: list[float] = []

    def received() -> list[float]:
        got.extend(m.x_m for m in take())
        return got

    def linked() -> bool:  # positive control: a message arrives and is returned
        pub.put(truth(-1.0))  # again until the peers are linked
        return bool(received())

    wait_for(linked, 10, "the first message")
    for x in (1.0, 2.0, 3.0):
        pub.put(truth(x))
    wait_for(lambda: received()[-1:] == [3.0], 5, "the three messages")
    assert [x for x in got if x > 0] == [1.0, 2.0, 3.0]  # each once, oldest first
    assert take() == []  # asked again: nothing new
    pub.put_raw(b"\xc1 not msgpack")
    pub.put(truth(4.0))
    got.clear()
    wait_for(lambda: received() == [4.0], 5, "the good message after a malformed one")
    assert node.health.counters.get(f"decode_errors:{keys.SIM_TRUTH.key}", 0) == 1


def test_beat_is_watched_like_a_rate_loop_and_pause_exempts_it() -> None:
    node = Node("efftest2", ZenohSettings(connect=[], listen=["tcp/127.0.0.1:0"]))
    try:
        beat = node.beat("reader", 0.01)
        bound = max(node.stale.watchdog_s, 0.03)
        now = time.monotonic()
        beat()
        assert not [x for x in node.liveness.late(time.monotonic()) if x.what == "loop reader"]
        late = node.liveness.late(now + bound + 0.5)  # no beat for longer than the bound
        assert [x.what for x in late if x.what == "loop reader"] == ["loop reader"]
        beat.pause()
        assert not [x for x in node.liveness.late(now + 100) if x.what == "loop reader"]
        beat()  # beating again: watched again
        late = node.liveness.late(time.monotonic() + bound + 0.5)
        assert [x.what for x in late if x.what == "loop reader"] == ["loop reader"]
    finally:
        node.close()


def test_zenoh_mode_from_the_command_line() -> None:
    hub = "tcp/127.0.0.1:7999"
    assert zenoh_settings(None, hub, None).mode == "peer"  # the config's default
    client = zenoh_settings(None, hub, "client")
    assert client.mode == "client" and client.listen == [] and client.connect == [hub]
    peer = zenoh_settings(None, hub, "peer")
    assert peer.mode == "peer" and peer.listen  # a peer listens, for direct links


def test_the_drive_chain_and_the_safety_path_stay_peers() -> None:
    """Clients relay through the hub; the 100 Hz chain, the recorder, the e-stop and the safety
    monitor talk directly."""
    mode = {p.name: ("client" if "--zenoh-mode" in p.args
                     and p.args[p.args.index("--zenoh-mode") + 1] == "client" else "peer")
            for p in PROCESSES}
    for name in ("gateway", "odometry", "pid", "logger", "estop", "safety"):
        assert mode[name] == "peer", name
    assert mode["lidar-sim"] == "client"  # positive control: the list does make clients


def test_sessions_use_no_shared_memory_and_large_samples_still_arrive(tmp_path: Path) -> None:
    """Shared memory is off in every session we configure (zenoh's default is on: it copies
    puts over 3 kB into a shared segment and runs watchdog threads in each process), also over
    a config file; a map-sized sample still arrives whole, over the socket."""
    def shm(cfg: zenoh.Config) -> bool:
        return bool(json.loads(cfg.get_json("transport/shared_memory/enabled")))

    assert shm(zenoh.Config())  # positive control: zenoh's own default
    base = tmp_path / "zenoh.json5"
    base.write_text('{ transport: { shared_memory: { enabled: true } } }')
    for settings in (ZenohSettings(), ZenohSettings(mode="client", listen=[]),
                     ZenohSettings(mode="router"), ZenohSettings(config_file=str(base))):
        assert not shm(settings.to_zenoh()), settings
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    a = open_session(ZenohSettings(connect=[], listen=[endpoint]))
    b = open_session(ZenohSettings(connect=[endpoint], listen=[]))
    got: list[bytes] = []
    sub = a.declare_subscriber("efftest/big", lambda s: got.append(s.payload.to_bytes()))
    payload = bytes(range(256)) * 1000  # 256 kB, a whole map's size
    try:
        wait_for(lambda: b.put("efftest/big", payload) or got, 10, "a large sample")
        assert got[0] == payload
    finally:
        sub.undeclare()
        b.close()
        a.close()
