"""Compiled traffic cars get only the rangefinder rays their behaviours read cast each tick
(`traffic_kernel.RAYS_READ`); every public read still sees all 19, bit for bit a full cast's.

Reference runs: the same episodes with the subset switched off (`COMPILED_KINDS` emptied, so
every car's 19 rays are cast as before)."""

from __future__ import annotations

import numpy as np
import pytest

from madsim.agents import traffic_kernel as tk
from madsim.agents.traffic import BEHAVIOURS as BUILT
from madsim.agents.traffic import TrafficBehaviour
from madsim.agents.traffic_fleet import TrafficFleet
from madsim.cars import load_car
from madsim.envs.madras_env import MadrasEnv
from madsim.envs.vector import make_vec
from madsim.physics.sensors import N_VALUES, O_ANGLE, O_OPP, O_SX, O_TPOS, O_TRACK, SensorSuite
from madsim.physics.world import World
from madsim.tracks import load_track

UNREAD = np.setdiff1d(np.arange(19), tk.RAYS_READ)
BEHAVIOURS = ("ConstVel", "RandomLaneSwitch", "SinusoidalSpeed", "RandomStopping")
STEPS = 200
ACTION = np.array([0.0, 0.5, 0.0], dtype=np.float32)


def config(noise: bool = False) -> dict:
    return {"server": {"tracks": ["madsim-road"], "cars": ["madsim-sedan"], "max_steps": 1000,
                       "observation_noise": noise},
            "agents": [{"name": "learner", "observation": {"mode": "SingleAgentInTrafficObs"}}],
            "traffic": [{"behaviour": b, "initial_distance": [15.0 + 12 * i] * 2,
                         "initial_trackpos": [-0.5 if i % 2 else 0.5] * 2}
                        for i, b in enumerate(BEHAVIOURS)]}


def bits(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64).view(np.uint64)


def _fleet_controls(sens: np.ndarray) -> np.ndarray:
    """Three ticks of the built-in behaviours (one each per row) on fixed sensors: controls and state."""
    n = sens.shape[0]
    fleet = TrafficFleet(n)
    for r in range(n):
        b = BUILT[BEHAVIOURS[r % len(BEHAVIOURS)]]()
        b.reset(np.random.default_rng(r), {"track_length": 1000.0, "track_width": 10.0, "index": r,
                                           "row": r, "car": "madsim-sedan", "tick_s": 0.02,
                                           "placement": (0.0, 0.0)})
        fleet.put(r, b)
    fleet.S[::2, tk.HALF_WIDTH] = 0.0        # half the cars measure the road's width (rays 0, 18)
    ctrl, out = np.zeros((n, 5)), []
    for _ in range(3):
        fleet.act(sens, ctrl, np.arange(n))
        out += [ctrl.copy(), fleet.S.copy()]
    return np.concatenate([o.ravel() for o in out])


def test_rays_read_are_the_rays_the_kernel_reads():
    """Unread rays NaN: the built-in behaviours' controls and state are unchanged (and a read
    ray NaN changes them: the comparison can fail)."""
    rng = np.random.default_rng(4)
    n = 32
    sens = np.zeros((n, N_VALUES))
    sens[:, O_TRACK:O_TRACK + 19] = rng.uniform(2.0, 150.0, (n, 19))
    sens[:, O_TRACK + 7:O_TRACK + 12] = rng.uniform(5.0, 15.0, (n, 5))   # an edge ahead: slow down
    sens[:, O_TPOS] = rng.uniform(-0.9, 0.9, n)
    sens[:, O_ANGLE] = rng.uniform(-0.3, 0.3, n)
    sens[:, O_SX] = rng.uniform(0.0, 80.0, n)
    sens[:, O_OPP:O_OPP + 36] = 200.0
    ref = _fleet_controls(sens)
    unread = sens.copy()
    unread[:, O_TRACK + UNREAD] = np.nan
    assert np.array_equal(bits(_fleet_controls(unread)), bits(ref))
    for j in tk.RAYS_READ:
        read = sens.copy()
        read[:, O_TRACK + j] = 1.0 if j in (0, 18) else 190.0
        assert not np.array_equal(bits(_fleet_controls(read)), bits(ref)), j


