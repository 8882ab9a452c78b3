"""The car kernel's speed work changes no bit: state hashes after N ticks equal the ones recorded
from the kernel that takes gravity along and across the road from the road heights under the
four wheels (issue 12, TORCS's SimCarUpdateForces; every scenario on a sloped or cambered road
moved: one car, six in contact, make_vec, the env), whose shift cap holds the throttle at 0.1 to the end of the driver call
(issue 12, TORCS's ctrl->accelCmd; every scenario that shifts moved) and whose speedZ reads the
body's vertical velocity (the env scenarios' observations moved), with TORCS's suspension
and the body's heave, roll and pitch (issue 12's suspension round) whose tyres run in SIMD lanes with `physics.elementary`'s atan, sincos and exp
(issue 13: a change of rounding only, see benchmarks/RESULTS.md "The four tyres in SIMD lanes")
and whose sub-step takes cos/sin(yaw - track heading) from the piece walk and the wings' climb
angle without atan2 (issue 13, rounding only: RESULTS "The car sub-step with three libm calls fewer";
six_contact and four_wd moved, the others kept their bits;
before that, the kernel with TORCS's spin step and averages above 3 m/s and static toe, issue 12,
and main's commit bb41c09).

Then (issue 12's sand round) the rolling resistance's speed clamp as TORCS's SimCarUpdate has it
(a crawling car loses v^2 of its speed a step): six_contact, four_wd, vec_traffic and env_ts
moved, one_car kept its bits.

Then (issue 13, session 9) the road relief's sines under the wheels by `physics.elementary`'s
sincos (within 2 ulp of libm's): the five scenarios above, all on madsim's tracks, kept their
bits; `rough_track` (g-track-1, road roughness under every wheel) was added, recorded from that
kernel (main's a5a8956 gives another digest: rounding only).

Then (issue 12, session 10) TORCS's shift inertia: a driven wheel keeps the engaged gear's
inertia while the clutch is open (it took the free wheel's): six_contact, four_wd, vec_traffic
and rough_track moved (they shift); one_car and env_ts (no shift) kept their bits.

Then (issue 13, session 10) the sub-step with fewer divisions (the tyre's 1 / (dx dv) and
1 / (s den), reciprocals of car constants in the car table, 1 / m once a sub-step): a change of
rounding only, every scenario moved (benchmarks/RESULTS.md, "The car sub-step, cuts that move
bits"). The digests below are of the two together (main after both merges).

Then (issue 12, session 10) bottoming, TORCS's SimCarCollideZ (`suspension.ground_contact`): no
scenario's wheel reaches its packers, all six kept their bits (tests/physics/test_bottoming.py
and the dirt-2 trace test cover the rule).

Then (issue 12, session 15) TORCS's barrier rule once per corner, tested on the box at the start
of the step (contact_kernels._barrier_corners): no scenario above reaches a barrier, so
`barrier` was added, recorded from that kernel: two cars steered into the walls of a 5 m street
at full throttle, hitting and then scraping them (each takes damage: asserted).

Each scenario hashes (sha256) the full float64 state array after its ticks (and, for the envs,
every observation and reward on the way). The expected digests were printed by this file's
`_digests()` run with PYTHONPATH pointing at that kernel (`python
tests/physics/test_bit_identity.py`); a change of the physics that is meant to move
trajectories updates them in the same commit and says so. Covered: one car following the line,
six cars in contact on a 5 m street with random controls (gears, reverse, brakes), a 4WD car
(155-DTM: centre viscous coupler, limited-slip axles) on random controls, make_vec with four
traffic cars per episode, a MadrasEnv with a T-S (PID) action space, and a TORCS car on a TORCS
track with road roughness.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np
import pytest

from madsim.cars import load_car
from madsim.physics.world import World
from madsim.tracks import load_track

EXPECTED = {
    "one_car": "6b76b6190821ba6f860b4fe64d85f182544b0ed7440938ac74819d0819586745",
    "six_contact": "2c25d65584b3d44991556169e7f3f750c3b6bbb5b4a6465ffe064af8c0be8fae",
    "four_wd": "e9f11b1b194666d081cd68e712023e1d93e4768cebd87946a9b098b7d8a800b0",
    "vec_traffic": "c8414e136d35e8e1fb94abd7be8c468e99d31ca8db2bc4d9fd085a48d6e1ebbd",
    "env_ts": "d34969b88b212353121c5b634e664601b482bee0684fbffdafc5f28366bc1f85",
    "rough_track": "2bbd0cadf966d09e65cbc162870ee08f203b434e13028ccede668817f84bfe6f",
    "barrier": "da46fea735074aa7a42198bb5dd516e44606a30dd5d336e11fa9a540d24d8cfd",
}


def _hash(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def _steer_to_centre(w) -> np.ndarray:
    """The steering command of a lane keeper towards the centre line (one value per car)."""
    angle = (w.track_heading - w.yaw + math.pi) % (2 * math.pi) - math.pi
    return np.clip((angle - 0.5 * w.n / (w.track.width / 2)) / 0.366519, -1, 1)


def one_car() -> str:
    w = World(load_track("madsim-road"), [load_car("madsim-sedan")], np.random.default_rng(0))
    w.reset(np.array([[10.0, 0.0, 20.0]]), gears=3)
    u = np.array([[0.0, 0.0, 0.0, 3.0, 0.0]])
    for _ in range(400):
        u[:, 0] = _steer_to_centre(w)
        u[:, 1] = np.clip((30.0 - w.vx) / 3.0, 0, 1)
        u[:, 2] = np.clip((w.vx - 30.0) / 3.0, 0, 1)
        w.step(u)
    return _hash(w.state)


def rough_track() -> str:
    """A real TORCS track and car: road roughness under every wheel (g-track-1's tarmac)."""
    w = World(load_track("g-track-1"), [load_car("car1-trb1")], np.random.default_rng(0))
    w.reset(np.array([[10.0, 1.0, 15.0]]), gears=2)
    u = np.array([[0.0, 0.0, 0.0, 2.0, 0.0]])
    for t in range(300):
        u[:, 0] = _steer_to_centre(w)
        u[:, 1] = np.clip((25.0 - w.vx) / 3.0, 0, 1)
        u[:, 3] = 2.0 if t < 100 else 3.0
        w.step(u)
    return _hash(w.state)


def barrier() -> str:
    """Two cars steered into the walls of madsim-street (5 m wide) at full throttle: a hit at
    18 / 25 m/s, then a scrape along each wall (TORCS's barrier rule, corner by corner)."""
    from madsim.physics import layout as L
    w = World(load_track("madsim-street"), [load_car("madsim-sedan"), load_car("madsim-gt")],
              np.random.default_rng(0))
    w.reset(np.array([[20.0, 1.0, 18.0], [60.0, -1.0, 25.0]]), gears=3)
    u = np.array([[0.6, 1.0, 0.0, 3.0, 0.0], [-0.8, 1.0, 0.0, 3.0, 0.0]])
    for _ in range(250):
        w.step(u)
    assert np.all(w.state[:, L.S["damage"]] > 0.0), "both cars must reach a wall"
    return _hash(w.state)


def _random_drive(cars: list[str], track: str, ticks: int, seed: int) -> str:
    n = len(cars)
    w = World(load_track(track), [load_car(c) for c in cars], np.random.default_rng(seed))
    w.reset(gears=1)
    rng = np.random.default_rng(seed)
    for _ in range(ticks):
        u = np.column_stack([rng.uniform(-1, 1, n), rng.uniform(0, 1, n), rng.uniform(0, 0.3, n),
                             rng.integers(-1, 4, n), np.zeros(n)])
        w.step(u)
    return _hash(w.state)


def six_contact() -> str:
    return _random_drive(["madsim-sedan", "madsim-gt", "madsim-buggy"] * 2, "madsim-street", 300, 7)


def four_wd() -> str:
    return _random_drive(["155-DTM", "155-DTM"], "madsim-road", 300, 3)


def vec_traffic() -> str:
    from madsim.envs.vector import make_vec
    cfg = {"server": {"tracks": ["madsim-road"], "cars": ["madsim-sedan"], "max_steps": 20000},
           "agents": [{"name": "learner", "target_speed": 16.0,
                       "observation": {"mode": "SingleAgentInTrafficObs"}}],
           "traffic": [{"behaviour": "ConstVel", "target_speed": 11.1, "lane": -0.5 if i % 2 else 0.5,
                        "initial_distance": [30.0 + 30 * i, 30.0 + 30 * i],
                        "initial_trackpos": [-0.5 if i % 2 else 0.5] * 2} for i in range(4)]}
    env = make_vec(cfg, num_envs=4)
    obs, _ = env.reset(seed=11)
    rng = np.random.default_rng(5)
    parts = [obs]
    for _ in range(150):
        a = rng.uniform(-0.3, 1.0, (4, 3)).astype(np.float32)
        a[:, 0] = np.clip(obs[:, 0] * np.pi * 2.0 - obs[:, 20] * 0.5, -1.0, 1.0)
        obs, rew, term, trunc, _ = env.step(a)
        parts += [obs, rew, term, trunc]
    parts.append(env.batch.state)
    env.close()
    return _hash(*parts)


def env_ts() -> str:
    from madsim.envs.madras_env import MadrasEnv
    cfg = {"server": {"tracks": ["madsim-road"], "cars": ["madsim-sedan"], "max_steps": 20000},
           "agents": [{"name": "learner", "action": {"space": "T-S"},
                       "observation": {"mode": "SingleAgentSimpleLapObs"}}]}
    env = MadrasEnv(cfg)
    obs, _ = env.reset(seed=2)
    rng = np.random.default_rng(9)
    parts = [obs]
    for _ in range(100):
        obs, rew, term, trunc, _ = env.step(
            rng.uniform(env.action_space.low, env.action_space.high).astype(np.float32))
        parts += [obs, np.float64(rew), np.bool_(term), np.bool_(trunc)]
        if term or trunc:
            obs, _ = env.reset()
    env.close()
    return _hash(*parts)


SCENARIOS = {"one_car": one_car, "rough_track": rough_track, "six_contact": six_contact, "four_wd": four_wd,
             "vec_traffic": vec_traffic, "env_ts": env_ts, "barrier": barrier}


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_state_bit_identical_to_recorded(name, request):
    if name == "four_wd":
        request.getfixturevalue("need_torcs")
    assert SCENARIOS[name]() == EXPECTED[name]


def _digests() -> None:
    for name, fn in SCENARIOS.items():
        print(f'    "{name}": "{fn()}",')


if __name__ == "__main__":
    _digests()
