"""World.step's contact tick (`World.finish_tick` -> `world_tick.finish_contact`) against the
contact solver's public rule stepped by hand: one sub-step at a time, `ContactSolver.resolve`
after each, a hit's flags or-ed into the tick's, its car pairs (sorted) appended, its damage
added and the track positions refreshed. Same bits, flags and pairs every tick."""

from __future__ import annotations

import numpy as np

from madsim.cars import load_car
from madsim.physics import kernel
from madsim.physics import layout as L
from madsim.physics.world import DT, World
from madsim.physics.world_tick import race_positions
from madsim.tracks import load_track


def _pack(n: int) -> np.ndarray:
    """A packed group on madsim-speedway: cars side by side and nose to tail, the outer ones
    close to the walls."""
    lateral = np.array([-6.0, -1.0, 0.8, -0.2, 1.5, 6.2])[:n]
    along = np.array([0.0, 3.0, 6.0, 9.0, 12.0, 15.0])[:n]
    return np.column_stack([along, lateral, np.full(n, 25.0)])


def _by_hand(w: World, u: np.ndarray, wall, car, pairs) -> None:
    """One tick of World w the slow way: sub-steps with `resolve` after each."""
    st, solver = w.state, w._solver
    cols = tuple(st[:, c] for c in (L.S_X, L.S_Y, L.S_YAW, L.S_VXG, L.S_VYG, L.S_R))
    u = u.copy()
    kernel.tick_start(st, w._cp, 0, w.n_cars, w.track.length)
    wall[:] = False
    car[:] = False
    pairs.clear()
    for _ in range(10):
        kernel.advance(st, w._cp, w._curve_w, w._curve_t, w._pt, w._surf, w._tsc, u, 1, DT,
                       w.fuel_on)
        piece = st[:, L.S_PIECE].astype(np.int64)
        rep = solver.resolve(*cols, piece, DT)
        if rep.wall.any() or rep.car.any():
            wall |= rep.wall
            car |= rep.car
            pairs.extend(rep.pairs)
            kernel.add_damage(st, w._cp, np.asarray(rep.damage, dtype=np.float64))
            kernel.refresh(st, w._cp, w._pt, w._surf, w._tsc, True)
    race_positions(st, w.race_pos)


def test_contact_tick_equals_the_solver_rule_stepped_by_hand():
    track, car_spec = load_track("madsim-speedway"), load_car("madsim-sedan")
    n = 6
    worlds = [World(track, [car_spec] * n, np.random.default_rng(0), contact=True) for _ in range(2)]
    for w in worlds:
        w.reset(_pack(n), gears=3)
    fast, slow = worlds
    wall, car, pairs = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool), []
    rng = np.random.default_rng(5)
    seen_wall = seen_car = seen_pairs = 0
    for tick in range(120):
        u = np.column_stack([rng.uniform(-0.6, 0.6, n), rng.uniform(0, 1, n), np.zeros(n),
                             np.full(n, 3.0), np.zeros(n)])
        fast.step(u)
        _by_hand(slow, u, wall, car, pairs)
        assert np.array_equal(fast.state, slow.state), f"state parts at tick {tick}"
        assert np.array_equal(fast.contact_wall, wall) and np.array_equal(fast.contact_car, car)
        assert fast.contact_pairs == pairs, f"pairs at tick {tick}"
        assert np.array_equal(fast.race_pos, slow.race_pos)
        seen_wall += int(wall.any())
        seen_car += int(car.any())
        seen_pairs += len(pairs)
    # the run exercised what it checks: walls, cars, several pairs in a tick, damage
    assert seen_wall > 5 and seen_car > 5 and seen_pairs > 10
    assert fast.damage.sum() > 0
