"""The front wheels' steer angles (spec 4.2) against TORCS 1.3.7's SimSteerUpdate, in closed form:
the outer wheel's Ackermann angle uses TORCS's `wheeltrack`, which SimCarConfig sums from all four
wheels (the mean of the front and rear tracks, negative: left y minus right y with the minus sign),
not the front axle's own track (issue 12, session 12)."""

import math

import numpy as np
import pytest

from madsim.cars import load_car
from madsim.physics import layout as L
from madsim.physics.kernel import front_wheel_angles, wheel_track
from madsim.physics.tables import car_table


def torcs_wheeltrack(car):
    """SimCarConfig: (-RL.y - FL.y + FR.y + RR.y) / 2 (wheel order FR, FL, RR, RL; y left +)."""
    fr, fl, rr, rl = (float(y) for y in car.wheel_ypos)
    return (-rl - fl + fr + rr) / 2.0


def torcs_steer(steer, wheelbase, wheeltrack):
    """SimSteerUpdate: (right, left) wheel angles for the steer angle `steer`."""
    tan_steer = abs(math.tan(steer))
    steer2 = math.atan2(wheelbase * tan_steer, wheelbase - tan_steer * wheeltrack)
    return (steer2, steer) if steer > 0 else (steer, -steer2)


def test_the_wheel_track_is_the_mean_of_both_axles_tracks():
    # car1-trb1: front wheels at y = -+0.84 m, rear at -+0.80 m: TORCS's wheeltrack -1.64 m
    car = load_car("car1-trb1")
    cp = car_table([car], ["semi-pro"])[0]
    assert car.track_front == pytest.approx(1.68, abs=1e-6) and car.track_rear == pytest.approx(1.60, abs=1e-6)
    assert wheel_track(cp, 0) == pytest.approx(-torcs_wheeltrack(car), rel=1e-12)
    assert wheel_track(cp, 0) == pytest.approx(1.64, abs=1e-6)


@pytest.mark.parametrize("steer", [0.3665, -0.3665, 0.05, -0.002, 0.0])
def test_front_wheel_angles_are_torcs_simsteerupdate(steer):
    car = load_car("car1-trb1")
    cp = car_table([car], ["semi-pro"])[0]
    wb = cp[0, L.C_L]
    got = front_wheel_angles(steer, wb, wheel_track(cp, 0))
    want = torcs_steer(steer, wb, torcs_wheeltrack(car))
    assert got == pytest.approx(want, abs=1e-15)


def test_full_lock_outer_angle_of_car1_trb1_in_numbers():
    # tan(0.3665) = 0.38384; wheelbase 2.64 m: outer = atan(2.64 x 0.38384 / (2.64 + 1.64 x
    # 0.38384)) = 0.30055 rad; with the front track (1.68 m) it would be 0.29923 rad
    car = load_car("car1-trb1")
    cp = car_table([car], ["semi-pro"])[0]
    wb, d = cp[0, L.C_L], 0.3665
    assert wb == pytest.approx(2.64, abs=1e-6)
    right, left = front_wheel_angles(d, wb, wheel_track(cp, 0))
    assert left == d
    t = math.tan(d)
    assert right == pytest.approx(math.atan(wb * t / (wb + 1.64 * t)), abs=1e-7)
    assert right == pytest.approx(0.30055, abs=1e-5)
    front_only = math.atan(wb * t / (wb + car.track_front * t))
    assert abs(right - front_only) > 1e-3
    np.testing.assert_allclose(front_only, 0.29923, atol=1e-5)
