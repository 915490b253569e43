"""supervisord with the generated config: a hung service is killed by `autochair-watchdog`
and restarted by supervisord's autorestart."""

from __future__ import annotations

import signal
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import msgspec
import psutil
import pytest

from autochair.runtime.client import Publisher, alive_services, open_client
from autochair_msgs import EncoderSample, keys
from tests.helpers import supervised, supervisorctl, wait_for

BIN = Path(sys.executable).parent
pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not (BIN / "supervisord").exists(),
                                 reason="pip supervisor is not installed in this venv"),
              pytest.mark.skipif(not (BIN / "autochair-watchdog").exists(),
                                 reason="reinstall the package: `pip install -e .` "
                                        "(autochair-watchdog console script missing)")]
ENC = msgspec.msgpack.Encoder()


@pytest.fixture()
def stack(tmp_path: Path) -> Iterator[tuple[Path, str, Path]]:
    with supervised(tmp_path, ["router", "odometry"]) as (conf, hub):
        yield conf, hub, tmp_path / "odometry.log"


def service_pid(conf: Path) -> tuple[int, int] | None:
    """(wrapper pid, odometry pid) under supervisord, once both exist."""
    try:
        wrapper = int(supervisorctl(conf, "pid", "odometry"))
        children = psutil.Process(wrapper).children()
    except (ValueError, psutil.Error):
        return None
    return (wrapper, children[0].pid) if wrapper and children else None


def test_supervisord_restarts_a_hung_service(stack: tuple[Path, str, Path]) -> None:
    conf, hub, log = stack
    assert "autochair-watchdog --timeout 1.5 -- " in conf.read_text()
    session = open_client(hub, timeout_ms=15000)
    seq = 0

    def feed(pub: Publisher) -> None:
        """Encoder samples, as the gateway sends them: the service's callbacks run."""
        nonlocal seq
        seq += 1
        pub.put(EncoderSample(stamp_ns=time.time_ns(), seq=seq & 0xFFFF,
                              mcu_time_us=seq * 10000, left_counts=seq, right_counts=seq,
                              status=0))

    try:
        pub = Publisher(session, keys.ENCODERS)
        wait_for(lambda: "odometry" in alive_services(session, 0.5), 60, "odometry alive")
        old = wait_for(lambda: service_pid(conf), 10, "the wrapper and its child")
        # the watchdog has armed: the service pinged (its log has no hang yet)
        t_hang = time.monotonic()
        psutil.Process(old[0]).send_signal(signal.SIGUSR2)  # forwarded by the wrapper

        def hung_line() -> str | None:
            feed(pub)
            text = log.read_text() if log.exists() else ""
            return next((ln for ln in text.splitlines() if "autochair-watchdog:" in ln
                         and " hung: " in ln), None)

        line = wait_for(hung_line, 10, "autochair-watchdog reporting the hang")
        detect_s = time.monotonic() - t_hang

        def restarted() -> tuple[int, int] | None:
            feed(pub)
            now = service_pid(conf)
            return now if now and now[1] != old[1] and now[0] != old[0] else None

        new = wait_for(restarted, 20, "a new odometry process")
        t_new = time.monotonic() - t_hang
        wait_for(lambda: "odometry" in alive_services(session, 0.5), 20, "odometry alive again")
        t_alive = time.monotonic() - t_hang
        print(f"\nsupervisord: hang detected after {detect_s:.2f} s ({line.strip()}); new "
              f"process after {t_new:.2f} s (pid {old[1]} → {new[1]}); alive after "
              f"{t_alive:.2f} s")
        assert "watchdog trigger: hung: callback autochair/chair/encoders" in line
        assert not psutil.pid_exists(old[1]) or \
            psutil.Process(old[1]).status() == psutil.STATUS_ZOMBIE
        assert detect_s < 2.0 + 0.1  # + this loop's log polling
        assert "RUNNING" in supervisorctl(conf, "status", "router")
    finally:
        session.close()
