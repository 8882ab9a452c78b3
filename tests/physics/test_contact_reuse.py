"""Barrier spaces reused across contact solvers on the same Track object (a reset onto a track
used before): a World on a reused space steps bit-identically to one on a freshly built space,
wall hits and car-car contacts included, and a space comes back empty."""

from __future__ import annotations

import gc

import numpy as np
import pymunk.batch as pmb
import pytest

from madsim.cars import load_car
from madsim.physics import layout as L
from madsim.physics.contact import _POOLS
from madsim.physics.world import World
from madsim.tracks import load_track

TRACK = "madsim-street"      # narrow: wall hits and car-car contacts within 300 ticks
N = 6
PLACE = np.column_stack([np.arange(N) * 9.0, (np.arange(N) % 2 - 0.5) * 2.5, np.full(N, 20.0)])


def _world(track):
    w = World(track, [load_car("madsim-sedan")] * N, np.random.default_rng(0), contact=True)
    w.reset(PLACE, gears=2)
    return w, np.random.default_rng(5)


def _tick(w, rng, noise=1.0):
    """One tick of a noisy lane keeper (TORCS's 10/11 sub-step schedule)."""
    ang = np.angle(np.exp(1j * (w.state[:, L.S_YAW] - w.state[:, L.S_THEAD])))
    steer = np.clip(-2.0 * ang - 0.1 * w.state[:, L.S_N] + rng.normal(0.0, noise, N), -1, 1)
    gear = np.clip(1 + w.state[:, L.S_VX] // 12, 1, 5)
    u = np.column_stack([steer, rng.uniform(0.5, 1.0, N), np.zeros(N), gear, np.zeros(N)])
    w.step(u, substeps=int(rng.integers(10, 12)))


def _arbiters(space) -> int:
    buf = pmb.Buffer()
    pmb.get_space_arbiters(space, pmb.ArbiterFields.BODY_A_ID, buf)
    return np.frombuffer(buf.int_buf(), dtype=np.int64).size


def _drive(track, ticks=300):
    w, rng = _world(track)
    w.hits = np.zeros(2, dtype=np.int64)       # car-ticks with a wall / a car contact
    for _ in range(ticks):
        _tick(w, rng)
        w.hits += w.contact_wall.sum(), w.contact_car.sum()
    return w


@pytest.fixture(scope="module")
def fresh():
    """The reference: a World on a new Track object (its own, freshly built barrier space)."""
    return _drive(load_track(TRACK))


def test_reused_space_steps_bit_identically(fresh):
    track = load_track(TRACK)
    first = _drive(track)                      # builds the track's space, leaves it with history
    space = first._solver._space
    assert space is not None and first.damage.sum() > 0
    first.reset()                              # gives the space back, emptied
    assert track in _POOLS and any(s is space for s, _ in _POOLS[track].free)
    assert all(b.body_type == b.STATIC for b in space.bodies) and _arbiters(space) == 0
    again = _drive(track)
    assert again._solver._space is space       # took the used space, did not build one
    assert np.array_equal(again.state, fresh.state)
    assert np.array_equal(again.damage, fresh.damage)
    assert again._solver.stats == fresh._solver.stats
    assert np.all(fresh.hits >= 5)             # wall hits and car-car contacts on the way


def test_two_worlds_on_one_track_at_once(fresh):
    # interleaved: each holds its own space while in contact; results as if alone
    track = load_track(TRACK)
    (a, ra), (b, rb) = _world(track), _world(track)
    for _ in range(300):
        _tick(a, ra)
        _tick(b, rb)
    assert a._solver._space is not b._solver._space
    for w in (a, b):
        assert np.array_equal(w.state, fresh.state)
    assert len(_POOLS[track].free) == 0
    del a
    gc.collect()                               # a dropped solver gives its space back
    assert len(_POOLS[track].free) == 1
    assert all(body.body_type == body.STATIC for body in _POOLS[track].free[0][0].bodies)


def test_narrow_reads_what_pymunk_batch_reports():
    """ContactSolver.narrow calls pymunk.batch's C iterators itself (request structs made once,
    views over the arbiter arrays kept while their capacity stays): after every narrow phase of
    300 ticks of six cars in contact its arrays equal pymunk.batch's own get_space_arbiters on
    the same space, through the arrays' growth and cars joining and leaving the space."""
    from madsim.physics import contact as C

    w, rng = _world(load_track(TRACK))
    solver = w._solver
    seen = {"calls": 0, "arbiters": 0, "capacities": set()}
    narrow = solver._narrow

    def checked(x, y, yaw, dt):
        ints, floats = narrow(x, y, yaw, dt)
        buf = pmb.Buffer()
        pmb.get_space_arbiters(solver._space, C._ARB_FIELDS, buf)
        np.testing.assert_array_equal(ints, np.frombuffer(buf.int_buf(), dtype=np.int64))
        np.testing.assert_array_equal(floats, np.frombuffer(buf.float_buf(), dtype=np.float64))
        seen["calls"] += 1
        seen["arbiters"] = max(seen["arbiters"], ints.size // C._ARB_INTS)
        seen["capacities"].add(solver._arb_views[0])
        return ints, floats

    solver._narrow = checked
    for _ in range(300):
        _tick(w, rng)
    assert seen["calls"] > 50 and seen["arbiters"] >= 2
    assert len(seen["capacities"]) >= 2           # pymunk grew its arrays: the views were redone
    assert solver.stats["pymunk_steps"] == seen["calls"]
