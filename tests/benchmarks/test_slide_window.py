"""benchmarks/slide_window.py's yaw-rate estimate from SCR's `angle` (issue 12's sand2 round):
closed-form cases, including the heading wrapping through +-pi."""

import numpy as np
import pytest

from tests.benchmarks.conftest import load_script, unload


@pytest.fixture(scope="module")
def slide():
    yield load_script("slide_window")
    unload()


def test_yaw_rate_of_a_car_following_a_turn_through_pi(slide):
    # the track turns left at 0.8 rad/s past heading pi (wrapped to -pi); the car points 0.1
    # rad right of it at first and swings by 0.05 sin(3 t): yaw = track - angle
    t = np.arange(0.0, 2.0, 0.0209)
    track = 2.9 + 0.8 * t
    angle = 0.1 + 0.05 * np.sin(3.0 * t)
    heading = (track + np.pi) % (2 * np.pi) - np.pi
    r = slide.yaw_rate(heading, angle, t)
    exact = 0.8 - 0.15 * np.cos(3.0 * t)
    # central differences: error (dt^2 / 6) x third derivative = 0.15 x 27 x 0.0209^2 / 6 inside
    assert np.max(np.abs(r[1:-1] - exact[1:-1])) < 4e-4
    assert np.max(np.abs(r - exact)) < 0.01           # one-sided at the two ends


def test_a_car_sliding_straight_on_has_the_turns_yaw_rate_minus_the_angle_growth(slide):
    # the car keeps its heading while the track turns under it: angle grows with the track
    t = np.linspace(0.0, 1.0, 49)
    track = 0.5 * t
    r = slide.yaw_rate(track, track - 0.2, t)
    assert np.allclose(r, 0.0, atol=1e-12)


def test_rear_differential_input_torque_and_clamp_of_car1_trb1(slide):
    # TORCS 1.3.7 (SimTransmissionUpdate): in.Tq = engine torque x overall ratio x clutch
    # transfer, no efficiency. car1-trb1: final drive 4.5, gears 3.0 and 1.1; limited slip with
    # max slip bias 0.03, locking torque 5000 and locking brake torque 1500 N m; full-throttle
    # torque 350 N m at 4000 rpm and 483 N m at 8000 rpm (linear between the file's points);
    # engine braking coefficient 0.33 of the curve, growing from tickover (900 rpm) to revs
    # maxi (10000 rpm). SCR's "rpm" is the engine speed in rad/s x 10.
    from madsim.cars import load_car

    car = load_car("car1-trb1")
    rpm = lambda n: n * 2.0 * np.pi / 60.0 * 10.0                 # true rpm -> SCR's unit
    run = {"gear": np.array([4.0, 1.0, 1.0, 0.0]), "rpm": np.array([rpm(4000), rpm(8000), rpm(8000), rpm(8000)]),
           "wheelSpinVel_2": np.array([84.0, 50.0, 0.0, 10.0]), "wheelSpinVel_3": np.array([80.0, 50.0, 0.0, 10.0])}
    d = slide.rear_differential(car, run, np.array([1.0, 1.0, 0.0, 1.0]))
    k = 0.33 * (8000.0 - 900.0) / (10000.0 - 900.0)
    expect = np.array([350.0 * 1.1 * 4.5, 483.0 * 3.0 * 4.5, -483.0 * k * 3.0 * 4.5, 0.0])
    np.testing.assert_allclose(d["d_in"], expect, rtol=1e-5)
    assert d["d_in"][0] < 5000.0 < d["d_in"][1]                    # 4th: free; 1st: a spool
    assert d["d_in"][2] < -1500.0                                  # lifting in 1st: a spool too
    np.testing.assert_allclose(d["allowed"], 0.03 * (1.0 - expect / np.array([5000.0, 5000.0, -1500.0, 5000.0])),
                               rtol=1e-5)
    np.testing.assert_allclose(d["ratio"], [4.0 / 164.0, 0.0, 0.0, 0.0], atol=1e-15)
