"""Namespaces: every key of one chair under its name (Zenoh's own session `namespace`), so two
chairs, or a chair and a replay, share one hub without seeing each other's keys.

What Zenoh 1.x does with it, checked here in the installed version: the namespace is prefixed
to every key expression a session declares or sends (puts, subscriptions, queries, queryables,
replies, liveliness tokens and queries) and stripped from what it receives; a session without a
namespace sees chair NAME's keys as NAME/autochair/...; the hub's ACL sees the prefixed keys."""

from __future__ import annotations

import argparse
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
from autochair.cli import CliError
from autochair.cli import main as cli_main
from autochair.commands.certs import make_all
from autochair.commands.replay import target_namespace
from autochair.launcher import free_port
from autochair.runtime import Node
from autochair.runtime.client import (
    RequestError,
    alive_chairs,
    alive_services,
    chair_of,
    open_client,
    request,
    subscribe,
    subscribe_chairs,
)
from autochair.runtime.config import (
    ENV_CHAIR,
    ENV_CONFIG,
    ConfigError,
    ZenohSettings,
    chair_in,
    check_chair,
    load_zenoh,
)
from autochair.runtime.session import open_session
from autochair_msgs import Empty, GoalStatus, Health, Odometry, keys
from tests.helpers import wait_for

ENC = msgspec.msgpack.Encoder()


