"""Safety-monitor core: footprint sweep and speed bounds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from autochair.geometry import mount_mismatch
from autochair.safety.core import (
    EStopAction,
    Fault,
    MonitorState,
    SafetyCore,
    SafetyParams,
    Scan,
    bearing_bins,
    check_scan,
    scan_points,
    stop_speed,
    unseen_swing,
)

P = SafetyParams()


def wall_x(x: float, y0: float = -2.0, y1: float = 2.0) -> np.ndarray:
    """Points of a wall across the path at chair-frame x."""
    y = np.arange(y0, y1, 0.02)
    return np.column_stack((np.full_like(y, x), y))


def wall_y(y: float, x0: float = -3.0, x1: float = 3.0) -> np.ndarray:
    x = np.arange(x0, x1, 0.02)
    return np.column_stack((x, np.full_like(x, y)))


def test_nothing_in_view_is_the_caps() -> None:
    lim = SafetyCore(P).limit(np.zeros((0, 2)), 1.0, 0.0)
    assert (lim.v_fwd, lim.v_rev, lim.omega) == (P.v_max_fwd_mps, P.v_max_rev_mps,
                                                  P.omega_max_radps)
    assert lim.reason == "clear" and not lim.imminent


@pytest.mark.parametrize("gap", [0.05, 0.2, 0.5, 1.0, 1.5])
def test_obstacle_ahead_bound_stops_before_it(gap: float) -> None:
    """A wall `gap` metres ahead of the padded front: the bound stops within the gap."""
    x = P.front_m + P.padding_m + gap
    lim = SafetyCore(P).limit(wall_x(x), 0.5, 0.0)
    assert lim.free_fwd_m == pytest.approx(gap, abs=P.step_m + 1e-9)
    v = lim.v_fwd
    stop = v * P.reaction_s + v * v / (2 * P.decel_mps2)
    assert stop <= lim.free_fwd_m - P.stop_margin_m + 1e-9 or v == 0.0
    assert v == pytest.approx(min(P.v_max_fwd_mps, stop_speed(
        lim.free_fwd_m, P.decel_mps2, P.reaction_s, P.stop_margin_m)))
    assert lim.v_rev == P.v_max_rev_mps  # backing away is free


def test_bound_decreases_monotonically_to_zero() -> None:
    core = SafetyCore(P)
    bounds = [core.limit(wall_x(P.front_m + P.padding_m + g), 0.3, 0.0).v_fwd
              for g in (2.5, 1.5, 1.0, 0.6, 0.3, 0.15, 0.1, 0.05, 0.0)]
    assert bounds == sorted(bounds, reverse=True)
    assert bounds[0] == P.v_max_fwd_mps and bounds[-1] == 0.0 and 0 < bounds[3] < 1.0


def test_obstacle_touching_the_front_allows_reverse() -> None:
    lim = SafetyCore(P).limit(wall_x(P.front_m + 0.02), 0.0, 0.0)  # inside the padding
    assert lim.v_fwd == 0.0 and lim.v_rev == P.v_max_rev_mps


def test_obstacle_behind_limits_reverse_only() -> None:
    lim = SafetyCore(P).limit(wall_x(-(P.rear_m + P.padding_m + 0.3)), -0.2, 0.0)
    assert lim.v_fwd == P.v_max_fwd_mps
    assert 0 < lim.v_rev < P.v_max_rev_mps
    lim = SafetyCore(P).limit(wall_x(-(P.rear_m + P.padding_m + 0.05)), 0.0, 0.0)
    assert lim.v_rev == 0.0 and lim.v_fwd == P.v_max_fwd_mps


def test_wall_alongside_does_not_limit_straight_driving() -> None:
    lim = SafetyCore(P).limit(wall_y(P.half_width_m + P.padding_m + 0.1), 1.0, 0.0)
    assert lim.v_fwd == P.v_max_fwd_mps and lim.v_rev == P.v_max_rev_mps


def test_turning_in_place_next_to_a_wall() -> None:
    core = SafetyCore(P)
    # A wall 15 cm beside the chair: either turn swings a corner into it.
    near = core.limit(wall_y(P.half_width_m + P.padding_m + 0.15), 0.0, 0.0)
    assert near.omega < 0.5 * P.omega_max_radps
    assert near.v_fwd == P.v_max_fwd_mps  # but it may drive along it
    # Beyond the corner radius (√(0.95² + 0.35²) ≈ 1.01 m + padding) turning is free.
    far = core.limit(wall_y(1.2), 0.0, 0.0)
    assert far.omega == P.omega_max_radps and math.isinf(far.free_ccw_rad)


def test_arc_follows_the_current_turn() -> None:
    """An obstacle ahead-left is on the path of a left turn but not of a right turn."""
    pts = np.array([[1.6, 0.9], [1.6, 1.0], [1.65, 0.95]])
    core = SafetyCore(P)
    straight = core.limit(pts, 0.5, 0.0)
    left = core.limit(pts, 0.5, 0.5)
    right = core.limit(pts, 0.5, -0.5)
    assert math.isinf(straight.free_fwd_m) and math.isinf(right.free_fwd_m)
    assert left.free_fwd_m < 1.0 and left.v_fwd < P.v_max_fwd_mps


def test_imminent_only_when_it_cannot_stop() -> None:
    core = SafetyCore(P)
    pts = wall_x(P.front_m + P.padding_m + 0.3)
    assert core.limit(pts, 1.2, 0.0).imminent  # 1.44 > 2·2·0.3
    assert not core.limit(pts, 0.5, 0.0).imminent
    assert not core.limit(pts, -0.5, 0.0).imminent  # backing away


def test_scan_points_mount_and_invalid_beams() -> None:
    ranges = np.array([1.0, math.nan, 0.01, 10.0, 2.0])
    pts = scan_points(ranges, -math.pi / 2, math.pi / 4, 0.02, 5.6, (0.8636, 0.2032, 0.0))
    assert pts.shape == (2, 2)  # NaN, below range_min, beyond range_max dropped
    assert pts[0] == pytest.approx([0.8636, 0.2032 - 1.0])
    assert pts[1] == pytest.approx([0.8636, 0.2032 + 2.0])


def test_bad_params_rejected() -> None:
    with pytest.raises(ValueError, match="decel_mps2"):
        SafetyCore(SafetyParams(decel_mps2=0.0))


def test_far_points_are_dropped_without_changing_the_limits() -> None:
    core = SafetyCore(SafetyParams())
    rng = np.random.default_rng(7)
    for _ in range(20):
        pts = rng.uniform(-6, 6, size=(400, 2))
        v, omega = rng.uniform(-0.5, 1.2), rng.uniform(-0.8, 0.8)
        fast = core.limit(pts, v, omega)
        core.reach_m = math.inf  # the same core without the prefilter
        full = core.limit(pts, v, omega)
        core.reach_m = SafetyCore(SafetyParams()).reach_m
        assert fast == full


# --- fail closed: blind sectors, absurd scans, the unseen rear ---------------------------------
URG_INC = 2 * math.pi / 1024  # URG-04LX: ARES 1024, steps 44..725, front step 384
URG_MIN = (44 - 384) * URG_INC
URG_N = 725 - 44 + 1


def urg_scan(ranges: np.ndarray | float, **fields: object) -> Scan:
    r = np.broadcast_to(np.asarray(ranges, dtype=np.float64), (URG_N,)).copy()
    kw: dict[str, object] = {"angle_min": URG_MIN, "angle_inc": URG_INC, "range_min": 0.02,
                             "range_max": 5.6, "frame_id": "laser", **fields}
    return Scan(ranges=r, **kw)  # type: ignore[arg-type]


def laser_bearings() -> np.ndarray:
    return URG_MIN + URG_INC * np.arange(URG_N)


def test_all_nan_scan_blocks_every_direction() -> None:
    core = SafetyCore(P)
    free = core.assess(urg_scan(3.0), 0.0, 0.0)  # positive control: walls 3 m from the laser
    assert free.v_fwd == P.v_max_fwd_mps and free.v_rev == P.v_max_rev_mps and free.omega > 0
    assert free.blind == () and free.valid_fraction[0] == 1.0
    blind = core.assess(urg_scan(math.nan), 0.0, 0.0)
    assert (blind.v_fwd, blind.v_rev, blind.omega, blind.v_rev_autonomy) == (0, 0, 0, 0)
    assert blind.free_fwd_m == blind.free_rev_m == blind.free_ccw_rad == blind.free_cw_rad == 0
    assert "blind ahead: 0 % valid beams" in blind.reason
    assert not blind.imminent  # blindness stops the chair by its bound, not as a collision
    # Error codes beyond the window (the ingest's NaN, or raw out-of-window values) alike.
    out_of_window = core.assess(urg_scan(np.where(np.arange(URG_N) % 2, 0.001, 99.0)), 0, 0)
    assert out_of_window.v_fwd == 0.0 and out_of_window.omega == 0.0


def test_partial_blindness_only_blocks_the_direction_whose_sector_it_hits() -> None:
    core = SafetyCore(P)
    mask = core.sector(*core._paths(0.0, 0.0)["fwd"][:3])
    assert mask is not None
    in_fwd = mask[bearing_bins(laser_bearings())]
    # The forward sweep of the default chair is seen from the laser at about −81°..+64°.
    assert 0.1 * mask.sum() == pytest.approx(145, abs=3)
    assert in_fwd.sum() == pytest.approx(145 / 0.3516, abs=10)
    ahead_blind = core.assess(urg_scan(np.where(in_fwd, math.nan, 3.0)), 0.0, 0.0)
    assert ahead_blind.v_fwd == 0.0 and ahead_blind.free_fwd_m == 0.0
    assert ahead_blind.blind[0] == "blind ahead: 0 % valid beams"
    assert ahead_blind.v_rev == P.v_max_rev_mps  # it may back away
    # Every beam outside the forward sector dead instead: forward stays free.
    side_blind = core.assess(urg_scan(np.where(~in_fwd, math.nan, 3.0)), 0.0, 0.0)
    assert side_blind.v_fwd == P.v_max_fwd_mps and side_blind.valid_fraction[0] == 1.0
    # The threshold itself: 25 % valid in the sector is blind, 35 % is not (default 0.3).
    idx = np.flatnonzero(in_fwd)
    for frac, blocked in ((0.25, True), (0.35, False)):
        r = np.full(URG_N, 3.0)
        r[idx[: round(len(idx) * (1 - frac))]] = math.nan
        lim = core.assess(urg_scan(r), 0.0, 0.0)
        assert lim.valid_fraction[0] == pytest.approx(frac, abs=0.01)
        assert (lim.v_fwd == 0.0) is blocked


def test_blind_sector_follows_the_arc() -> None:
    """Beams dead from +70° (left, sideways): outside the straight sweep, inside the sweep of
    a left arc (the chair turns into that side)."""
    core = SafetyCore(SafetyParams(min_valid_fraction=0.8))
    r = np.where(laser_bearings() > math.radians(70), math.nan, 3.0)
    straight = core.assess(urg_scan(r), 0.5, 0.0)
    assert straight.v_fwd > 0 and straight.valid_fraction[0] == 1.0
    right = core.assess(urg_scan(r), 0.5, -0.25)  # κ = −0.5 /m
    assert right.v_fwd > 0 and not [b for b in right.blind if "ahead" in b]
    left = core.assess(urg_scan(r), 0.5, 0.25)  # κ = 0.5 /m
    assert left.v_fwd == 0.0 and left.blind[0].startswith("blind ahead")
    assert left.valid_fraction[0] is not None and left.valid_fraction[0] < 0.8


def test_reverse_is_judged_by_the_whole_scan_unless_the_rear_is_seen() -> None:
    core = SafetyCore(P)
    # 240°: the reversing arc's sector shows only at the edge of the view, here looking down a
    # corridor (no return); the rest of the scan is fine: not blind.
    edge = laser_bearings() < math.radians(-80)
    lim = core.assess(urg_scan(np.where(edge, math.nan, 3.0)), -0.3, -0.3)
    assert lim.v_rev > 0 and not lim.rear_seen and lim.blind == ()
    assert lim.valid_fraction[1] == pytest.approx(1 - edge.mean())
    # A 360° laser sees the whole reverse sweep: judged by its own sector.
    bearings = -math.pi + URG_INC * np.arange(1024)
    behind = np.abs(bearings) > math.radians(150)
    full = Scan(np.where(behind, math.nan, 3.0), -math.pi, URG_INC, 0.02, 5.6)
    seen = core.assess(full, 0.0, 0.0)
    assert seen.rear_seen and seen.v_rev == 0.0 and seen.blind[0].startswith("blind behind")
    assert seen.v_fwd == P.v_max_fwd_mps
    control = core.assess(Scan(np.full(1024, 3.0), -math.pi, URG_INC, 0.02, 5.6), 0.0, 0.0)
    assert control.v_rev == P.v_max_rev_mps


SCAN_FIELDS = [
    ({"angle_min": math.nan}, "fields"),
    ({"angle_inc": math.inf}, "fields"),
    ({"range_max": math.nan}, "fields"),
    ({"angle_inc": 0.0}, "increment"),
    ({"angle_inc": -URG_INC}, "increment"),
    ({"angle_inc": 0.1}, "increment"),  # 5.7° between beams: a chair leg fits between
    ({"angle_min": 40.0}, "angles"),
    ({"range_min": -0.1}, "range_window"),
    ({"range_min": 6.0}, "range_window"),
    ({"range_max": 1e6}, "range_window"),
    ({"frame_id": "base"}, "frame"),
]


@pytest.mark.parametrize(("fields", "kind"), SCAN_FIELDS)
def test_absurd_scan_fields_block_every_direction(fields: dict[str, object], kind: str) -> None:
    core = SafetyCore(P)
    assert not core.assess(urg_scan(3.0), 0.0, 0.0).rejected  # positive control
    lim = core.assess(urg_scan(3.0, **fields), 0.0, 0.0)
    assert lim.rejected == kind and lim.reason.startswith("scan rejected: ")
    assert (lim.v_fwd, lim.v_rev, lim.omega, lim.v_rev_autonomy) == (0, 0, 0, 0)


def test_beam_count_against_the_angles() -> None:
    core = SafetyCore(P)
    one = Scan(np.array([1.0]), URG_MIN, URG_INC, 0.02, 5.6)
    assert core.assess(one, 0, 0).rejected == "beams"
    # 1100 beams at 0.35° each would cover 377°: more than a full turn.
    many = Scan(np.full(1100, 3.0), -math.pi, URG_INC, 0.02, 5.6)
    assert core.assess(many, 0, 0).rejected == "beams"
    full = Scan(np.full(1024, 3.0), -math.pi, URG_INC, 0.02, 5.6)  # exactly 360°: fine
    assert not core.assess(full, 0, 0).rejected
    assert check_scan(urg_scan(3.0), "laser", P) == ("", "")


def test_unseen_footprint_caps_omega() -> None:
    """URG-04LX (±119.9°) at the thesis mount (0.8636, 0.2032): the left side of the footprint
    is unseen from x = 0.779 m backwards (the FOV edge passes 8 cm behind the laser), so the
    farthest unseen boundary point is (0.779, 0.35), R = 0.854 m: |ω| ≤ 0.3 / 0.854."""
    a_max = URG_MIN + (URG_N - 0.5) * URG_INC  # the last beam's bearing + half a step
    lx, ly = P.mount[:2]
    x_edge = lx + (P.half_width_m - ly) / math.tan(a_max)
    r_expected = math.hypot(x_edge, P.half_width_m)
    assert x_edge == pytest.approx(0.779, abs=1e-3) and r_expected == pytest.approx(0.854, 1e-3)
    r, cap = unseen_swing(P, (URG_MIN - URG_INC / 2, URG_N * URG_INC))
    assert r == pytest.approx(r_expected, abs=1.5e-3)
    assert cap == pytest.approx(P.blind_speed_mps / r_expected, rel=2e-3)  # 0.351 rad/s
    lim = SafetyCore(P).assess(urg_scan(3.0), 0.0, 0.0)
    assert lim.omega == pytest.approx(0.351, abs=1e-3) and lim.omega == lim.omega_unseen_cap
    # A laser at the axle sees all but the rear: the rear corners, R = √(0.25² + 0.35²).
    at_axle = SafetyParams(mount=(0.0, 0.0, 0.0))
    r0, cap0 = unseen_swing(at_axle, (URG_MIN - URG_INC / 2, URG_N * URG_INC))
    assert r0 == pytest.approx(math.hypot(0.25, 0.35), abs=1e-3)
    assert cap0 == pytest.approx(0.3 / 0.4301, rel=2e-3)
    # Positive control: a 360° scan sees the whole footprint: no cap.
    full = Scan(np.full(1024, 3.0), -math.pi, URG_INC, 0.02, 5.6)
    assert unseen_swing(P, (-math.pi - URG_INC / 2, 1024 * URG_INC)) == (0.0, math.inf)
    assert SafetyCore(P).assess(full, 0.0, 0.0).omega == P.omega_max_radps
    # blind_speed is configurable: twice the speed, twice the cap.
    fast = SafetyCore(SafetyParams(blind_speed_mps=0.6)).assess(urg_scan(3.0), 0.0, 0.0)
    assert fast.omega == pytest.approx(2 * lim.omega, rel=1e-9)


def test_autonomy_may_not_reverse_blind_unless_configured() -> None:
    scan = urg_scan(3.0)
    lim = SafetyCore(P).assess(scan, 0.0, 0.0)
    assert lim.v_rev == P.v_max_rev_mps  # attended (teleop) reverse as before
    assert lim.v_rev_autonomy == 0.0 and not lim.rear_seen
    slow = SafetyCore(SafetyParams(blind_reverse_autonomy_mps=0.2)).assess(scan, 0.0, 0.0)
    assert slow.v_rev_autonomy == 0.2
    over = SafetyCore(SafetyParams(blind_reverse_autonomy_mps=0.8)).assess(scan, 0.0, 0.0)
    assert over.v_rev_autonomy == P.v_max_rev_mps  # never above the reverse bound
    # A 360° laser sees the reverse sweep: autonomy gets the reverse bound.
    full = Scan(np.full(1024, 3.0), -math.pi, URG_INC, 0.02, 5.6)
    seen = SafetyCore(P).assess(full, 0.0, 0.0)
    assert seen.rear_seen and seen.v_rev_autonomy == seen.v_rev == P.v_max_rev_mps


def test_mount_mismatch_tolerances() -> None:
    want = ((0.8636, 0.2032, 0.3937), 0.0)

    def check(t: tuple[float, float, float], yaw: float, parent: str = "chair") -> str:
        return mount_mismatch(parent, t, (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)),
                              *want)

    assert check((0.8636, 0.2032, 0.3937), 0.0) == ""
    assert check((0.8636 + 0.0009, 0.2032, 0.3937), math.radians(0.09)) == ""
    assert "x 0.8647 m" in check((0.8636 + 0.0011, 0.2032, 0.3937), 0.0)
    assert "laser_z_m" in check((0.8636, 0.2032, 0.5), 0.0)
    assert "0.11°" in check((0.8636, 0.2032, 0.3937), math.radians(0.11))
    assert "parent" in check((0.8636, 0.2032, 0.3937), 0.0, parent="world")
    assert "non-finite" in check((math.nan, 0.2032, 0.3937), 0.0)
    # A tilted laser (roll) is a different mount for a planar monitor too.
    tilt = mount_mismatch("chair", want[0], (math.sin(0.01), 0.0, 0.0, math.cos(0.01)), *want)
    assert "rotation differs" in tilt


def test_monitor_state_faults_are_typed() -> None:
    s = MonitorState(stale_s=0.5)
    assert s.faults(0.0) == (Fault.NO_SCAN,) and s.reason(0.0) == "scan stale"
    s.on_scan(1.0, "")
    assert s.faults(1.4) == () and s.reason(1.4) == ""
    assert s.faults(1.6) == (Fault.STALE,) and s.reason(1.6) == "scan stale"
    s.on_scan(2.0, "scan rejected: frame 'base', want 'laser'")
    assert s.faults(2.1) == (Fault.REJECTED,) and "frame 'base'" in s.reason(2.1)
    assert s.on_mount("tf x 0.9000 m vs [chair] laser_x_m 0.8636 m")
    s.on_scan(2.2, "")
    assert s.faults(2.3) == (Fault.MOUNT,) and s.reason(2.3).startswith("laser mount mismatch")
    assert not s.on_mount("tf x 0.9100 m vs [chair] laser_x_m 0.8636 m")  # still wrong
    assert s.on_mount("") and s.faults(2.3) == ()
    assert s.on_blind(("fwd", "ccw")) and not s.on_blind(("fwd", "ccw")) and s.on_blind(())
    faults, changed = s.poll(2.3)
    assert faults == () and changed  # from the initial NO_SCAN
    assert s.poll(2.35) == ((), False)


def test_estop_asserts_every_scan_while_imminent_then_clears_for_a_second() -> None:
    s = MonitorState(stale_s=0.5, clear_hold_s=1.0)
    # Start: the first scans clear whatever a previous monitor left, for one second.
    assert s.estop(False, 0.0) == (EStopAction.CLEAR, False)
    assert s.estop(False, 0.9)[0] is EStopAction.CLEAR
    assert s.estop(False, 1.1)[0] is EStopAction.NONE
    assert s.estop(True, 2.0) == (EStopAction.ASSERT, True)
    for t in (2.1, 2.2, 2.3):  # every scan, not only the transition
        assert s.estop(True, t) == (EStopAction.ASSERT, False)
    assert s.estop(False, 2.4) == (EStopAction.CLEAR, True)
    assert [s.estop(False, t)[0] for t in (2.5, 3.0, 3.4, 3.5)] == [EStopAction.CLEAR] * 3 + [
        EStopAction.NONE]


def test_monitor_decides_what_to_publish_around_the_sweep() -> None:
    from autochair.safety.monitor import Monitor

    m = Monitor(SafetyCore(P), stale_s=0.5, odometry_s=0.2, clear_hold_s=1.0, frame_id="laser")
    near = urg_scan(0.35)  # walls 0.35 m from the laser all round
    # Odometry fresh: 1.2 m/s toward a wall 0.2 m off is imminent, asserted on this scan.
    m.on_odom(1.2, 0.0, 0.0)
    v = m.on_scan(near, 0.1)
    assert v.v == 1.2 and not v.odometry_stale and v.imminent and v.imminent_changed
    assert v.estop is EStopAction.ASSERT and v.published is v.assessed
    # A rejected scan says nothing new: the imminent verdict stands, and it is a stop.
    bad = m.on_scan(urg_scan(0.35, frame_id="base"), 0.15)
    assert bad.assessed.rejected and bad.imminent and bad.estop is EStopAction.ASSERT
    assert bad.published.v_fwd == 0.0 and bad.degraded
    # Odometry stale: assessed at rest (no motion claimed), so no longer imminent.
    rest = m.on_scan(near, 0.5)
    assert rest.odometry_stale and rest.v == 0.0 and not rest.imminent
    assert rest.imminent_changed and rest.estop is EStopAction.CLEAR
    # A mount mismatch publishes a stop at once and overrides every scan until fixed.
    stop, changed = m.on_mount("tf x 0.9000 m vs [chair] laser_x_m 0.8636 m")
    assert changed and stop is not None and stop.v_fwd == 0.0
    far = m.on_scan(urg_scan(5.0), 0.6)
    assert far.assessed.v_fwd > 0 and far.published.v_fwd == 0.0 and far.degraded
    assert far.detail.startswith("stop: laser mount mismatch")
    assert m.on_mount("") == (None, True)
    assert m.on_scan(urg_scan(5.0), 0.7).published.v_fwd > 0
    # Silence: no stop while scans are fresh, a stop once they are stale or the source died.
    assert m.tick(0.8).stop is None
    assert m.tick(1.3).stop is not None
    m.on_scan(urg_scan(5.0), 1.4)
    m.source_lost()
    t = m.tick(1.41)
    assert t.stop is not None and t.stop.v_fwd == 0.0 and t.reason == "scan stale"


def test_a_late_or_future_scan_is_a_stop() -> None:
    """H38: the monitor judges a scan by its own stamp, not by when it arrived."""
    from autochair.safety.monitor import Monitor

    m = Monitor(SafetyCore(P), stale_s=0.5, odometry_s=0.2, clear_hold_s=1.0, frame_id="laser",
                max_age_s=0.35, skew_s=0.1)
    m.on_odom(0.5, 0.0, 0.0)
    fresh = m.on_scan(urg_scan(5.0), 0.1, age_s=0.11)  # positive control: a sweep just ended
    assert fresh.published.v_fwd > 0.5 and not fresh.degraded
    for age, kind in ((0.36, "old"), (2.0, "old"), (-0.11, "future")):
        v = m.on_scan(urg_scan(5.0), 0.2, age_s=age)
        assert v.published.v_fwd == v.published.v_rev == v.published.omega == 0.0, age
        assert v.assessed.rejected == kind and v.degraded and "stamp" in v.detail
        assert m.tick(0.25).reason.startswith("scan rejected: " + kind)
    assert m.on_scan(urg_scan(5.0), 0.3, age_s=0.1).published.v_fwd > 0.5  # fresh again


def test_coarse_to_fine_sweep_equals_testing_every_pose() -> None:
    """SafetyCore._free tests a few poses of each window first; it must find exactly the
    first hit that testing every pose finds, on every path, for points anywhere (inside the
    footprint at the start too)."""
    def dense(core: SafetyCore, pts: np.ndarray, x: np.ndarray, y: np.ndarray,
              th: np.ndarray, steps: np.ndarray) -> float:
        pen = core._penetration(pts, x, y, th, core.p.padding_m)
        start = pen[0]
        blocked = (pen[1:] > 0) & ((start <= 0)[None, :] | (pen[1:] > start[None, :] + 1e-9))
        hit = np.flatnonzero(blocked.any(axis=1))
        return math.inf if hit.size == 0 else float(steps[hit[0]])

    rng = np.random.default_rng(7)
    core = SafetyCore(P)
    checked = finite = 0
    for _ in range(300):
        n = int(rng.integers(1, 40))
        pts = rng.uniform(-3.0, 3.0, (n, 2))
        v, w = rng.uniform(-1.2, 1.2), rng.uniform(-1.0, 1.0)
        for path in core._paths(v, w).values():
            got, want = core._free(pts, *path), dense(core, pts, *path)
            assert got == want, (pts.tolist(), v, w)
            checked += 1
            finite += math.isfinite(want)
    assert finite > checked // 4  # a positive control: many paths do hit something


@pytest.mark.parametrize("v,omega", [(1.0, math.nan), (1.0, math.inf)])
def test_non_finite_odometry_is_no_motion_known_not_a_clear_path(v: float, omega: float) -> None:
    """H10 at the monitor: a NaN ω swept no arc, so a wall 1 m ahead read as "clear" at
    1.2 m/s. A non-finite sample is stale odometry (assessed at rest, counted), never a path."""
    from autochair.safety.monitor import Monitor

    b = laser_bearings()
    ahead = np.where(np.abs(b) < 1.2, 1.0 / np.cos(np.clip(b, -1.2, 1.2)), 5.0)  # a wall 1 m
    m = Monitor(SafetyCore(P), stale_s=0.5, odometry_s=0.2, clear_hold_s=1.0, frame_id="laser")
    m.on_odom(1.0, 0.0, 0.0)  # positive control: the same wall, finite odometry, limits
    fine = m.on_scan(urg_scan(ahead), 0.05)
    assert not fine.odometry_stale and 0.0 < fine.published.v_fwd < P.v_max_fwd_mps
    m.on_odom(v, omega, 0.1)
    bad = m.on_scan(urg_scan(ahead), 0.15)
    assert bad.published.v_fwd <= fine.published.v_fwd and bad.published.free_fwd_m < 1.0
    assert bad.odometry_stale and bad.v == 0.0
