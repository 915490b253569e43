"""People tracked on the live stack: the simulated URG-04LX sees a person cross the corridor
ahead of the parked chair (crossing.world: x = 4 m, y from −3 to 3 m and back, 0.8 m/s); the
control service reports them (autochair/people) on that line at that speed, and nothing else
once the live map has come. (The lidar simulator walks people on its own clock, so the check
is the person's line and speed, not the phase along it.)"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import pytest

from autochair.launcher import Launcher
from autochair.runtime.client import request
from autochair.sim.world import DEFAULT_WORLD
from autochair_msgs import GoalReply, GoalRequest, Pose2D, keys
from tests.helpers import Recorder, client_session, wait_for
from tests.test_nav_system import (
    L_WORLD,
    drive_to,
    held,
    map_ready,
    shifted,
    story,
    world_config,
)
from tests.test_nav_system import STACK as NAV_STACK

pytestmark = pytest.mark.slow

STACK = ["sim", "gateway", "odometry", "lidar-sim", "lidar", "mapping", "control"]
CROSSING = (DEFAULT_WORLD.parent / "crossing.world").read_text()


def test_a_person_crossing_is_tracked_on_their_line_at_their_speed(
        stack_factory: Callable[..., Launcher], hub: str, tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """With the corridor closed 1.5 m behind the person's line. Without that wall the parked
    chair's laser (5.6 m) never sees the floor under the middle of the line (its beams there
    return nothing from the far end, 12 m), and never-seen cells count as the map's, so the
    person was tracked only near the side walls, for about 1 s a crossing, mostly at 0.2-0.5
    m/s: 0-4 reports in 10 s met the check below (measured), and once none in 75 s. With the
    wall: 32-54 in 10 s."""
    world_config(tmp_path, monkeypatch, CROSSING + "wall 5.5 -1.5 5.5 1.5\n")
    stack_factory(STACK)
    session = client_session(hub)
    try:
        people = Recorder(session, keys.PEOPLE)
        map_ready(session)
        wait_for(people.latest, 10, "people reports")
        since = people.latest().stamp_ns

        def tracks() -> list[tuple[float, float, float, float]]:
            return [(q.x_m, q.y_m, q.vx_mps, q.vy_mps) for m in people.messages()
                    if m.stamp_ns > since for q in m.people]

        def walking() -> tuple[float, float, float, float] | None:
            return next((t for t in tracks() if abs(t[0] - 4.0) < 0.3 and abs(t[1]) < 1.5
                         and abs(abs(t[3]) - 0.8) < 0.3 and abs(t[2]) < 0.3), None)

        # (in view half the time, 3.75 s a crossing)
        def seen() -> str:  # for a failure: what the tracker reported instead
            near = [t for t in tracks() if abs(t[0] - 4.0) < 0.75]
            fastest = max(near, key=lambda t: abs(t[3]), default=None)
            return (f"the crossing person tracked at walking speed: {len(people.messages())} "
                    f"reports, {len(tracks())} tracks, {len(near)} on the line, fastest "
                    f"{fastest}, the last {tracks()[-3:]}")

        x, y, vx, vy = wait_for(walking, 40, seen)
        print(f"tracked at ({x:.2f}, {y:.2f}) moving ({vx:.2f}, {vy:.2f}) m/s")
        # Positive control above; now nothing else: every track lies on the person's line.
        wrong = [(round(t[0], 2), round(t[1], 2)) for t in tracks()
                 if abs(t[0] - 4.0) > 0.75 or abs(t[1]) > 3.5]  # (0.75: half hidden by a jamb)
        assert not wrong, f"tracks where no one walks: {wrong[:5]}"
    finally:
        session.close()


def test_driving_round_a_corner_makes_no_people_of_walls(
        stack_factory: Callable[..., Launcher], hub: str, tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """New walls come into view at a corner before the live map has them: they must not be
    reported as people. Positive control: someone walking across the far end of the second
    leg (x 4.3 … 5.7 at y = 8.3) is. The world is moved 3 m as in test_around_a_corner: from
    the first leg's closed end the chair was blocked at the inner wall the cabinet hid (a
    known navigation shortfall) in about 1 of 4 runs, twice over when asked again. Judged
    from the goal on, sent once the tracker reports no one: before its first map the tracker
    takes every point for a candidate (fail safe), and the cabinet beside the parked chair was
    one for ~0.7 s."""
    world_config(tmp_path, monkeypatch, shifted(L_WORLD + "person 7.3 8.3 8.7 8.3 0.6\n", -3.0))
    stack_factory(NAV_STACK)
    session = client_session(hub)
    try:
        people = Recorder(session, keys.PEOPLE)
        grids = Recorder(session, keys.MAP_GRID)  # (for a failure: when the maps came)
        pid = Recorder(session, keys.PID_STATUS)  # (for a failure: what held the chair)
        map_ready(session)
        # The tracker settled on the map first: before the map has the cabinet beside the
        # parked chair its face is a candidate, and that track coasts on for `coast_s` after
        # (fail safe; measured: reported up to 0.3 s into the goal in 3 of 6 runs at load ~4).
        settled = len(people.messages())
        wait_for(lambda: len(people.messages()) > settled and not people.latest().people, 10,
                 "no one reported beside the parked chair")
        # Round the corner (this test is about what the tracker reports on the way, not the
        # goal's end: near the outer wall a goal may also end blocked, see test_nav_system).
        sent_ns = time.time_ns()
        states = drive_to(session, Pose2D(5.0, 3.0, 1.5708), 90)
        assert "driving" in {s.state for s in states}, f"{story(states)}; {held(pid, sent_ns)}"

        def walker() -> bool:
            return any(abs(q.y_m - 8.3) < 0.4 and 4.0 < q.x_m < 6.0
                       for m in people.messages() for q in m.people)

        def instead() -> str:  # for a failure: how the drive ended, what was reported
            # (when, too: the cabinet reported before the goal was once read as a wall
            # reported instead of the walker)
            seen = [(round(q.x_m, 1), round(q.y_m, 1), round((m.stamp_ns - sent_ns) / 1e9, 1))
                    for m in people.messages() for q in m.people]
            return (f"the walker at the far end reported; the goal: {story(states)}; "
                    f"{len(people.messages())} reports, the last people (x, y, s after the "
                    f"goal) {seen[-6:]}; {held(pid, sent_ns)}")

        wait_for(walker, 10, instead)
        wrong = [(round(q.x_m, 2), round(q.y_m, 2), round((m.stamp_ns - sent_ns) / 1e9, 2))
                 for m in people.messages() if m.stamp_ns >= sent_ns
                 for q in m.people if not (abs(q.y_m - 8.3) < 0.6 and 3.8 < q.x_m < 6.2)]
        # (for a failure: when, and when the grids came, in s after the goal)
        came = [round((g.stamp_ns - sent_ns) / 1e9, 1) for g in grids.messages()]
        assert not wrong, f"walls reported as people (x, y, s): {wrong[:8]}; grids {came[:12]}"
        request(session, keys.GOAL_CANCEL, GoalRequest(waypoints=[]), GoalReply)
    finally:
        session.close()
