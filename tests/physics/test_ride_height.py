"""The CG height (`z` sensor): GC height + the ride height TORCS's suspension settles at under
the current wheel loads (spring x bellcrank^2 wheel rate, packers, suspension course)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from madsim.physics import SensorSuite
from trackfiles import segment

G = 9.81


def test_z_at_rest_is_gc_height_plus_loaded_ride_height(straight, ph):
    car = ph.sedan()
    w = ph.world_at(straight(), car)
    m = car.mass + car.fuel                      # the static loads carry the fuel too
    rides = []
    for k in range(4):
        axle = car.weight_front if k < 2 else 1.0 - car.weight_front
        side = (car.weight_front_right if k < 2 else car.weight_rear_right)
        side = side if k % 2 == 0 else 1.0 - side
        w0 = car.mass * G * axle * side
        rate = car.susp_spring[k] * car.susp_bellcrank[k] ** 2
        rides.append(car.ride_height[k] - (w0 * m / car.mass - w0) / rate)
    ride_cg = (0.5 * (rides[0] + rides[1]) * car.b + 0.5 * (rides[2] + rides[3]) * car.a) / car.wheelbase
    f = SensorSuite(w).frame()
    assert f.z[0] == pytest.approx(car.cg_height + ride_cg, abs=1e-5)     # 0.01 mm
    assert 0.0 < ride_cg < max(car.ride_height)


def test_ride_height_stops_at_the_packers(straight, ph):
    car = ph.sedan()
    soft = dataclasses.replace(car, susp_spring=np.full(4, 1000.0), susp_packers=np.full(4, 0.03))
    w = ph.world_at(straight(), soft)
    assert SensorSuite(w).frame().z[0] == pytest.approx(car.cg_height + 0.03, abs=1e-9)


def test_downforce_lowers_the_car(make_track, ph):
    from madsim.cars import load_car
    car = load_car("madsim-gt")                  # wings: downforce grows with v^2
    track = make_track([segment("s", "str", lg=3000)])
    slow = ph.world_at(track, car, speed=10.0, gear=2)
    fast = ph.world_at(track, car, speed=70.0, gear=6)
    u = np.zeros((1, 5))
    for w, g in ((slow, 2), (fast, 6)):
        u[0, 3] = g
        u[0, 1] = 0.3
        for _ in range(10):
            w.step(u)
    assert fast.z[0] < slow.z[0] - 0.002