# --- names and configuration ---------------------------------------------------------------------
def test_chair_names_are_one_word_and_errors_name_their_source(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    for good in ("chair-2", "lab_A", "7"):
        assert check_chair(good) == good
    for bad in ("", "a/b", "*", "**", "a b", "chaise-é", "a$b", "a?", "x/"):
        with pytest.raises(ConfigError, match="--chair: a chair name is one word") as e:
            check_chair(bad)
        assert "\n" not in str(e.value)
    config = tmp_path / "chair.toml"
    config.write_text('[zenoh]\nnamespace = "from-file"\n')
    monkeypatch.delenv(ENV_CHAIR, raising=False)
    assert load_zenoh(str(config)).namespace == "from-file"
    assert load_zenoh().namespace == ""  # none, as before
    monkeypatch.setenv(ENV_CHAIR, "from-env")
    assert load_zenoh(str(config)).namespace == "from-env"
    assert load_zenoh(str(config), chair="from-arg").namespace == "from-arg"
    assert load_zenoh(str(config), chair="").namespace == ""  # explicitly none
    monkeypatch.setenv(ENV_CHAIR, "a/b")
    with pytest.raises(ConfigError, match=r"^\$AUTOCHAIR_CHAIR: a chair name"):
        load_zenoh(str(config))
    monkeypatch.delenv(ENV_CHAIR)
    config.write_text('[zenoh]\nnamespace = "a/b"\n')
    with pytest.raises(ConfigError, match=r"^\[zenoh\] namespace: a chair name"):
        load_zenoh(str(config))
    # What the launcher computes for its children, from their environment.
    assert chair_in({ENV_CHAIR: "x"}) == "x"
    config.write_text('[zenoh]\nnamespace = "y"\n')
    assert chair_in({ENV_CONFIG: str(config)}) == "y"
    assert json.loads(ZenohSettings(namespace="x").to_zenoh().get_json("namespace")) == "x"


def test_the_chair_of_a_key_seen_from_outside() -> None:
    assert chair_of("autochair/alive/pid", keys.ALIVE) == ""
    assert chair_of("lab-2/autochair/alive/pid", keys.ALIVE) == "lab-2"
    assert chair_of("autochair/autochair/alive/pid", keys.ALIVE) == "autochair"
    assert chair_of("x/autochair/health/gateway", keys.HEALTH.key) == "x"


def test_cli_chair_errors_are_one_line(capsys: pytest.CaptureFixture[str],
                                       monkeypatch: pytest.MonkeyPatch) -> None:
    hub = f"tcp/127.0.0.1:{free_port()}"  # never reached: the name is checked first
    for argv, needle in [
        (["status", "--chair", "a/b", "--connect", hub], "--chair: a chair name"),
        (["drive", "0", "0", "--chair", "*", "--connect", hub], "--chair: a chair name"),
        (["up", "--sim", "--chair", "two words"], "--chair: a chair name"),
        (["replay", "x.mcap", "--namespace", "a/b"], "--namespace: a chair name"),
        (["replay", "x.mcap", "--namespace", "a", "--chair", "b"], "disagree"),
    ]:
        assert cli_main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and needle in err[0], (argv, err)
    monkeypatch.setenv(ENV_CHAIR, "a b")
    assert cli_main(["status", "--connect", hub]) == 2
    assert "$AUTOCHAIR_CHAIR: a chair name" in capsys.readouterr().err


def test_replay_publishes_into_its_own_namespace_unless_told() -> None:
    def ns(namespace: str | None, chair: str | None) -> str:
        return target_namespace(argparse.Namespace(namespace=namespace, chair=chair))

    assert ns(None, None) == "replay"  # never $AUTOCHAIR_CHAIR: only what is on its line
    assert ns("lab", None) == ns(None, "lab") == ns("lab", "lab") == "lab"
    assert ns("", None) == ""  # the keys of a chair without a namespace
    with pytest.raises(CliError, match="disagree"):
        ns("a", "b")


# --- Zenoh's namespace on one hub ----------------------------------------------------------------
@pytest.fixture
def hub() -> Iterator[str]:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = open_session(ZenohSettings(mode="router", connect=[], listen=[endpoint]))
    try:
        yield endpoint
    finally:
        router.close()


class Got:
    """Messages (or keys) arriving on a Zenoh thread."""

    def __init__(self) -> None:
        self.items: list[Any] = []
        self._lock = threading.Lock()

    def add(self, item: Any) -> None:
        with self._lock:
            self.items.append(item)

    def snapshot(self) -> list[Any]:
        with self._lock:
            return list(self.items)


def test_a_namespace_covers_every_kind_of_key_and_keeps_chairs_apart(hub: str) -> None:
    nodes = {c: Node("pid", ZenohSettings(connect=[hub], namespace=c)) for c in ("ca", "cb")}
    sessions = {c: open_client(hub, chair=c) for c in ("ca", "cb", "")}
    try:
        def goal_of(goal_id: int) -> Callable[[Empty], GoalStatus]:
            return lambda _req: GoalStatus(stamp_ns=time.time_ns(), goal_id=goal_id,
                                           state="idle")

        for goal_id, c in enumerate(("ca", "cb"), start=1):
            nodes[c].serve(keys.GOAL_GET, goal_of(goal_id))
        ca, cb, plain = sessions["ca"], sessions["cb"], sessions[""]
        # Liveliness: each chair sees its own token, as autochair/alive/pid.
        assert wait_for(lambda: alive_services(ca), 5, "ca's token") == {"pid"}
        assert alive_services(cb) == {"pid"} and alive_services(plain) == set()
        assert alive_chairs(plain) == {"ca": {"pid"}, "cb": {"pid"}}
        assert alive_chairs(ca) == {"": {"pid"}}
        # Queries and queryables: each chair's own service answers, nobody un-namespaced.
        assert request(ca, keys.GOAL_GET, Empty(), GoalStatus).goal_id == 1
        assert request(cb, keys.GOAL_GET, Empty(), GoalStatus).goal_id == 2
        with pytest.raises(RequestError, match="no reply"):
            request(plain, keys.GOAL_GET, Empty(), GoalStatus, timeout_s=0.3)
        # Puts and subscriptions.
        in_a, in_b, raw = Got(), Got(), Got()
        subscribe(ca, keys.ODOM, in_a.add)
        subscribe(cb, keys.ODOM, in_b.add)
        plain.declare_subscriber(f"**/{keys.ODOM.key}", lambda s: raw.add(str(s.key_expr)))
        pub_a, pub_b = nodes["ca"].publisher(keys.ODOM), nodes["cb"].publisher(keys.ODOM)

        def odom(x: float) -> Odometry:
            return Odometry(stamp_ns=time.time_ns(), x_m=x, y_m=0, yaw_rad=0, v_mps=0,
                            omega_radps=0)

        def both_heard() -> bool:
            pub_a.put(odom(1.0))
            pub_b.put(odom(2.0))
            return bool(in_a.snapshot() and in_b.snapshot())

        wait_for(both_heard, 5, "each chair's odometry")
        wait_for(lambda: {"ca/autochair/odom", "cb/autochair/odom"} <= set(raw.snapshot()), 5,
                 "both chairs seen from outside, under their names")
        assert {m.x_m for m in in_a.snapshot()} == {1.0}
        assert {m.x_m for m in in_b.snapshot()} == {2.0}
        assert set(raw.snapshot()) == {"ca/autochair/odom", "cb/autochair/odom"}
        # Health of every chair, from outside, tagged with its chair.
        health = Got()
        subscribe_chairs(plain, keys.HEALTH, lambda c, h: health.add((c, cast(Health, h)
                                                                      .service)))
        def both_healths() -> bool:
            for n in nodes.values():
                n.publish_health()
            return {("ca", "pid"), ("cb", "pid")} <= set(health.snapshot())

        wait_for(both_healths, 5, "health of both chairs")
    finally:
        for s in sessions.values():
            s.close()
        for n in nodes.values():
            n.close()


# --- the hub's access control ---------------------------------------------------------------------
@pytest.fixture(scope="module")
def certs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("certs")
    make_all(out, [], [("alice", "drive"), ("bob", "view")], "tls/127.0.0.1:1")
    return out


def open_json(obj: object) -> zenoh.Session:
    return open_session(zenoh.Config.from_json5(json.dumps(obj)))


def test_acl_sees_namespaced_keys_and_holds_in_every_chair(certs: Path) -> None:
    """The hub's ACL is checked on the keys as they cross it, i.e. WITH the namespace: the
    generated rules name `autochair/...` and `*/autochair/...`, so a laptop in chair NAME
    (`--chair NAME`) keeps exactly its role: drive or view, stop always, clear never."""
    tcp, tls = free_port(), free_port()
    router = open_json(deploy.chair_zenoh(
        str(certs), [f"tcp/127.0.0.1:{tcp}", f"tls/127.0.0.1:{tls}"]))
    service = open_client(f"tcp/127.0.0.1:{tcp}", chair="ca")  # a service of chair ca
    plain_service = open_client(f"tcp/127.0.0.1:{tcp}", chair="")

    def laptop(name: str, chair: str | None) -> zenoh.Session:
        profile = deploy.laptop_zenoh(str(certs), name, f"tls/127.0.0.1:{tls}")
        if chair:
            profile["namespace"] = chair
        return open_json(profile)

    alice, bob, outside = laptop("alice", "ca"), laptop("bob", "ca"), laptop("bob", None)
    tokens = [service.liveliness().declare_token(f"{keys.PREFIX}/alive/pid"),
              plain_service.liveliness().declare_token(f"{keys.PREFIX}/alive/gateway")]
    try:
        got = {k: Got() for k in (keys.CMD_VEL.key, keys.ESTOP_CLEAR.key,
                                  keys.ESTOP_ASSERT.key)}
        def keep(into: Got) -> Callable[[zenoh.Sample], None]:
            return lambda sample: into.add(sample.payload.to_bytes())

        for k, g in got.items():
            service.declare_subscriber(k, keep(g))
        seen = Got()
        bob.declare_subscriber(keys.ODOM.key, lambda s: seen.add(s.payload.to_bytes()))
        odom = service.declare_publisher(keys.ODOM.key)
        def viewer_sees() -> bool:
            odom.put(b"o")
            return bool(seen.snapshot())

        wait_for(viewer_sees, 10, "a viewer in chair ca sees its data (so silence below is "
                 "the ACL)")

        def put_all() -> bool:
            for who in (alice, bob):
                name = b"alice" if who is alice else b"bob"
                who.put(keys.CMD_VEL.key, name)
                who.put(keys.ESTOP_CLEAR.key, name)
            bob.put(keys.ESTOP_ASSERT.key, b"bob")
            return bool(got[keys.CMD_VEL.key].snapshot()
                        and got[keys.ESTOP_ASSERT.key].snapshot())

        wait_for(put_all, 10, "the driver's command and the viewer's stop in chair ca")
        for _ in range(10):
            put_all()
        wait_for(lambda: len(got[keys.ESTOP_ASSERT.key].snapshot()) >= 11, 5, "every stop")
        assert set(got[keys.CMD_VEL.key].snapshot()) == {b"alice"}  # a viewer cannot drive
        assert got[keys.ESTOP_CLEAR.key].snapshot() == []  # nobody clears from a laptop
        # `autochair status` from a laptop without --chair: both chairs, through the ACL.
        assert alive_chairs(outside) == {"": {"gateway"}, "ca": {"pid"}}
        assert alive_chairs(bob) == {"": {"pid"}}
    finally:
        for t in tokens:
            t.undeclare()
        for s in (alice, bob, outside, service, plain_service, router):
            s.close()


def test_acl_gives_no_laptop_the_clear_key_in_any_chair() -> None:
    acl = cast(dict[str, Any], deploy.chair_zenoh()["access_control"])
    rules = {r["id"]: r for r in acl["rules"]}
    for key in (keys.ESTOP_CLEAR.key, f"ca/{keys.ESTOP_CLEAR.key}", f"*/{keys.ESTOP_CLEAR.key}"):
        clear = zenoh.KeyExpr(key)
        for policy in acl["policies"]:
            if policy["id"] == "services":
                continue
            for r in policy["rules"]:
                if "ingress" in rules[r]["flows"] and "put" in rules[r]["messages"]:
                    assert not any(clear.intersects(zenoh.KeyExpr(k))
                                   for k in rules[r]["key_exprs"]), (key, r)
    assert "*/autochair/estop/assert" in rules["laptop-stop"]["key_exprs"]


# --- replay ---------------------------------------------------------------------------------------
def write_recording(path: Path) -> list[tuple[str, bytes]]:
    from autochair.logger.writer import LoggerConfig, Recorder
    from tests.logger_samples import T0, samples

    rec = Recorder(LoggerConfig(path=str(path)), T0, 0.0)
    sent: list[tuple[str, bytes]] = []
    for i in range(5):
        for key, msg in samples(i).items():
            payload = ENC.encode(msg)
            assert rec.write(key, payload, T0 + i * 20_000_000)
            sent.append((key, payload))
    rec.finish()
    return sent


@pytest.mark.slow
def test_replay_never_reaches_a_chair_unless_asked_and_then_not_a_live_one(
        hub: str, tmp_path: Path) -> None:
    path = tmp_path / "drive.mcap"
    sent = write_recording(path)
    live = open_client(hub, chair="ca")  # chair ca with a live PID (its token)
    watcher = open_client(hub, chair="")
    token = live.liveliness().declare_token(f"{keys.PREFIX}/alive/pid")
    try:
        in_ca, everywhere = Got(), Got()
        live.declare_subscriber(f"{keys.PREFIX}/**", lambda s: in_ca.add(str(s.key_expr)))
        for expr in (f"{keys.PREFIX}/**", f"*/{keys.PREFIX}/**"):
            watcher.declare_subscriber(expr, lambda s: everywhere.add(str(s.key_expr)))

        def replay(*extra: str) -> subprocess.CompletedProcess[str]:
            return subprocess.run(
                [sys.executable, "-m", "autochair.cli", "replay", str(path), "--connect", hub,
                 "--quiet", "--rate", "4", *extra],
                capture_output=True, text=True, timeout=30, stdin=subprocess.DEVNULL)

        ok = replay()  # by default: its own namespace, next to the live chair
        assert ok.returncode == 0, ok.stderr
        wait_for(lambda: len(everywhere.snapshot()) >= len(sent), 10, "the replay")
        assert everywhere.snapshot() == [f"replay/{k}" for k, _ in sent]
        refused = replay("--chair", "ca")  # explicitly into the live chair: refused
        assert refused.returncode == 2
        line = refused.stderr.strip()
        assert line.startswith("autochair replay: error: drive-chain service alive"), line
        assert "namespace 'ca'" in line and "\n" not in line
        other = replay("--namespace", "cb")  # another chair's namespace, no drive chain there
        assert other.returncode == 0, other.stderr
        wait_for(lambda: len(everywhere.snapshot()) >= 2 * len(sent), 10, "the replay into cb")
        assert in_ca.snapshot() == []  # chair ca got nothing at all
    finally:
        token.undeclare()
        live.close()
        watcher.close()
