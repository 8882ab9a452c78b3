"""`World.place` (any pose, read its sensors), `World.step(substeps)` and TORCS's driver-call
schedule (`madsim.physics.schedule`)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from madsim.physics import SensorSuite, TorcsClock, World, make_clock
from madsim.physics.schedule import FixedClock


def make(track, cars):
    return World(track, cars, np.random.default_rng(0), contact=False)


def test_place_puts_the_car_at_the_pose_and_the_sensors_read_it(road, sedan):
    w = make(road, [sedan, sedan])
    w.reset()
    before = np.array(w.state[1])
    w.place(0, 321.0, n=2.5, yaw_rel=0.1, speed=20.0, gear=2)
    f = SensorSuite(w).frame()
    assert w.s[0] == pytest.approx(321.0, abs=1e-6)
    assert w.n[0] == pytest.approx(2.5, abs=1e-6)
    # SCR angle = track direction - car heading; trackPos = n / half width; speedX km/h
    assert f.angle[0] == pytest.approx(-0.1, abs=1e-9)
    assert f.trackPos[0] == pytest.approx(2.5 / (road.width / 2), abs=1e-9)
    assert f.speedX[0] == pytest.approx(72.0, abs=1e-9)
    assert f.speedY[0] == pytest.approx(0.0, abs=1e-9)
    assert f.gear[0] == 2
    assert f.wheelSpinVel[0][0] > 0 and f.wheelSpinVel[0][0] == pytest.approx(f.wheelSpinVel[0][1])
    np.testing.assert_array_equal(w.state[1], before)     # the other car is untouched


def test_place_keeps_the_counters_and_wraps_s(road, sedan):
    w = make(road, [sedan])
    w.reset()
    for _ in range(50):
        w.step(np.array([[0.0, 1.0, 0.0, 1, 0.0]]))
    t = w.time
    w.place(0, road.length + 10.0, speed=5.0)
    assert w.time == t
    assert w.s[0] == pytest.approx(10.0, abs=1e-6)
    assert w.vx[0] == pytest.approx(5.0, abs=1e-12)


@pytest.mark.parametrize("bad", [dict(s=math.nan), dict(s=1.0, n=math.inf), dict(s=1.0, speed="fast")])
def test_place_rejects_bad_numbers(road, sedan, bad):
    w = make(road, [sedan])
    with pytest.raises(ValueError, match="place"):
        w.place(0, **bad)
    with pytest.raises(ValueError, match="car must be"):
        w.place(1, 10.0)


def test_reset_with_placements_equals_place(road, sedan):
    a, b = make(road, [sedan]), make(road, [sedan])
    a.reset(np.array([[200.0, -1.0, 15.0]]), gears=3)
    b.reset()
    b.place(0, 200.0, n=-1.0, speed=15.0, gear=3)
    np.testing.assert_array_equal(a.state, b.state)


def test_substeps_advance_that_many_sub_steps(road, sedan):
    a, b = make(road, [sedan]), make(road, [sedan])
    u = np.array([[0.0, 1.0, 0.0, 1, 0.0]])
    a.step(u, 11)
    for _ in range(11):
        b.step(u, 1)
    assert a.time == pytest.approx(0.022, abs=1e-12)
    np.testing.assert_array_equal(a.state, b.state)
    with pytest.raises(ValueError, match="substeps"):
        a.step(u, 0)


@pytest.mark.parametrize("speed", [2.9, 20.0])
def test_substeps_agree_across_the_spin_average(road, sedan, speed):
    # above kernel.SPIN_AVG_SPEED (3 m/s) the spins and tyre forces are two-sample averages
    # whose last raw values are state columns: one call of n sub-steps equals n calls of one,
    # also across the switch from the implicit step (2.9 m/s, accelerating through 3 m/s)
    a, b = make(road, [sedan]), make(road, [sedan])
    for w in (a, b):
        w.place(0, 50.0, speed=speed, gear=1)
    u = np.array([[0.3, 1.0, 0.0, 1, 0.0]])
    a.step(u, 60)
    for _ in range(60):
        b.step(u, 1)
    assert a.vx[0] > 3.0
    np.testing.assert_array_equal(a.state, b.state)


def test_torcs_clock_calls_every_20_or_22_ms_and_settles():
    c = TorcsClock()
    assert c.time == pytest.approx(0.018, abs=1e-12)     # TORCS's first racing message
    steps = np.array([c.substeps() for _ in range(21211)])
    assert set(np.unique(steps)) == {10, 11}
    # reference: the real-TORCS trace forza__car1-trb1__100 (../shared/torcs-traces): its 21,212
    # racing messages are 22 ms apart after racing messages 11, 23, 48, 98, ..., 3,914 times
    assert list(np.nonzero(steps[:100] == 11)[0][:4]) == [11, 23, 48, 98]
    assert np.count_nonzero(steps == 11) == 3914
    assert np.all(steps[-10000:] == 10)                   # later: exactly 20 ms
    c.reset()
    assert c.time == pytest.approx(0.018, abs=1e-12) and c.substeps() == steps[0]


def test_make_clock():
    assert isinstance(make_clock("fixed"), FixedClock) and make_clock("fixed").substeps() == 10
    assert isinstance(make_clock("torcs"), TorcsClock)
    with pytest.raises(ValueError, match="tick schedule"):
        make_clock("sometimes")


def test_reset_grid_as_a_torcs_race_file_gives_it(road, sedan):
    w = make(road, [sedan] * 3)
    w.reset(grid={"rows": 1, "distance to start": 100.0, "distance between columns": 12.0})
    # one row: every car on the centre line, 100 m + 12 m per place before the line (track spec 7)
    assert w.s == pytest.approx(road.length - np.array([100.0, 112.0, 124.0]), abs=1e-6)
    assert w.n == pytest.approx(np.zeros(3), abs=1e-9)
    w.reset()      # default: quickrace's grid, 25 m and 2 rows
    assert w.s[0] == pytest.approx(road.length - 25.0, abs=1e-6) and abs(w.n[0]) > 1.0


@pytest.mark.parametrize("grid, msg", [({"rows": 0}, "'rows' must be >= 1"), ({"lanes": 2}, "unknown value 'lanes'"),
                                       ({"distance to start": math.nan}, "finite number")])
def test_reset_grid_rejects_bad_values(road, sedan, grid, msg):
    w = make(road, [sedan])
    with pytest.raises(ValueError, match=msg):
        w.reset(grid=grid)
    with pytest.raises(ValueError, match="not both"):
        w.reset(np.zeros((1, 3)), grid={"rows": 1})
