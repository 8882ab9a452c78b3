"""MadrasEnv's contact ticks finished inside the compiled step (`world_tick.contact_direct`,
pymunk consulted from compiled code through `physics.pymunk_direct`) against the same env
with them handed to Python (`World.finish_tick` after each near sub-step, the path before):
bit-identical observations, rewards, World state and contact counters, with the compiled
consultations doing (nearly) all of the work."""

from __future__ import annotations

import numpy as np
import pytest

from madsim.envs.backends import LocalBackend
from madsim.envs.env_tick import F_DIRECT
from madsim.envs.madras_env import MadrasEnv
from madsim.physics.pymunk_direct import D_CALLS, D_READY

pytest.importorskip("pymunk")

STEPS = 1500


def _config() -> dict:
    """benchmarks/bench_env.py's `traffic` case: a lane-keeping learner at 16 m/s that runs into
    the 11.1 m/s traffic ahead and keeps pushing it (contact in about 40 % of its ticks)."""
    agent = {"observation": {"mode": "SingleAgentInTrafficObs"},
             "action": {"space": "SAB", "normalised": True}, "pid": {"latency": 5},
             "target_speed": 16.0, "dones": ["TimeOut", "OutOfTrack", "TurnBackward"]}
    traffic = [{"behaviour": "ConstVel", "target_speed": 11.1,
                "initial_distance": [20.0 + 40 * i, 20.0 + 40 * i]} for i in range(9)]
    return {"server": {"tracks": ["madsim-road"], "max_steps": 5000}, "agents": [agent],
            "traffic": traffic}


def _run(direct: bool, small_buffer: bool = False):
    env = MadrasEnv(_config(), backend=LocalBackend())
    obs, _ = env.reset(seed=0)
    core = env.core
    world = core.backend.world
    if not direct:
        core._compiled.flags[F_DIRECT] = 0
    solver = world._solver
    out = []
    for _ in range(STEPS):
        if small_buffer and solver.direct[D_READY]:
            # the response's pair buffer too small: the next compiled consultation hands its
            # arbiters to Python (D_NARROWED), which grows it
            small_buffer = False
            solver._pair_out = np.zeros((1, 2), dtype=np.int64)
            solver.arrays_version += 1
            world._set_contact_table()
            core._compiled._set_args()
        steer = max(-1.0, min(1.0, 3.0 * float(obs[0]) - 0.4 * float(obs[20])))
        obs, r, term, trunc, info = env.step(np.array([steer, 0.2, -1.0]))
        out.append((obs.tobytes(), r, term, trunc))
        assert not (term or trunc)
    stats = world._solver.stats
    compiled = int(world._solver.direct[D_CALLS])
    state = world.state.copy()
    env.close()
    return out, state, stats, compiled


def test_compiled_contact_ticks_equal_the_python_ones():
    fast, fast_state, fast_stats, fast_compiled = _run(True)
    slow, slow_state, slow_stats, slow_compiled = _run(False)
    assert slow_compiled == 0
    assert fast_stats["consults"] > 100                    # contact all along the run
    assert fast_compiled >= 0.9 * fast_stats["consults"]   # nearly all of it compiled
    assert fast_stats == slow_stats
    assert len(fast) == len(slow)
    for k, (a, b) in enumerate(zip(fast, slow)):
        assert a == b, f"step {k}"
    np.testing.assert_array_equal(fast_state, slow_state)
    grown, grown_state, grown_stats, _ = _run(True, small_buffer=True)
    assert grown == slow and grown_stats == slow_stats
    np.testing.assert_array_equal(grown_state, slow_state)
