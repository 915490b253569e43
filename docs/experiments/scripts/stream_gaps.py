"""(issue 12 / H46, session 18) The command stream's gaps through the stack: the corner goal of
tests/test_nav_system.py, CMD_VEL, odometry and e-stop stamps recorded; copy into tests/ and run
with `pytest -s -n 0`. Prints the longest gaps and when they came after the goal was sent."""
import math, time
import pytest
from tests.test_nav_system import STACK, world_config, shifted, L_WORLD, map_ready, drive_to, story, held
from tests.helpers import Recorder, client_session
from autochair_msgs import keys, Pose2D
pytestmark = pytest.mark.slow

def test_gap(stack_factory, hub, tmp_path, monkeypatch) -> None:
    world_config(tmp_path, monkeypatch, shifted(L_WORLD, -3.0))
    stack_factory(STACK)
    session = client_session(hub)
    try:
        cmd = Recorder(session, keys.CMD_VEL)
        odo = Recorder(session, keys.ODOM_SLOW)
        est = Recorder(session, keys.ESTOP_STATE)
        pid = Recorder(session, keys.PID_STATUS)
        health = Recorder(session, keys.HEALTH, keys.HEALTH.for_service("control"))
        map_ready(session)
        sent_ns = time.time_ns()
        states = drive_to(session, Pose2D(5.0, 3.0, math.radians(90)), 90)
        items = [(t, m) for t, m in cmd.items if m.stamp_ns >= sent_ns]
        st = [m.stamp_ns / 1e9 for _, m in items]
        rx = [t for t, _ in items]
        lat = [ (time.time_ns()/1e9 - time.monotonic()) + t - s for t, s in zip(rx, st)]
        gs = max((b - a for a, b in zip(st, st[1:])), default=0)
        gr = max((b - a for a, b in zip(rx, rx[1:])), default=0)
        h = health.latest()
        def mg(r):
            s2 = [m.stamp_ns / 1e9 for _, m in r.items if m.stamp_ns >= sent_ns]
            d = sorted(b - a for a, b in zip(s2, s2[1:]))
            return f"max {d[-1]*1e3:.0f} p99 {d[int(len(d)*0.99)]*1e3:.0f}"
        cs = [m.stamp_ns / 1e9 for _, m in cmd.items if m.stamp_ns >= sent_ns]
        big = sorted(((b - a, a - sent_ns / 1e9) for a, b in zip(cs, cs[1:])), reverse=True)[:5]
        print("BIG", [(round(g * 1e3), round(t, 2)) for g, t in big], "first cmd at", round(cs[0] - sent_ns / 1e9, 2))
        print(f"GAPS cmd {mg(cmd)} odom {mg(odo)} estop {mg(est)}")
        print(f"RESULT {states[-1].state} n={len(items)} max stamp gap {gs*1e3:.0f} ms, max rx gap {gr*1e3:.0f} ms, max latency {max(lat)*1e3:.0f} ms; overruns {dict((k,v) for k,v in h.counters.items() if 'overrun' in k)}; {held(pid, sent_ns)[:200]}")
    finally:
        session.close()