def test_suite_completes_a_partial_frame_bit_for_bit():
    track = load_track("madsim-road")
    world = World(track, [load_car("madsim-sedan")] * 4, np.random.default_rng(0))
    world.reset([[20.0, 0.5, 10.0], [40.0, -0.5, 10.0], [60.0, 0.0, 10.0], [80.0, 3.0, 10.0]])
    full, part = SensorSuite(world), SensorSuite(world)
    part.cast_only([0, 1, 3], tk.RAYS_READ)
    ref, frame = full.frame().flat, part.frame().flat
    track_part = frame[:, O_TRACK:O_TRACK + 19]
    for k in (0, 1, 3):
        assert np.isnan(track_part[k, UNREAD]).all()
        assert np.array_equal(bits(track_part[k, tk.RAYS_READ]), bits(ref[k, O_TRACK + tk.RAYS_READ]))
    assert np.array_equal(bits(frame[2]), bits(ref[2]))
    assert part.complete(frame, np.arange(4)) == 3 * UNREAD.size      # 12 rays a partial car
    assert np.array_equal(bits(frame), bits(ref))
    assert part.complete(frame, np.arange(4)) == 0
    part.cast_all()                                  # (both suites' focus now cooling down)
    assert np.array_equal(bits(part.frame().flat), bits(full.frame().flat))
    with pytest.raises(ValueError, match="noisy"):
        SensorSuite(world, noisy=True).cast_only([0], tk.RAYS_READ)


def _env_run(monkeypatch, full: bool, noise: bool = False):
    with monkeypatch.context() as m:
        if full:
            m.setattr(tk, "COMPILED_KINDS", ())
        env = MadrasEnv(config(noise))
        obs, _ = env.reset(seed=3)
        out, uncast = [obs], 0
        for _ in range(STEPS):
            obs, r, term, trunc, _ = env.step(ACTION)
            out += [obs, np.array([r])]
            uncast += int(np.isnan(env.core.frame.flat).sum())
        rows = env.core.rows
        return (np.concatenate([np.ravel(o).astype(np.float64) for o in out]),
                env.core.backend.world.state.copy(), env.core.frame.flat.copy(), rows, uncast)


def test_madras_env_casts_only_read_rays_and_reads_all(monkeypatch):
    part, full = _env_run(monkeypatch, False), _env_run(monkeypatch, True)
    assert part[4] == STEPS * len(BEHAVIOURS) * UNREAD.size       # the rays not cast, counted
    assert full[4] == 0
    assert np.array_equal(bits(part[0]), bits(full[0]))          # observations, rewards
    assert np.array_equal(bits(part[1]), bits(full[1]))          # the World's state
    assert np.array_equal(bits(part[2]), bits(full[2]))          # the frame after `rows`
    assert [dict(r) for r in part[3]] == [dict(r) for r in full[3]]
    assert all(np.isfinite(r["track"]).all() for r in part[3])


def test_noisy_env_casts_every_ray(monkeypatch):
    assert _env_run(monkeypatch, False, noise=True)[4] == 0


def test_python_traffic_sees_every_ray():
    """A foreign object's act(row) and a Python target(row) get all 19 rays."""
    seen = []

    class Recorder:
        def __init__(self, entry):
            pass

        def reset(self, rng, info):
            pass

        def act(self, row):
            seen.append(np.array(row["track"]))
            return 0.0, 0.3, 0.0, 1

    class UserTarget(TrafficBehaviour):          # a Python target: K_USER
        def target(self, row, t_s):
            seen.append(np.array(row["track"]))
            return 0.0, 10.0

    kinds = iter([Recorder, UserTarget] * 8)

    def factory(entry):
        cls = next(kinds)
        return cls(entry) if cls is Recorder else cls()

    env = MadrasEnv(config(), traffic_factory=factory)
    env.reset(seed=1)
    for _ in range(20):
        env.step(ACTION)
    assert len(seen) >= 20 * len(BEHAVIOURS) and all(np.isfinite(t).all() for t in seen)
    assert not np.isnan(env.core.frame.flat).any()


def _vec_run(monkeypatch, full: bool, n: int = 3):
    with monkeypatch.context() as m:
        if full:
            m.setattr(tk, "COMPILED_KINDS", ())
        env = make_vec(config(), num_envs=n)
        obs, _ = env.reset(seed=5)
        out, uncast = [obs], 0
        for _ in range(STEPS):
            obs, r, *_ = env.step(np.tile(ACTION, (n, 1)))
            out += [obs, r]
            uncast += int(np.isnan(env.batch.sensors).sum())
        filled = env.batch.complete()
        return (np.concatenate([np.ravel(o).astype(np.float64) for o in out]),
                env.batch.state.copy(), env.batch.sensors.copy(), uncast, filled)


def test_make_vec_casts_only_read_rays_and_completes(monkeypatch):
    part, full = _vec_run(monkeypatch, False), _vec_run(monkeypatch, True)
    n_partial = 3 * len(BEHAVIOURS)
    assert part[3] == STEPS * n_partial * UNREAD.size and full[3] == 0
    assert part[4] == n_partial * UNREAD.size and full[4] == 0
    assert np.array_equal(bits(part[0]), bits(full[0]))
    assert np.array_equal(bits(part[1]), bits(full[1]))
    assert np.array_equal(bits(part[2]), bits(full[2]))
