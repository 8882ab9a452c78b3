"""Damage after the finish (docs/physics.md, "Damage after the finish"; TORCS 1.3.7's simuv2
collide.cpp adds wall, pit-wall, car-car and bottoming damage only while the car's
RM_CAR_STATE_FINISH is clear). A car that has crossed the start line more than `race_laps` times
has finished: the same hit costs it no points, the hit itself (velocities) is unchanged; the
racing car beside it still takes its points. World and WorldBatch share the rule."""

from __future__ import annotations

import numpy as np
import pytest

from madsim.physics import layout as L
from madsim.physics.world import World

STILL = np.zeros((1, 5))


def _rigid(ph):
    """The sedan with its packers at full extension: a wheel touching the road is on them."""
    car = ph.sedan()
    return ph.sedan(susp_packers=car.susp_course / car.susp_bellcrank)


def _wall_run(track, car, laps_done, race_laps):
    """A car at 20 m/s heading 0.4 rad to the right, 3 m from the right barrier; 60 ticks."""
    w = World(track, [car], np.random.default_rng(0), race_laps=race_laps)
    w.state[0, L.S_LAPS] = laps_done
    w.place(0, 100.0, -7.0, yaw_rel=-0.4, speed=20.0)
    hit_tick = None
    for k in range(60):
        w.step(STILL)
        if hit_tick is None and w.contact_wall[0]:
            hit_tick = k
            v_after_hit = (w.vx_global[0], w.vy_global[0])
    assert hit_tick is not None, "the car never reached the barrier"
    return w, hit_tick, v_after_hit


def test_a_finished_car_hits_a_barrier_without_damage(straight, ph):
    """race_laps 2: after 2 crossings (lap 2 under way) the hit costs points; after 3 (finished)
    none, with the same impact tick and the same velocities after it (to 1e-6: damage raises the
    drag by damage/10000 in the sub-steps after the hit); without race_laps (a race without end)
    the finished-looking car takes the points too."""
    track, car = straight(width=20.0), ph.sedan()
    racing, k_r, v_r = _wall_run(track, car, 2, 2)
    finished, k_f, v_f = _wall_run(track, car, 3, 2)
    endless, _, _ = _wall_run(track, car, 3, None)
    assert racing.damage[0] > 0.0 and endless.damage[0] == racing.damage[0]
    assert finished.damage[0] == 0.0
    assert k_f == k_r and v_f == pytest.approx(v_r, rel=1e-6)
    assert racing.finished.tolist() == [False] and finished.finished.tolist() == [True]
    assert endless.finished.tolist() == [False] and endless.race_laps is None and racing.race_laps == 2


def test_a_finished_car_lands_on_its_packers_without_damage(straight, ph):
    """The rigid sedan dropped 0.5 m: racing, it takes bottoming points; finished (laps done 2 of
    race_laps 1), none, and its vertical speed after the landing is the same bit for bit."""
    track = straight()
    runs = []
    for laps_done in (1, 2):
        w = ph.world_at(track, _rigid(ph), race_laps=1)
        w.state[0, L.S_LAPS] = laps_done
        for _ in range(50):
            w.step(STILL)
        w.state[0, L.S_Z] += 0.5
        for _ in range(50):
            w.step(STILL)
        runs.append(w)
    assert runs[0].damage[0] > 0.0
    assert runs[1].damage[0] == 0.0
    assert runs[1].state[0, L.S_VZ] == runs[0].state[0, L.S_VZ]


def _rear_end(track, car, batch=False):
    """Car 0 at 15 m/s 6 m behind car 1 at rest; car 0 has finished (3 crossings of a 2-lap
    race, the last at 40 s), car 1 is racing (2, its last crossing at 30 s: it finishes at its
    next). Returns the damage of both after 60 ticks (and the World or the batch's rows for
    comparison)."""
    where = np.array([[100.0, 0.0, 15.0], [106.0, 0.0, 0.0]])
    laps = np.array([3.0, 2.0])
    clock = {L.S_TIME: [50.0, 50.0], L.S_LAPSTART: [40.0, 30.0]}
    if batch:
        from madsim.physics.world_batch import WorldBatch
        b = WorldBatch(1, 2, race_laps=2)
        b.start(0, ("rear", (car.name, car.name)), track, [car, car], where)
        b.state[b.rows(0), L.S_LAPS] = laps
        for col, values in clock.items():
            b.state[b.rows(0), col] = values
        mask = np.ones(1, dtype=bool)
        for _ in range(60):
            b.step(mask)
        return b.state[b.rows(0)].copy()
    w = World(track, [car, car], np.random.default_rng(0), race_laps=2)
    w.reset(where)
    w.state[:, L.S_LAPS] = laps
    for col, values in clock.items():
        w.state[:, col] = values
    for _ in range(60):
        w.step(np.zeros((2, 5)))
    return w


def test_car_car_damage_only_for_the_car_still_racing(straight, ph):
    """A finished car runs into a racing one: the racing car takes its car-car points, the
    finished one none (TORCS gates each car of the pair on its own finish flag); WorldBatch's
    slot equals the World bit for bit."""
    track, car = straight(), ph.sedan()
    w = _rear_end(track, car)
    assert w.damage[1] > 0.0
    assert w.damage[0] == 0.0
    assert w.finished.tolist() == [True, False]
    assert np.array_equal(_rear_end(track, car, batch=True), w.state)


@pytest.mark.parametrize("bad", [-1, 1.5, "2", True])
def test_bad_race_laps_are_rejected(straight, ph, bad):
    with pytest.raises(ValueError, match="race_laps"):
        World(straight(), [ph.sedan()], np.random.default_rng(0), race_laps=bad)


def test_the_servers_world_takes_the_race_laps():
    """`madsim serve --laps N` builds its Worlds with race_laps N (the server steps that World)."""
    from madsim.cli import make_world_factory

    w = make_world_factory("madsim-oval", ["car1-trb1"], 2, race_laps=3)(0)
    assert w.race_laps == 3 and w.finished.tolist() == [False, False]
    w.state[0, L.S_LAPS] = 4
    assert w.finished.tolist() == [True, False]
    assert make_world_factory("madsim-oval", ["car1-trb1"], 1)(0).race_laps is None


@pytest.mark.parametrize("speed, brake", [(40.0, 0.05), (20.0, 0.0)])
def test_a_finished_car_goes_on_at_torcs_slow_pace(straight, ph, speed, brake):
    """simuv2's ctrlCheck: once finished, the accel command is at most 0.2 and, above 30 m/s
    forward, the brake at least 0.05. A finished car at full throttle in 4th gear drives bit for
    bit like a racing one given (accel 0.2, brake 0.05) at 40 m/s, (0.2, 0) at 20 m/s."""
    track, car = straight(), ph.sedan()
    worlds = []
    for laps_done in (3, 2):
        w = ph.world_at(track, car, speed=speed, gear=4, race_laps=2)
        w.state[0, L.S_LAPS] = laps_done
        worlds.append(w)
    full, capped = np.array([[0.0, 1.0, 0.0, 4.0, 0.0]]), np.array([[0.0, 0.2, brake, 4.0, 0.0]])
    for _ in range(25):
        worlds[0].step(full)
        worlds[1].step(capped)
    same = np.ones(L.N_STATE, dtype=bool)
    same[[L.S_LAPS, L.S_DIST]] = False          # the crossings differ, and the distance raced
    assert np.array_equal(worlds[0].state[:, same], worlds[1].state[:, same])
    assert (worlds[0].vx[0] < speed) == (brake > 0.0)
