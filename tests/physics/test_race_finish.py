"""TORCS's finish of a race of several cars (docs/physics.md, "The finish of a race";
`madsim.physics.finish`; TORCS 1.3.7's race engine, ReManage and ReSortCars, read in the public
source). A car finishes when its start-line crossings exceed the race's laps, or at its first
crossing after another car has finished; a finished car's crossings are not counted (laps, last
and best lap time stay, the lap timer and the distance raced go on) and its next one ends the
race, every car then finished. World and WorldBatch share the rule (it runs at each tick's start
with the slipstream); the SCR server ends the race there (tests/net/test_server.py)."""

from __future__ import annotations

import numpy as np
import pytest

from madsim.physics import layout as L
from madsim.physics.sensors import SensorSuite
from madsim.physics.world import World
from madsim.tracks import load_track

TRACK = "madsim-oval"     # the start line on a long straight


@pytest.fixture(scope="module")
def oval():
    return load_track(TRACK)


def _race(track, cars, before_line, laps, lap_start, race_laps, *, time_s=100.0, speed=20.0,
          contact=False):
    """Cars on the start straight `before_line` m (N,) before the line at `speed` m/s, 4 m apart
    across, in neutral; laps (N,) crossings done, the last at lap_start (N,) s; race clock time_s."""
    n = len(cars)
    w = World(track, cars, np.random.default_rng(0), contact=contact, race_laps=race_laps)
    lateral = 4.0 * (np.arange(n) - (n - 1) / 2.0)
    w.reset(np.column_stack([track.length - np.asarray(before_line, float), lateral, np.full(n, speed)]))
    _set_clock(w.state, laps, lap_start, time_s)
    return w


def _set_clock(st, laps, lap_start, time_s):
    st[:, L.S_LAPS] = laps
    st[:, L.S_LAPSTART] = lap_start
    st[:, L.S_TIME] = time_s


def _coast(w, ticks):
    """Step with every car coasting straight ahead; returns (laps, finished) after each tick."""
    u = np.zeros((w.n_cars, 5))
    seen = []
    for _ in range(ticks):
        w.step(u)
        seen.append((w.laps.tolist(), w.finished.tolist()))
    return seen


def test_the_car_behind_finishes_at_its_next_crossing_after_the_leaders_finish(oval, ph):
    """race_laps 2: the leader (2 crossings done) finishes when it crosses; the car behind (1
    crossing done, 50 m back) is flagged at its own next crossing, its lap 2 only begun (TORCS:
    `_raceState == RM_RACE_FINISHING`); then every car has finished and the race is over. Before
    this rule the car behind raced on (it needed 3 crossings)."""
    car = ph.sedan()
    w = _race(oval, [car, car], [10.0, 60.0], [2, 1], [40.0, 60.0], 2)
    seen = _coast(w, 200)
    states = [s for i, s in enumerate(seen) if i == 0 or s != seen[i - 1]]
    assert states == [([2, 1], [False, False]), ([3, 1], [True, False]), ([3, 2], [True, True])]
    assert w.race_over
    # the car behind's crossing counted as TORCS's does: a lap more, its lap time from 60 s
    assert w.state[1, L.S_LASTLAP] == pytest.approx(w.state[1, L.S_LAPSTART] - 60.0)


def test_a_car_crossing_in_the_same_tick_after_the_leaders_finish_is_finished_from_the_next(oval, ph):
    """Both cross within one tick (0.1 m apart at 20 m/s), the leader first: the car behind is
    finished at the next tick's start (its crossing came at or after the leader's finish)."""
    car = ph.sedan()
    w = _race(oval, [car, car], [0.05, 0.15], [2, 1], [40.0, 60.0], 2)
    w.step(np.zeros((2, 5)))
    assert w.laps.tolist() == [3, 2] and w.finished.tolist() == [True, False]
    w.step(np.zeros((2, 5)))
    assert w.finished.tolist() == [True, True] and w.race_over


