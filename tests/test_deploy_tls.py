"""The chair's generated Zenoh profile over loopback: mutual TLS and default-deny access control.

A router session uses autochair.deploy.chair_zenoh (the generator of deploy/zenoh/chair.json5)
with certificates from `autochair certs`; laptops use deploy.laptop_zenoh.
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, cast

import msgspec
import pytest
import zenoh

from autochair import deploy
from autochair.commands.certs import make_all
from autochair.launcher import free_port
from autochair.runtime.client import deadline
from autochair.runtime.config import ConfigError
from autochair.runtime.session import open_session
from autochair_msgs import EStopAssert, EStopRelease, EStopReply, EStopState, Health, keys
from tests.helpers import stop_process
from tests.helpers import wait_for as wait  # fails the test with what it waited for


def wait_for(cond: Callable[[], bool], timeout: float = 10.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.02)
    return cond()


def open_json(obj: object) -> zenoh.Session:
    return open_session(zenoh.Config.from_json5(json.dumps(obj)))


class Chair:
    def __init__(self, certs: Path) -> None:
        self.certs = certs
        self.tcp, self.tls = free_port(), free_port()
        self.router = open_json(deploy.chair_zenoh(
            str(certs), [f"tcp/127.0.0.1:{self.tcp}", f"tls/127.0.0.1:{self.tls}"]))
        # A service: plain TCP on loopback, full access.
        self.service = open_json({"mode": "client",
                                  "connect": {"endpoints": [f"tcp/127.0.0.1:{self.tcp}"]},
                                  "scouting": {"multicast": {"enabled": False}}})

    def laptop(self, name: str) -> zenoh.Session:
        return open_json(deploy.laptop_zenoh(str(self.certs), name,
                                             f"tls/127.0.0.1:{self.tls}"))

    def close(self) -> None:
        self.service.close()
        self.router.close()


@pytest.fixture(scope="module")
def certs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("certs")
    make_all(out, [], [("alice", "drive"), ("bob", "view")], "tls/127.0.0.1:1")
    return out


@pytest.fixture()
def chair(certs: Path) -> Iterator[Chair]:
    c = Chair(certs)
    try:
        yield c
    finally:
        c.close()


def collect(session: zenoh.Session, key: str) -> list[bytes]:
    got: list[bytes] = []
    lock = threading.Lock()

    def on(sample: zenoh.Sample) -> None:
        with lock:
            got.append(sample.payload.to_bytes())

    session.declare_subscriber(key, on)
    return got


def test_remote_laptop_over_tls_receives_chair_data(chair: Chair) -> None:
    laptop = chair.laptop("bob")
    try:
        got = collect(laptop, keys.ODOM.key)
        pub = chair.service.declare_publisher(keys.ODOM.key)
        assert wait_for(lambda: (pub.put(b"pose"), bool(got))[1]), "no data over TLS"
        assert got[0] == b"pose"
    finally:
        laptop.close()


def test_client_without_certificate_is_refused(chair: Chair) -> None:
    cfg = deploy.laptop_zenoh(str(chair.certs), "alice", f"tls/127.0.0.1:{chair.tls}")
    tls = cfg["transport"]["link"]["tls"]  # type: ignore[index]
    del tls["connect_certificate"], tls["connect_private_key"]
    cfg["connect"] = {"endpoints": [f"tls/127.0.0.1:{chair.tls}"], "timeout_ms": 2000,
                      "exit_on_failure": True}
    with pytest.raises(ConfigError, match="cannot open a Zenoh session"):
        open_json(cfg).close()


def test_client_with_foreign_ca_is_refused(chair: Chair, tmp_path: Path) -> None:
    make_all(tmp_path, [], [("alice", "drive")], "tls/127.0.0.1:1")  # a different CA
    cfg = deploy.laptop_zenoh(str(tmp_path), "alice", f"tls/127.0.0.1:{chair.tls}")
    cfg["connect"] = {"endpoints": [f"tls/127.0.0.1:{chair.tls}"], "timeout_ms": 2000,
                      "exit_on_failure": True}
    with pytest.raises(ConfigError, match="cannot open a Zenoh session"):
        open_json(cfg).close()


@pytest.mark.parametrize("key", [keys.CMD_VEL.key, keys.TELEOP.key])
def test_view_identity_cannot_drive_but_drive_identity_can(chair: Chair, key: str) -> None:
    got = collect(chair.service, key)
    viewer, driver = chair.laptop("bob"), chair.laptop("alice")
    try:
        # Sanity: the viewer's link works (it sees data), so silence below is the ACL.
        seen = collect(viewer, keys.ODOM.key)
        pub = chair.service.declare_publisher(keys.ODOM.key)
        assert wait_for(lambda: (pub.put(b"x"), bool(seen))[1])
        drive_pub = driver.declare_publisher(key)
        assert wait_for(lambda: (drive_pub.put(b"drive"), b"drive" in got)[1]), \
            "drive identity could not put"
        view_pub = viewer.declare_publisher(key)
        for _ in range(20):
            view_pub.put(b"view")
            drive_pub.put(b"drive-after")
        assert wait_for(lambda: b"drive-after" in got)
        time.sleep(0.2)  # let any late view sample arrive before asserting its absence
        assert b"view" not in got
        # Nor may a viewer put on keys it could not drive with: the log, or health.
        log_got = collect(chair.service, keys.LOG.key)
        viewer.put(keys.LOG.key, b"spoof")
        driver.put(keys.LOG.key, b"spoof-d")
        time.sleep(0.3)
        assert log_got == []
    finally:
        viewer.close()
        driver.close()


def test_any_laptop_may_stop_the_chair(chair: Chair) -> None:
    got = collect(chair.service, keys.ESTOP_ASSERT.key)
    viewer = chair.laptop("bob")
    try:
        pub = viewer.declare_publisher(keys.ESTOP_ASSERT.key)
        assert wait_for(lambda: (pub.put(b"stop"), b"stop" in got)[1]), \
            "a view-only laptop could not latch the e-stop"
    finally:
        viewer.close()


def test_generated_profile_is_the_committed_one() -> None:
    committed = Path(__file__).parent.parent / "deploy" / "zenoh" / "chair.json5"
    body = "\n".join(ln for ln in committed.read_text().splitlines()
                     if not ln.startswith("//"))
    assert json.loads(body) == deploy.chair_zenoh()


def test_laptop_cannot_clear_an_estop_cause_but_a_service_can(chair: Chair,
                                                              tmp_path: Path) -> None:
    """The hazard: a laptop that may latch the e-stop must not clear the safety monitor's
    cause, neither on keys.ESTOP_CLEAR (denied by the hub's ACL) nor by `active=False` on
    keys.ESTOP_ASSERT (allowed, but only ever latches). Positive control: a services session's
    clear does clear it, then a drive laptop's release succeeds."""
    enc = msgspec.msgpack.Encoder()
    states: list[EStopState] = []
    health: list[Health] = []
    dec_state, dec_health = msgspec.msgpack.Decoder(EStopState), msgspec.msgpack.Decoder(Health)
    chair.service.declare_subscriber(keys.ESTOP_STATE.key, lambda s: states.append(
        dec_state.decode(s.payload.to_bytes())))
    chair.service.declare_subscriber(keys.HEALTH.for_service("estop"), lambda s: health.append(
        dec_health.decode(s.payload.to_bytes())))
    estop = subprocess.Popen(
        [sys.executable, "-m", "autochair.estop.node", "--connect",
         f"tcp/127.0.0.1:{chair.tcp}", "--set", f"state_file={tmp_path / 'estop.json'}"],
        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    viewer, driver = chair.laptop("bob"), chair.laptop("alice")

    def cause(source: str) -> bool | None:
        st = states[-1] if states else None
        return next((c.active for c in st.causes if c.source == source), None) if st else None

    def counter(name: str) -> int:
        return health[-1].counters.get(name, 0) if health else -1

    def release() -> EStopReply:
        replies = list(driver.get(keys.ESTOP_RELEASE.key, timeout=3.0,
                                  attachment=deadline(time.time_ns(), 3.0),
                                  payload=enc.encode(EStopRelease(by="alice"))))
        oks = [r.ok for r in replies if r.ok is not None]
        assert len(oks) == 1, replies
        return msgspec.msgpack.decode(oks[0].payload.to_bytes(), type=EStopReply)

    def msg(source: str, active: bool) -> bytes:
        return enc.encode(EStopAssert(stamp_ns=time.time_ns(), source=source, reason="x",
                                      active=active))

    try:
        service_assert = chair.service.declare_publisher(keys.ESTOP_ASSERT.key)
        held = EStopAssert(stamp_ns=time.time_ns(), source="safety", reason="imminent collision")
        wait(lambda: (service_assert.put(enc.encode(held)), cause("safety"))[1], 15,
             "the e-stop holding the safety cause", interval=0.1)
        view_clear = viewer.declare_publisher(keys.ESTOP_CLEAR.key)
        view_assert = viewer.declare_publisher(keys.ESTOP_ASSERT.key)
        # The viewer knows the e-stop subscribes to both keys: its puts are sent, not dropped
        # for want of subscribers; what stops the clear is the hub.
        for pub in (view_clear, view_assert):
            def matching(p: zenoh.Publisher = pub) -> bool:
                return bool(cast(Any, p.matching_status).matching)
            wait(matching, 5, "viewer sees the subscriber")
        for _ in range(5):
            view_clear.put(msg("safety", False))
            view_assert.put(msg("safety", False))
        view_assert.put(msg("bob-marker", False))  # same link, after the spoofs
        wait(lambda: cause("bob-marker") is False, 5, "the viewer's press (it may stop)")
        assert cause("safety") is True, "a laptop cleared the safety monitor's cause"
        wait(lambda: counter("assert_msgs") >= 7, 5, "the e-stop counting every assert")
        assert counter("clear_msgs") == 0  # the spoofed clears never reached it
        reply = release()
        assert not reply.ok and reply.latched and "safety: imminent collision" in reply.error
        # Positive control: a service on the chair (plain TCP) clears it; the release then works.
        chair.service.put(keys.ESTOP_CLEAR.key, msg("safety", False))
        wait(lambda: cause("safety") is False, 5, "the service's clear applied")
        wait(lambda: counter("clear_msgs") >= 1, 5, "the e-stop counting the clear")
        reply = release()
        assert reply.ok and not reply.latched, reply.error
        wait(lambda: states and not states[-1].latched, 5, "released state")
        assert estop.poll() is None
    finally:
        viewer.close()
        driver.close()
        stop_process(estop)


def test_acl_gives_no_laptop_the_clear_key() -> None:
    """Static check of the generated ACL: no laptop policy has an ingress put on any key
    expression that intersects keys.ESTOP_CLEAR; control: the assert key is allowed."""
    acl = cast(dict[str, Any], deploy.chair_zenoh()["access_control"])
    rules = {r["id"]: r for r in acl["rules"]}
    clear, press = zenoh.KeyExpr(keys.ESTOP_CLEAR.key), zenoh.KeyExpr(keys.ESTOP_ASSERT.key)

    def puts(policy: dict[str, Any], key: zenoh.KeyExpr) -> bool:
        return any("ingress" in rules[r]["flows"] and "put" in rules[r]["messages"]
                   and any(key.intersects(zenoh.KeyExpr(k)) for k in rules[r]["key_exprs"])
                   for r in policy["rules"])

    laptops = [p for p in acl["policies"] if p["id"] != "services"]
    assert {p["id"] for p in laptops} == {"drive", "view"}
    for policy in laptops:
        assert not puts(policy, clear), policy["id"]
        assert puts(policy, press), policy["id"]
    (services,) = [p for p in acl["policies"] if p["id"] == "services"]
    assert puts(services, clear)
