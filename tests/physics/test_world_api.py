"""World construction, placement on the starting grid, controls validation and clipping."""

from __future__ import annotations

import numpy as np
import pytest

from madsim.physics import layout as L
from madsim.physics.world import World
from madsim.tracks import load_track


def make(track, cars, **kw):
    kw.setdefault("contact", False)
    return World(track, cars, np.random.default_rng(0), **kw)


def test_grid_follows_track_spec_7_with_quickrace_values(road, sedan):
    w = make(road, [sedan] * 5)
    i = np.arange(5)
    # quickrace: rows 2, 25 m to the start, 20 m between columns, 10 m offset within a column
    expected_s = road.length - (25.0 + (i // 2) * 20.0 + (i % 2) * 10.0)
    assert w.s == pytest.approx(expected_s, abs=1e-6)
    assert not road.grid                          # no track override here
    width = road.width
    to_right = w.n + width / 2
    # two cars per row at 1/3 and 2/3 of the width; pole on the inside of the first curve
    assert sorted(set(np.round(to_right / width, 6))) == pytest.approx([1 / 3, 2 / 3])
    assert (to_right[0] > width / 2) == (w.n[0] > 0)
    assert np.all(w.speed == 0.0) and np.all(w.laps == 0)
    assert w.yaw == pytest.approx(road.heading_at(w.s), abs=1e-9)
    assert w.dist_raced == pytest.approx(w.s - road.length)      # (0 - (0 + 1)) L + s


def test_track_grid_overrides_the_race_values(need_torcs, sedan):
    alpine = load_track("alpine-1")                # Starting Grid: 4 m to start, 15 m, 7 m
    w = make(alpine, [sedan] * 3)
    assert w.s == pytest.approx(alpine.length - np.array([4.0, 11.0, 19.0]), abs=1e-6)


def test_explicit_placement_and_attributes(road, sedan):
    w = make(road, [sedan, sedan])
    w.reset(np.array([[100.0, 1.5, 20.0], [300.0, -2.0, 0.0]]), gears=[2, 0])
    assert w.s == pytest.approx([100.0, 300.0], abs=1e-6)
    assert w.n == pytest.approx([1.5, -2.0], abs=1e-6)
    assert w.speed == pytest.approx([20.0, 0.0])
    assert list(w.gear) == [2, 0]
    assert w.wheel_spin.shape == (2, 4)
    assert w.wheel_spin[0] == pytest.approx(20.0 / sedan.wheel_radius, rel=1e-9)
    assert w.engine_speed[0] == pytest.approx(20.0 / sedan.wheel_radius[2] * sedan.overall_ratio(2))
    assert w.engine_speed[1] == pytest.approx(sedan.tickover)
    assert w.fuel == pytest.approx([sedan.fuel] * 2)
    assert w.time == 0.0
    assert w.x.flags.writeable is False
    with pytest.raises(ValueError, match="shape"):
        w.reset(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="car 1 speed"):
        w.reset(np.array([[1.0, 0.0, 0.0], [2.0, 0.0, np.nan]]))


def test_every_state_column_is_documented():
    assert len(L.STATE_COLUMNS) == L.N_STATE == len(set(L.STATE_COLUMNS))
    assert set(L.STATE_DOC) == set(L.STATE_COLUMNS)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_controls_are_rejected_naming_car_and_column(road, sedan, bad):
    w = make(road, [sedan] * 3)
    u = np.zeros((3, 5))
    u[1, 2] = bad
    before = w.state.copy()
    with pytest.raises(ValueError, match=r"car 1 brake"):
        w.step(u)
    assert np.array_equal(w.state, before)       # nothing advanced


def test_nan_policy_zero_replaces_and_counts(road, sedan):
    a = make(road, [sedan] * 2, nan_policy="zero")
    b = make(road, [sedan] * 2)
    u = np.array([[0.1, np.nan, 0.0, 1.0, np.inf], [0.0, 1.0, 0.0, 1.0, 0.0]])
    clean = np.nan_to_num(u, nan=0.0, posinf=0.0)
    for _ in range(5):
        a.step(u)
        b.step(clean)
    assert np.array_equal(a.state, b.state)
    assert list(a.nan_count) == [10, 0]
    assert np.isnan(u[0, 1])                      # the caller's array is not modified


def test_out_of_range_controls_are_clipped(road, sedan):
    a = make(road, [sedan])
    b = make(road, [sedan])
    for w in (a, b):
        w.reset(np.array([[100.0, 0.0, 10.0]]), gears=1)
    wild = np.array([[7.0, 3.0, -2.0, 99.0, -5.0]])
    tame = np.array([[1.0, 1.0, 0.0, sedan.top_gear, 0.0]])
    for _ in range(20):
        a.step(wild)
        b.step(tame)
    assert np.array_equal(a.state, b.state)
    assert a.gear[0] == sedan.top_gear
    a.step(np.array([[0.0, 0.0, 0.0, 2.4, 0.0]]))
    a.step(np.array([[0.0, 0.0, 0.0, -7.0, 0.0]]))   # shift in progress: request ignored
    assert a.gear[0] == 2
    for _ in range(30):
        a.step(np.array([[0.0, 0.0, 0.0, -7.0, 0.0]]))
    assert a.gear[0] == -1


def test_controls_shape_is_checked(road, sedan):
    w = make(road, [sedan] * 2)
    with pytest.raises(ValueError, match=r"\(2, 5\)"):
        w.step(np.zeros((2, 4)))
    with pytest.raises(ValueError, match=r"\(2, 5\)"):
        w.step(np.zeros(5))


def test_bad_arguments(road, sedan):
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="nan_policy"):
        World(road, [sedan], rng, nan_policy="ignore")
    with pytest.raises(ValueError, match="skill"):
        World(road, [sedan], rng, skill="expert")
    with pytest.raises(TypeError, match="Generator"):
        World(road, [sedan], 42)
    with pytest.raises(TypeError, match="CarSpec"):
        World(road, [], rng)


def test_step_is_exactly_ten_substeps_of_2ms(road, sedan):
    w = make(road, [sedan])
    w.reset(np.array([[100.0, 0.0, 10.0]]), gears=0)
    x0 = float(w.x[0])
    w.step(np.zeros((1, 5)))
    assert w.time == pytest.approx(0.02, abs=1e-15)
    assert w.cur_lap_time[0] == pytest.approx(0.02, abs=1e-15)
    # coasting at 10 m/s on a straight: 0.2 m per tick (minus a hair of deceleration)
    assert float(w.x[0]) - x0 == pytest.approx(0.2, rel=1e-3)


def test_fuel_is_consumed_only_when_switched_on(road, sedan):
    on = make(road, [sedan], fuel=True)
    off = make(road, [sedan], fuel=False)
    u = np.array([[0.0, 1.0, 0.0, 1.0, 0.0]])
    for w in (on, off):
        w.reset(np.array([[100.0, 0.0, 5.0]]), gears=1)
    for _ in range(50):
        on.step(u)
        off.step(u)
    assert off.fuel[0] == sedan.fuel
    assert 0.0 < sedan.fuel - on.fuel[0] < 0.1    # |T| we factor 1e-7 dt: grams per second


def test_step_leaves_the_callers_controls_alone_whatever_their_layout(road, sedan):
    # World.step runs the tick on its own copy of the controls (a shift caps the throttle in
    # it: gear 1 -> 2 below); the caller's array, read-only or in Fortran order, is never
    # written and gives the same bits as a plain C array
    def run(make_u):
        w = make(road, [sedan] * 2, contact=True)
        w.reset([[100.0, 0.0, 5.0], [130.0, 0.0, 5.0]], gears=1)
        seen = []
        for t in range(30):
            u = make_u(np.array([[0.0, 1.0, 0.0, 1.0 if t < 5 else 2.0, 0.0]] * 2))
            before = np.array(u)
            w.step(u)
            assert np.array_equal(np.array(u), before)
            seen.append(w.state.copy())
        return np.array(seen)

    def read_only(u):
        u.flags.writeable = False
        return u

    plain = run(lambda u: u)
    assert np.array_equal(plain, run(read_only))
    assert np.array_equal(plain, run(np.asfortranarray))
    assert np.array_equal(plain, run(lambda u: u.tolist()))
    assert plain[-1, 0, L.S_GEAR] == 2.0 and plain[-1, 0, L.S_VX] > plain[5, 0, L.S_VX]
