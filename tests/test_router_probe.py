"""The hub's watchdog probe pings only while the hub answers its own queryable through a
client link (router/node.py)."""

from __future__ import annotations

import socket
import threading

import pytest

from autochair.launcher import free_port
from autochair.router.node import PROBE_PERIOD_S, probe_endpoint, probe_loop
from autochair.runtime.client import answer_hub_probe, hub_answers
from autochair.runtime.config import ZenohSettings
from autochair.runtime.session import client_settings, open_session
from autochair.runtime.watchdog import Notifier, parse
from tests.helpers import wait_for


def test_probe_endpoint_is_the_first_tcp_listener_on_loopback() -> None:
    assert probe_endpoint(["tls/0.0.0.0:7448", "tcp/0.0.0.0:7447"]) == "tcp/127.0.0.1:7447"
    assert probe_endpoint(["tcp/127.0.0.1:9"]) == "tcp/127.0.0.1:9"
    assert probe_endpoint(["tls/0.0.0.0:7448"]) is None


def test_the_probe_pings_while_the_hub_answers_and_stops_when_it_does_not() -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    hub = open_session(ZenohSettings(mode="router", listen=[endpoint], connect=[]))
    queryable = answer_hub_probe(hub)
    client = open_session(client_settings(endpoint))
    supervisor = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    supervisor.bind(f"\0autochair-test-probe-{free_port()}")
    supervisor.settimeout(2.0)  # the first answer comes within a period
    notifier = Notifier("@" + supervisor.getsockname()[1:].decode())
    stop = threading.Event()
    thread = threading.Thread(target=probe_loop, args=(client, notifier, stop), daemon=True)
    thread.start()
    try:
        # Positive control: READY, then a ping every period while the hub answers.
        assert parse(supervisor.recv(256)) == {"READY": "1", "WATCHDOG": "1"}
        assert parse(supervisor.recv(256)) == {"WATCHDOG": "1"}
        queryable.undeclare()  # the hub runs but does not answer: as if its routing were stuck
        wait_for(lambda: not hub_answers(client, 0.5), 5, "the probe to go unanswered")
        # At most the probes already answered arrive; then 4 periods and more of silence.
        supervisor.settimeout(4 * PROBE_PERIOD_S)
        late = 0
        with pytest.raises(TimeoutError):
            while late < 3:
                supervisor.recv(256)
                late += 1
    finally:
        stop.set()
        thread.join(3)
        notifier.close()
        supervisor.close()
        client.close()
        hub.close()
