"""WorldBatch (the engine under make_vec): each slot advances exactly like its own World.

Reference: one `World` + `SensorSuite` per slot, as LocalBackend builds them; every state
column, sensor value and contact flag must be equal (no tolerance) after every tick, with
slots on different tracks, several cars per slot in contact, and slots left out by the mask.
"""

import numpy as np
import pytest

from madsim.cars import load_car
from madsim.envs.backends import RANGEFINDER_ANGLES_DEG
from madsim.physics import layout as L
from madsim.physics.world_batch import WorldBatch
from madsim.physics.sensors import SensorSuite
from madsim.physics.world import World
from madsim.tracks import load_track

ROAD, OVAL = load_track("madsim-road"), load_track("madsim-oval")
SEDAN, GT = load_car("madsim-sedan"), load_car("madsim-gt")
# (track, cars, placements (s m, n m, speed m/s)): slot 2 starts with two cars 0.5 m apart,
# slots 0, 2 and 3 put a car on the same spot of the same track
SLOTS = [(ROAD, [SEDAN], [[100.0, 0.0, 20.0]]),
         (OVAL, [SEDAN, GT], [[50.0, 0.0, 25.0], [58.0, 0.3, 10.0]]),
         (ROAD, [GT, SEDAN, SEDAN], [[100.0, 0.0, 20.0], [100.5, 0.0, 18.0], [110.0, -2.0, 30.0]]),
         (ROAD, [SEDAN], [[100.0, 0.0, 20.0]])]


def reference(track, cars, where):
    world = World(track, cars, np.random.default_rng(0))
    suite = SensorSuite(world)
    for i in range(world.n_cars):
        suite.set_angles(i, RANGEFINDER_ANGLES_DEG)
    world.reset(np.array(where))
    suite.reset()
    return world, suite, suite.frame()


def start(batch, slot, track, cars, where):
    batch.start(slot, (track.name, tuple(c.name for c in cars)), track, cars, np.array(where))


def controls(rng, n_cars, lone):
    u = np.zeros((n_cars, 5))
    u[:, 0] = rng.uniform(-0.05, 0.05, n_cars) if lone else rng.uniform(-1.0, 1.0, n_cars)
    u[:, 1] = rng.uniform(0.0, 1.0, n_cars)
    u[:, 2] = rng.uniform(0.0, 0.2, n_cars)
    u[:, 3] = rng.integers(1, 4, n_cars)
    return u


def assert_slot_equals(batch, slot, world, frame):
    rows = batch.rows(slot)
    assert np.array_equal(batch.state[rows], world.state), f"slot {slot}: state"
    assert np.array_equal(batch.sensors[rows], frame.flat), f"slot {slot}: sensors"
    assert np.array_equal(batch.race_pos[rows], world.race_pos), f"slot {slot}: racePos"


def test_slots_advance_exactly_like_their_own_worlds():
    batch = WorldBatch(len(SLOTS), 3, angles_deg=RANGEFINDER_ANGLES_DEG, focus=True)
    refs = []
    for e, (track, cars, where) in enumerate(SLOTS):
        start(batch, e, track, cars, where)
        refs.append(list(reference(track, cars, where)))
    batch.sense(np.ones(len(SLOTS), dtype=bool))
    rng = np.random.default_rng(1)
    car_contacts = 0
    for tick in range(150):
        mask = rng.random(len(SLOTS)) < 0.8
        for e, ref in enumerate(refs):
            assert_slot_equals(batch, e, ref[0], ref[2])
            if mask[e]:
                u = controls(rng, ref[0].n_cars, lone=ref[0].n_cars == 1)
                batch.controls[batch.rows(e)] = u
                ref[0].step(u)
                ref[2] = ref[1].frame()
        batch.step(mask)
        for e, (world, _, frame) in enumerate(refs):
            assert_slot_equals(batch, e, world, frame)
            if mask[e]:
                hits = world.contact_wall | world.contact_car
                assert np.array_equal(batch.hits[batch.rows(e)], hits), (tick, e)
        car_contacts += bool(refs[2][0].contact_car.any())
    assert car_contacts > 0                          # slot 2's cars did touch
    # the lone cars never came near a barrier or another car: no contact solver for them
    assert batch._solver[0] is None and batch._solver[3] is None
    assert batch._solver[2] is not None


def test_a_restarted_slot_reuses_its_solver_and_still_matches_a_fresh_world():
    batch = WorldBatch(1, 3, angles_deg=RANGEFINDER_ANGLES_DEG)
    track, cars, where = SLOTS[2]
    rng = np.random.default_rng(5)
    for episode in range(2):
        start(batch, 0, track, cars, where)
        batch.sense(np.ones(1, dtype=bool))
        world, suite, _ = reference(track, cars, where)
        for _ in range(40):
            u = controls(rng, 3, lone=False)
            batch.controls[batch.rows(0)] = u
            world.step(u)
            batch.step(np.ones(1, dtype=bool))
            assert_slot_equals(batch, 0, world, suite.frame())
        assert world.contact_car.any() or world.state[:, L.S_DAMAGE].any()
    assert batch.solvers_built == 1             # built once for the kind, handed back, reused


def test_non_finite_controls_name_the_slot_and_car():
    batch = WorldBatch(2, 2)
    for e in range(2):
        start(batch, e, ROAD, [SEDAN, SEDAN], [[100.0, 0.0, 0.0], [80.0, 0.0, 0.0]])
    batch.controls[3, 2] = np.inf
    with pytest.raises(ValueError, match="slot 1 car 1 brake"):
        batch.step(np.ones(2, dtype=bool))
    with pytest.raises(ValueError, match="1..2 per slot"):
        start(batch, 0, ROAD, [SEDAN] * 3, [[0.0, 0.0, 0.0]] * 3)


def test_threads_give_bit_identical_slots():
    batches = [WorldBatch(len(SLOTS), 3, threads=threads) for threads in (False, True)]
    for batch in batches:
        for e, (track, cars, where) in enumerate(SLOTS):
            start(batch, e, track, cars, where)
        batch.sense(np.ones(len(SLOTS), dtype=bool))
    rng = np.random.default_rng(3)
    for _ in range(30):
        mask = rng.random(len(SLOTS)) < 0.8
        u = np.concatenate([controls(rng, 3, lone=False) for _ in SLOTS])
        for batch in batches:
            batch.controls[:] = u
            batch.step(mask)
        assert np.array_equal(batches[0].state, batches[1].state)
        assert np.array_equal(batches[0].sensors, batches[1].sensors)
        assert np.array_equal(batches[0].hits, batches[1].hits)
