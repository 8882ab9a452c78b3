"""Whole ticks: a car advanced a whole tick in one kernel call when the contact broad phase
provably has nothing to find on the way, bit-identical to one sub-step per call with the broad
phase after each.

`tick_clear`'s bound is checked against the closed form of the broad phase's own tests (the
cached wall clearance over the clearance gain, the neighbour-list rebuild distance, the pair
gap less both bounding circles); the World is checked against the same World with whole ticks
switched off (the sub-step path), with contacts happening.
"""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest

import madsim.physics.world as W
from madsim.cars import load_car
from madsim.physics import layout as L
from madsim.physics.contact import ContactSolver
from madsim.physics import contact_kernels
from madsim.physics.contact_kernels import C_GAIN, C_RAD, P_MOVE_CAP, REBUILD_M, tick_clear
from madsim.tracks import load_track

HL, HW, MASS, IZZ = 2.3, 0.95, 1200.0, 2000.0


@pytest.fixture(scope="module")
def oval():
    return load_track("madsim-oval")


def test_tick_clear_is_the_broad_phase_bound(oval):
    n = 2
    solver = ContactSolver(oval, np.full(n, HL), np.full(n, HW), np.full(n, MASS), np.full(n, IZZ))
    s = np.array([10.0, 40.0])
    x, y, _, yaw = oval.pose(s, np.zeros(n))
    x, y, yaw = (np.ascontiguousarray(a, dtype=np.float64) for a in (x, y, yaw))
    args = solver.broad_phase_args
    assert solver.broad_phase_kernel(x, y, yaw, oval.piece_at(s).astype(np.int64), *args) == 0
    geo, bar, cars, prm, wall_cache, vref, pairs, meta, flags, slack = args
    # just measured: moved = 0, turn = 0, so path p is allowed while gain p < clearance, p below
    # the move cap and REBUILD_M, and the gap less 2 p beyond both circles
    gap = math.hypot(x[1] - x[0], y[1] - y[0]) - cars[0, C_RAD] - cars[1, C_RAD]
    limit = min(wall_cache[0, 3] / cars[0, C_GAIN], wall_cache[1, 3] / cars[1, C_GAIN],
                prm[P_MOVE_CAP], REBUILD_M, gap / 2.0)
    assert limit > 0.05

    def clear(path, turn=0.0):
        return tick_clear(x, y, yaw, cars, prm, wall_cache, vref, pairs, meta,
                          np.full(n, path), np.full(n, turn))

    assert clear(0.0) and clear(0.99 * limit)
    assert not clear(1.01 * limit)
    assert not clear(math.nan) and not clear(0.0, math.nan)
    # turning uses the clearance at the rate of the bounding radius
    turn_limit = min(wall_cache[i, 3] / cars[i, C_RAD] for i in range(n))
    assert clear(0.0, 0.99 * turn_limit) and not clear(0.0, 1.01 * turn_limit)
    # cars closer than their circles plus both paths: not clear
    x2 = x.copy()
    x2[1], y2 = x[0], y.copy()
    y2[1] = y[0] + cars[0, C_RAD] + cars[1, C_RAD] + 0.5
    assert not tick_clear(x2, y2, yaw, cars, prm, wall_cache, vref, pairs, meta,
                          np.full(n, 0.3), np.zeros(n))


_advance_car = W.kernel.advance_car
_near_after = contact_kernels._near_after_sub_step


@numba.njit
def _sub_steps_only(st, cp, cw, ct, pt, surf, tsc, u, k0, nsub, dt, fuel_on, x, y, yaw, piece, bp,
                    near, snap, path, turn):
    """The sub-step path (what `advance_until_near` did before whole ticks): one sub-step of
    every car, then the broad phase, until it finds something."""
    for k in range(k0, nsub):
        for i in range(st.shape[0]):
            _advance_car(st, i, cp, cw, ct, pt, surf, tsc, u, 1, dt, fuel_on)
        if _near_after(st, x, y, yaw, piece, bp, near):
            return k + 1
    return nsub


