"""PID and T-S controller against hand-stepped sequences (spec madras-features.md 6.2, 6.3)."""

import math

import pytest

from madsim.agents.pid import PID, PIDController, TrackSpeedController, rpm_gear, speed_gear

EXACT = 1e-12   # the arithmetic is a handful of float operations


def row(track_pos=0.0, angle_over_pi=0.0, speed_kmh=0.0):
    return {"trackPos": track_pos, "angle": angle_over_pi * math.pi, "speedX": speed_kmh}


@pytest.mark.parametrize("speed, gear", [(-20, 1), (0, 1), (50, 1), (50.01, 2), (80, 2),
                                         (80.01, 3), (110.01, 4), (140.01, 5), (170.01, 6),
                                         (300, 6)])
def test_speed_gear_is_snakeoils_table(speed, gear):
    assert speed_gear(speed) == gear


@pytest.mark.parametrize("gear, rpm, expected", [
    (0, 9000, 1), (-1, 0, 1),                        # neutral / reverse -> first
    (1, 4999, 1), (1, 5000, 2), (2, 6000, 3), (4, 6500, 5), (5, 7000, 6), (6, 9900, 6),
    (2, 2500, 1), (2, 2501, 2), (3, 3000, 2), (5, 3500, 4), (6, 3400, 5)])
def test_rpm_gear_follows_the_scr_sample_driver(gear, rpm, expected):
    assert rpm_gear(gear, rpm) == expected


def test_pid_madras_form_with_derivative_kick():
    pid = PID(2.0, 0.5, 1.0, kick_free=False)
    # t1: e=1, sum=1, de=1 -> 2+0.5+1; t2: e=2, sum=3, de=1; t3: e=-1, sum=2, de=-3
    assert [pid(e) for e in (1.0, 2.0, -1.0)] == pytest.approx([3.5, 6.5, -4.0], abs=EXACT)


def test_pid_kick_free_first_tick_then_identical():
    pid = PID(2.0, 0.5, 1.0)
    assert [pid(e) for e in (1.0, 2.0, -1.0)] == pytest.approx([2.5, 6.5, -4.0], abs=EXACT)
    pid.reset()
    assert pid(1.0) == pytest.approx(2.5, abs=EXACT)


def test_anti_windup_holds_the_integral_while_saturated():
    free = PID(1.0, 1.0, 0.0)
    held = PID(1.0, 1.0, 0.0, limits=(-1.0, 1.0))
    # free: sums 2, 4, 3.5 -> 4, 6, 3.0 ; held: sum stays 0 while output > 1, then -0.5
    assert [free(e) for e in (2.0, 2.0, -0.5)] == pytest.approx([4.0, 6.0, 3.0], abs=EXACT)
    assert [held(e) for e in (2.0, 2.0, -0.5)] == pytest.approx([2.0, 2.0, -1.0], abs=EXACT)
    assert held.integral == pytest.approx(-0.5, abs=EXACT)


def test_madras_compat_sequence_starts_from_zero_state():
    """MADRaS: the first tick after reset ignores the observation (state zeros), outputs are
    not clipped and any negative speed output brakes fully."""
    ts = TrackSpeedController(PIDController(madras_compat=True), target_speed=1.0,
                              normalised=False)
    ts.reset()
    ts.set_action((0.0, 50.0))                        # lane 0, 50 km/h = 1.0 in /50 units
    r1 = row(0.2, 0.05, 25.0)
    r2 = row(0.1, 0.0, 60.0)
    a = ts.act(r1)
    # steer_e = 0, accel_e = 1: 10.5 + 0.05 + 2.8 * (1 - 0)
    assert a[:3] == pytest.approx([0.0, 13.35, 0.0], abs=EXACT)
    a = ts.act(r1)
    # steer_e = 0.05 - 0.2 * 0.1 = 0.03: 5.1*0.03 + 0.001*0.03 + 1e-6*0.03
    # accel_e = 1 - 0.5 = 0.5: 10.5*0.5 + 0.05*1.5 + 2.8*(0.5 - 1)
    assert a[:3] == pytest.approx([0.15303003, 3.925, 0.0], abs=EXACT)
    a = ts.act(r2)
    # steer_e = -0.01: -0.051 + 0.001*0.02 + 1e-6*(-0.04); accel_e = -0.2:
    # -2.1 + 0.05*1.3 + 2.8*(-0.7) = -3.995 -> brake 1, accel passed on unclipped
    assert a[:3] == pytest.approx([-0.05098004, -3.995, 1.0], abs=EXACT)
    assert a[3] == 2                                   # 60 km/h -> second gear


def test_fixed_controller_sequence():
    """Fixed: state from the observation, no kick, anti-windup, clipped outputs."""
    ts = TrackSpeedController(PIDController(), target_speed=1.0, normalised=False)
    r1 = row(0.2, 0.05, 25.0)
    ts.reset(r1)
    ts.set_action((0.0, 50.0))
    a = ts.act(r1)
    # steer_e 0.03 -> 0.153 + 0.00003; accel_e 0.5 -> 5.25 + 0.025 > 1: integral held,
    # output 5.25 clipped to accel 1
    assert a[:3] == pytest.approx([0.15303, 1.0, 0.0], abs=EXACT)
    assert ts.pid.accel_pid.integral == 0.0
    a = ts.act(row(0.1, 0.0, 60.0))
    # accel_e -0.2: -2.1 - 0.01 - 1.96 < -1, integral held: -4.06 -> full brake, no throttle
    assert a[:3] == pytest.approx([-0.05098004, 0.0, 1.0], abs=EXACT)


def test_small_overspeed_brakes_proportionally():
    ts = TrackSpeedController(PIDController(), target_speed=1.0, normalised=False)
    r = row(0.0, 0.0, 51.0)
    ts.reset(r)
    ts.set_action((0.0, 50.0))
    # accel_e = -0.02: 10.5 * -0.02 + 0.05 * -0.02 = -0.211
    assert ts.act(r)[:3] == pytest.approx([0.0, 0.0, 0.211], abs=EXACT)


@pytest.mark.parametrize("limits, action, lane", [((-1, 1), (-1, 0), -1.0), ((-1, 1), (0, 0), 0.0),
                                                  ((-1, 1), (1, 0), 1.0),
                                                  ((-0.5, 0.5), (1, 0), 0.5),
                                                  ((-0.5, 0.5), (-0.5, 0), -0.25)])
def test_normalised_lane_spans_the_track_limits(limits, action, lane):
    ts = TrackSpeedController(PIDController(), target_speed=25.0, track_limits=limits)
    assert ts.desired(action)[0] == pytest.approx(lane, abs=EXACT)


def test_madras_compat_lane_mapping_keeps_the_master_bug():
    ts = TrackSpeedController(PIDController(madras_compat=True), target_speed=25.0)
    assert ts.desired((-1.0, 0.0))[0] == pytest.approx(-3.0)    # spec 11, item 15


def test_speed_action_scaling():
    norm = TrackSpeedController(PIDController(), target_speed=25.0)
    assert norm.desired((0.0, 0.5))[1] == pytest.approx(0.5 * 25.0 * 3.6)   # km/h
    raw = TrackSpeedController(PIDController(), target_speed=25.0, normalised=False)
    assert raw.desired((0.3, 80.0)) == pytest.approx((0.3, 80.0))
