"""TORCS's slipstream (car spec 4.6): a car in another's wake, or just ahead of one, has less
body drag; factors against the closed form, and the effect on speed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from madsim.physics import World
from madsim.physics import layout as L


def cd(car):
    return car.scx2 - car.wing_kx[1] * math.sin(car.wing_angle[1])


def pair(road, sedan, gap, speed=40.0, n_follow=0.0):
    w = World(road, [sedan, sedan], np.random.default_rng(0), contact=False)
    w.reset(np.array([[500.0 + gap, 0.0, speed], [500.0, n_follow, speed]]), gears=4)
    w.step(np.array([[0, 0, 0, 4, 0], [0, 0, 0, 4, 0]], dtype=float))
    return w


@pytest.mark.parametrize("gap", [5.0, 20.0])
def test_factors_follow_the_closed_form(road, sedan, gap):
    w = pair(road, sedan, gap)
    # set at the start of the tick from the reset poses: distance = gap (a straight), vx = 40
    k = w.state[:, L.S_DRAGK]
    c = cd(sedan)
    assert k[1] == pytest.approx(1.0 - math.exp(-2.0 * gap / (c * 40.0)), rel=1e-5)     # in the wake
    assert k[0] == pytest.approx(1.0 - 0.15 * math.exp(-8.0 * gap / (c * 40.0)), rel=1e-5)   # ahead


def test_no_slipstream_beside_slow_or_alone(road, sedan):
    assert np.all(pair(road, sedan, 0.0, n_follow=3.0).state[:, L.S_DRAGK] == 1.0)   # side by side
    assert np.all(pair(road, sedan, 10.0, speed=9.0).state[:, L.S_DRAGK] == 1.0)      # below 10 m/s
    w = World(road, [sedan], np.random.default_rng(0), contact=False)
    w.reset(np.array([[500.0, 0.0, 40.0]]), gears=4)
    w.step(np.array([[0, 0, 0, 4, 0]], dtype=float))
    assert w.state[0, L.S_DRAGK] == 1.0


def test_the_follower_coasts_faster(road, sedan):
    w = pair(road, sedan, 8.0)
    u = np.array([[0, 0, 0, 4, 0], [0, 0, 0, 4, 0]], dtype=float)
    for _ in range(50):
        w.step(u)
    assert w.vx[1] > w.vx[0] + 0.05       # less drag in the wake: the gap closes


def test_many_cars_sorted_along_the_track_give_the_all_pairs_factors(road, sedan):
    # 24 cars (> SLIP_ALL_PAIRS: the sorted scan) in two lanes and a few spun or slow ones
    from madsim.physics import kernel
    n = 24
    rng = np.random.default_rng(3)
    w = World(road, [sedan] * n, np.random.default_rng(0), contact=False)
    s = np.sort(rng.uniform(0.0, 600.0, n))
    w.reset(np.column_stack([s, np.where(np.arange(n) % 2, 2.0, -2.0), rng.uniform(5.0, 45.0, n)]), gears=4)
    st = w.state
    kernel.slipstream(st, w._cp, 0, n, road.length)
    c = cd(sedan)
    ref = np.ones(n)
    for i in range(n):
        if st[i, L.S_VX] <= 10.0:
            continue
        heading = math.atan2(st[i, L.S_VYG], st[i, L.S_VXG])
        for j in range(n):
            if j == i or st[j, L.S_VX] <= 10.0:
                continue
            if abs((st[i, L.S_YAW] - st[j, L.S_YAW] + math.pi) % (2 * math.pi) - math.pi) >= 0.1396:
                continue
            dx, dy = st[i, L.S_X] - st[j, L.S_X], st[i, L.S_Y] - st[j, L.S_Y]
            d = math.hypot(dx, dy)
            off = abs((heading - math.atan2(dy, dx) + math.pi) % (2 * math.pi) - math.pi)
            if off > 2.9671:
                ref[i] = min(ref[i], 1.0 - math.exp(-2.0 * d / (c * st[j, L.S_VX])))
            elif off < 0.1396:
                ref[i] = min(ref[i], 1.0 - 0.15 * math.exp(-8.0 * d / (c * st[i, L.S_VX])))
    assert np.any(ref < 0.99)
    np.testing.assert_allclose(st[:, L.S_DRAGK], ref, rtol=0, atol=1e-12)