def _drive(track_name, n, place, ticks, rng_seed=5, noise=0.3, sub_steps_only=False):
    """A World driven by a noisy lane keeper with TORCS's 10/11 sub-step schedule; returns it
    and its state before the last tick."""
    track = load_track(track_name)
    w = World(track, [load_car("madsim-sedan")] * n, np.random.default_rng(0), contact=True)
    w.reset(place, gears=2)
    if sub_steps_only:      # every part of every tick on the sub-step path (not step_world's)
        w._stepper = _sub_steps_only
        w._stepper_serial = None
        w.tick_args = None
    rng = np.random.default_rng(rng_seed)
    before = None
    for _ in range(ticks):
        ang = np.angle(np.exp(1j * (w.state[:, L.S_YAW] - w.state[:, L.S_THEAD])))
        steer = np.clip(-2.0 * ang - 0.1 * w.state[:, L.S_N] + rng.normal(0.0, noise, n), -1, 1)
        gear = np.clip(1 + w.state[:, L.S_VX] // 12, 1, 5)
        u = np.column_stack([steer, rng.uniform(0.5, 1.0, n), np.zeros(n), gear, np.zeros(n)])
        before = w.state.copy()
        w.step(u, substeps=int(rng.integers(10, 12)))
    return w, before


World = W.World


def _traffic_place(n, gap_m=5.2):
    """Two cars nose to tail, gap_m between centres (they bump), and the others spread out
    ahead: split ticks."""
    s = np.r_[0.0, gap_m, 40.0 + 30.0 * np.arange(n - 2)]
    return np.column_stack([s, np.zeros(n), np.r_[24.0, 20.0, np.full(n - 2, 20.0)]])


@pytest.mark.parametrize("track_name, n, noise, packed", [("madsim-street", 1, 2.0, True),
                                                          ("madsim-speedway", 6, 1.0, True),
                                                          ("madsim-speedway", 6, 0.3, False)])
def test_whole_ticks_equal_substeps(track_name, n, noise, packed):
    place = None
    if n > 1 and packed:     # a packed group: car-car contacts and neighbour-list rebuilds
        place = np.column_stack([np.arange(n) * 9.0, (np.arange(n) % 2 - 0.5) * 2.5,
                                 np.full(n, 20.0)])
    elif n > 1:              # two bumping cars among others clear of everything: split ticks
        place = _traffic_place(n)
    whole, _ = _drive(track_name, n, place, 400, noise=noise)
    sub, _ = _drive(track_name, n, place, 400, noise=noise, sub_steps_only=True)
    assert np.array_equal(whole.state, sub.state)
    assert whole._solver.stats == sub._solver.stats
    assert whole.damage.sum() > 0              # contacts happened on the way
    assert np.isfinite(whole.state).all()


def test_open_road_takes_whole_ticks():
    # a lone car on the speedway's straight: the last tick went in one call (the whole-tick
    # scratch holds the tick's start state, written only when the prediction passed)
    w, before = _drive("madsim-speedway", 1, None, 30)
    assert np.array_equal(w._snap[:, :L.N_STATE], before)
    assert w._solver.stats["consults"] == 0


def test_split_tick_steps_far_cars_in_one_call(oval):
    # cars 0 and 1 within each other's reach, three clear of everything: split_tick takes the
    # tick (returns 10, not 0) and ends where ten sub-steps with the broad phase after each end
    n = 5
    worlds = []
    for _ in range(2):
        w = World(oval, [load_car("madsim-sedan")] * n, np.random.default_rng(0), contact=True)
        w.reset(_traffic_place(n), gears=2)
        w.step(np.tile([0.0, 0.3, 0.0, 2.0, 0.0], (n, 1)), substeps=1)   # the neighbour list
        worlds.append(w)
    u = np.tile([0.0, 0.6, 0.0, 2.0, 0.0], (n, 1))
    results = []
    for w, stepper in zip(worlds, (contact_kernels.split_tick, _sub_steps_only)):
        cols = w._contact_cols
        k = stepper(w.state, w._cp, w._curve_w, w._curve_t, w._pt, w._surf, w._tsc, u.copy(), 0,
                    10, W.DT, False, cols[0], cols[1], cols[2], w._piece_i,
                    w._solver.broad_phase_args, w._near, w._snap, w._path, w._turn)
        results.append((k, w._near[0], w.state.copy(), w._solver.broad_phase_args[4].copy()))
    (k_split, near_split, st_split, cache_split), (k_sub, near_sub, st_sub, cache_sub) = results
    assert k_split == k_sub == 10 and near_split == near_sub == 0
    assert np.array_equal(st_split, st_sub) and np.array_equal(cache_split, cache_sub)


def test_split_tick_undoes_a_lazy_car_that_went_farther_than_predicted(oval):
    # predicted paths of 1 mm: the far cars are lazy, go farther, and the tick is given back
    # untouched (state, controls, wall clearances) for the caller to step every car. Cars 0
    # and 1 are 5 m apart, closer than their bounding circles (2 x 2.56 m): near even standing
    n = 5
    w = World(oval, [load_car("madsim-sedan")] * n, np.random.default_rng(0), contact=True)
    w.reset(_traffic_place(n, gap_m=5.0), gears=2)
    w.step(np.tile([0.0, 0.3, 0.0, 2.0, 0.0], (n, 1)), substeps=1)
    u = np.tile([0.0, 0.6, 0.0, 3.0, 0.0], (n, 1))         # a shift: its cap writes into u
    bp = w._solver.broad_phase_args
    before = (w.state.copy(), u.copy(), bp[4].copy())
    cols = w._contact_cols
    w._snap[:] = 0.0
    k = contact_kernels.split_predicted(
        w.state, w._cp, w._curve_w, w._curve_t, w._pt, w._surf, w._tsc, u, 0, 10, W.DT, False,
        cols[0], cols[1], cols[2], w._piece_i, bp, w._near, w._snap, np.full(n, 1e-3),
        np.full(n, 1e-3))
    assert k == 0
    assert np.array_equal(w._snap[:, :L.N_STATE], before[0])   # it split: the start kept
    assert np.array_equal(w._snap[:, L.N_STATE:], before[1])
    assert np.array_equal(w.state, before[0]) and np.array_equal(u, before[1])
    assert np.array_equal(bp[4], before[2])


def test_whole_tick_undo_restores_the_controls_a_shift_capped(oval):
    # a lone car whose yaw rate (20 rad/s) is beyond what the prediction assumes (capped at
    # YAW_RATE_MAX), with a wall clearance the predicted turn fits and the real one does not: the
    # whole tick runs, fails its check and is given back. Its shift (gear 2 -> 3) started at the
    # 1st sub-step and capped the accel command from the 2nd on; the retried sub-step must run
    # on the tick's own controls, as the sub-step path's first sub-step does
    w = World(oval, [load_car("madsim-sedan")], np.random.default_rng(0), contact=True)
    w.reset(np.array([[100.0, 0.0, 20.0]]), gears=2)
    w.step(np.array([[0.0, 0.3, 0.0, 2.0, 0.0]]), substeps=1)
    st = w.state
    st[0, L.S_R] = 20.0
    bp = w._solver.broad_phase_args
    cars, prm, wall_cache = bp[2], bp[3], bp[4]
    nsub, span = 10, 10 * W.DT
    v = math.hypot(st[0, L.S_VXG], st[0, L.S_VYG])
    path = span * (v + contact_kernels.PREDICT_ACCEL * span) + contact_kernels.WHOLE_EPS_M
    turn = span * W.kernel.YAW_RATE_MAX + contact_kernels.WHOLE_EPS_M
    wall_cache[0, :3] = st[0, L.S_X], st[0, L.S_Y], st[0, L.S_YAW]
    wall_cache[0, 3] = cars[0, C_GAIN] * path + cars[0, C_RAD] * turn + 1e-3
    assert path < prm[P_MOVE_CAP]
    u = np.array([[0.0, 0.8, 0.0, 3.0, 0.0]])
    ref_st, ref_u = st.copy(), u.copy()
    _advance_car(ref_st, 0, w._cp, w._curve_w, w._curve_t, w._pt, w._surf, w._tsc, ref_u, 1, W.DT,
                 False)                                   # the sub-step path's 1st sub-step
    k = contact_kernels.whole_tick_rows(st, np.int64(0), np.int64(1), w._cp, w._curve_w,
                                        w._curve_t, w._pt, w._surf, w._tsc, u, nsub, W.DT, False,
                                        *bp[2:8], w._snap, w._path, w._turn)
    assert k == 1
    assert w._snap[0, L.S_GEAR] == 2.0      # the whole tick was tried (its start kept) ...
    assert ref_st[0, L.S_GEAR] == 3.0 and ref_u[0, L.U_ACCEL] == 0.8    # ... the shift began
    assert np.array_equal(st, ref_st)       # main: the retried sub-step ran on accel 0.1
    assert np.array_equal(u, ref_u)