def test_a_finished_cars_next_crossing_is_not_counted_and_ends_the_race(oval, ph):
    """race_laps 1: car 0 finished (2 crossings) crosses again: its laps (2), last and best lap
    times stay, its lap timer runs on from its finish, its distance raced goes on across the line
    without a jump; every car is then finished (car 1, 800 m back, from the next tick's start:
    TORCS's "allow one lap after finish for the first car")."""
    car = ph.sedan()
    w = _race(oval, [car, car], [10.0, 800.0], [2, 1], [40.0, 60.0], 1)
    w.state[0, L.S_LASTLAP] = w.state[0, L.S_BESTLAP] = 35.0
    suite = SensorSuite(w)
    before = suite.frame()
    u = np.zeros((2, 5))
    dist = []
    for _ in range(40):
        w.step(u)
        f = suite.frame()
        dist.append(f.distRaced[0])
    assert w.laps.tolist() == [2, 1]
    assert w.state[0, L.S_LASTLAP] == 35.0 and w.state[0, L.S_BESTLAP] == 35.0
    assert f.lastLapTime[0] == before.lastLapTime[0] == 35.0
    assert f.curLapTime[0] == pytest.approx(100.0 + 40 * 0.02 - 40.0, abs=1e-9)    # from 40 s on
    steps = np.diff(dist)
    assert np.all((steps > 0.2) & (steps < 0.5))          # 20 m/s x 0.02 s, no lap's jump
    assert w.finished.tolist() == [True, True] and w.race_over


def test_one_car_race_ends_at_its_finish_and_its_laps_stop(oval, ph):
    """One car, race_laps 1: finished at its second crossing (race over); crossing again
    (placed back before the line) counts nothing more."""
    car = ph.sedan()
    w = _race(oval, [car], [5.0], [1], [0.0], 1)
    _coast(w, 30)
    assert w.laps.tolist() == [2] and w.finished.tolist() == [True] and w.race_over
    last = w.state[0, L.S_LASTLAP]
    w.place(0, oval.length - 5.0, 0.0, speed=20.0)
    _coast(w, 30)
    assert w.laps.tolist() == [2] and w.state[0, L.S_LASTLAP] == last


def test_the_finish_rule_brings_the_slow_pace_and_the_damage_gate_to_the_car_behind(oval, ph):
    """After both finished by the rule above, the car behind at full throttle drives bit for bit
    as the same car given accel 0.2 in a race without end (TORCS's slow pace), and a drop of
    0.5 m on its packers costs it nothing where the racing car takes bottoming points."""
    car = ph.sedan()
    rigid = ph.sedan(susp_packers=car.susp_course / car.susp_bellcrank)
    worlds = [_race(oval, [rigid, rigid], [10.0, 60.0], [2, 1], [40.0, 60.0], laps) for laps in (2, None)]
    for w in worlds:
        _coast(w, 200)
    assert worlds[0].finished.tolist() == [True, True] and not worlds[1].finished.any()
    assert np.array_equal(worlds[0].state, worlds[1].state)        # coasting: no cap bites
    full, capped = np.zeros((2, 5)), np.zeros((2, 5))
    full[:, 1], capped[:, 1] = 1.0, 0.2
    full[:, 3] = capped[:, 3] = 2
    for _ in range(50):
        worlds[0].step(full)
        worlds[1].step(capped)
    assert np.array_equal(worlds[0].state, worlds[1].state)
    for w in worlds:
        w.state[1, L.S_Z] += 0.5
        _coast(w, 50)
    assert worlds[0].damage[1] == 0.0 and worlds[1].damage[1] > 0.0


def test_world_batch_slot_follows_the_world(oval, ph):
    """The rule of the first test in a WorldBatch slot (contact on) equals the World bit for bit,
    finish flags included."""
    from madsim.physics.world_batch import WorldBatch
    car = ph.sedan()
    w = _race(oval, [car, car], [10.0, 60.0], [2, 1], [40.0, 60.0], 2, contact=True)
    b = WorldBatch(1, 2, race_laps=2)
    where = np.array([[oval.length - 10.0, -2.0, 20.0], [oval.length - 60.0, 2.0, 20.0]])
    b.start(0, ("finish", (car.name, car.name)), oval, [car, car], where)
    rows = b.rows(0)
    _set_clock(b.state[rows], [2, 1], [40.0, 60.0], 100.0)
    mask = np.ones(1, dtype=bool)
    for _ in range(200):
        w.step(np.zeros((2, 5)))
        b.step(mask)
    assert w.finished.tolist() == [True, True]
    assert np.array_equal(b.state[rows], w.state)
    assert np.array_equal(b._cp[rows, L.C_FINISH], w._cp[:, L.C_FINISH])


def test_reset_starts_the_race_again(oval, ph):
    car = ph.sedan()
    w = _race(oval, [car, car], [10.0, 800.0], [2, 1], [40.0, 60.0], 1)
    _coast(w, 30)
    assert w.race_over and w.race_laps == 1
    w.reset()
    assert not w.race_over and w.finished.tolist() == [False, False] and w.race_laps == 1
