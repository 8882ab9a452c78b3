"""MadrasEnv's compiled step (madsim.envs.env_tick) against the same env stepped stage by stage
in Python: the same observations, rewards, flags and infos, bit for bit, through the stages the
compiled call leaves to Python (traffic controls, contact near a car, sensor noise, a reward
written in Python) and through resets."""

import numpy as np
import pytest

from madsim.envs import env_tick
from madsim.envs.core import MadrasCore
from madsim.envs.madras_env import MadrasEnv
from tests.envs.test_vector import same, throttle_reward


def episode_log(cfg, steps, actions, *, compiled, seed=5):
    """Everything `steps` env steps return (resets included), and the Python stages counted."""
    env = MadrasEnv(cfg)
    stages = {}
    if compiled:
        run = env_tick.EnvTick.run

        def counting(self, first, tick0, ticks):
            stage = run(self, first, tick0, ticks)
            stages[stage] = stages.get(stage, 0) + 1
            return stage
        env_tick.EnvTick.run = counting
    else:
        original = MadrasCore._compiled_step
        MadrasCore._compiled_step = lambda self: None
    try:
        rng = np.random.default_rng(seed)
        log = [env.reset(seed=seed)]
        assert (env.core._compiled is not None) == compiled
        for _ in range(steps):
            out = env.step(actions(rng))
            log.append(out)
            if out[2] or out[3]:
                log.append(env.reset())
    finally:
        if compiled:
            env_tick.EnvTick.run = run
        else:
            MadrasCore._compiled_step = original
    return log, stages


def compare(cfg, steps, actions):
    ref, _ = episode_log(cfg, steps, actions, compiled=False)
    got, stages = episode_log(cfg, steps, actions, compiled=True)
    assert len(ref) == len(got)
    for i, (a, b) in enumerate(zip(ref, got)):
        same(list(a), list(b), f"[{i}]")
    return ref, stages


def sab(rng):
    return np.array([rng.uniform(-0.3, 0.3), rng.uniform(0.3, 1.0), -1.0], dtype=np.float32)


def test_among_traffic_with_contact_the_compiled_step_is_the_python_one():
    cfg = {"server": {"tracks": ["madsim-street"], "max_steps": 400},
           "agents": [{"observation": {"mode": "SingleAgentInTrafficObs"},
                       "rewards": {"Progress": 1.0, "Collision": 3.0, "SuccessfulOvertake": 1.0},
                       "dones": ["TimeOut", "OutOfTrack", "TurnBackward"]}],
           "traffic": [{"behaviour": "ConstVel", "target_speed": 4.0, "lane": 0.0,
                        "initial_distance": [12.0, 12.0]},
                       {"behaviour": "Parked", "initial_distance": [30.0, 40.0]}]}
    def straight(rng):      # the learner catches up with the ConstVel car within ~5 s
        return np.array([rng.uniform(-0.02, 0.02), rng.uniform(0.3, 1.0), -1.0], dtype=np.float32)

    log, stages = compare(cfg, 300, straight)
    assert stages.get(env_tick.TRAFFIC, 0) == 0        # built-ins that draw nothing: compiled
    assert stages.get(env_tick.STEP, 0) > 0            # contact near: the narrow phase
    assert any(step[4]["reward_terms"]["Collision"] != 0.0 for step in log if len(step) == 5)


def test_traffic_that_draws_as_it_drives_is_driven_from_python_in_the_same_order():
    cfg = {"server": {"tracks": ["madsim-road"], "max_steps": 150},
           "agents": [{"observation": {"mode": "SingleAgentInTrafficObs"}}],
           "traffic": [{"behaviour": "RandomLaneSwitch", "target_speed": 9.0},
                       {"behaviour": "SinusoidalSpeed"}, {"behaviour": "ConstVel"}]}
    log, stages = compare(cfg, 160, sab)
    assert stages.get(env_tick.TRAFFIC, 0) >= 160      # the fleet's act, every tick


def test_track_speed_actions_with_noise_and_manual_gear():
    cfg = {"server": {"tracks": ["madsim-oval"], "max_steps": 60, "observation_noise": True},
           "agents": [{"action": {"space": "TS"}, "gear": "manual", "pid": {"latency": 3},
                       "action_noise_std": 0.05,
                       "observation": {"mode": "TorcsObs", "normalised": True}}]}

    def ts(rng):
        return rng.uniform(-1.0, 1.0, 3).astype(np.float32)

    log, stages = compare(cfg, 70, ts)
    assert stages.get(env_tick.SENSE, 0) >= 3 * 70      # every tick's noise
    assert sum(1 for step in log if len(step) == 5 and (step[2] or step[3])) >= 1


def test_a_reward_written_in_python_is_called_by_the_compiled_step():
    with throttle_reward("TestEnvTickThrottle"):
        cfg = {"server": {"max_steps": 30},
               "agents": [{"rewards": {"TestEnvTickThrottle": 2.0, "Progress2": 1.0}}]}
        log, stages = compare(cfg, 40, sab)
    assert stages.get(env_tick.OUTCOME, 0) >= 40
    assert all(step[4]["reward_terms"]["TestEnvTickThrottle"] > 0.0
               for step in log if len(step) == 5)


def test_manual_gear_without_noise_is_taken_in_the_compiled_call():
    cfg = {"server": {"tracks": ["madsim-oval"], "max_steps": 80},
           "agents": [{"gear": "manual", "action": {"normalised": True}}]}

    def sab_gear(rng):
        a = sab(rng)
        return np.array([*a, rng.choice([-0.5714285714285714, 0.0, 0.4285714285714286])])

    log, stages = compare(cfg, 90, sab_gear)
    assert stages == {env_tick.DONE: 90}               # every step one call, from the action


ACTIONS = [[0.1, 0.5, -1.0], (0.1, 2.0, -3.0), np.array([0.1, 0.5, -1.0], dtype=np.float32),
           np.array([1, 1, 0]), np.arange(6.0)[::2] / 5.0, np.float64([0.1, 0.5, -1.0]),
           np.array([0.1, 0.5, 1.5], dtype=np.float16), np.array(["0.1", "0.5", "-1"]),
           [0.1, np.nan, -1.0], np.array([0.1, 0.5, -np.inf], dtype=np.float32), [0.1, 0.5],
           np.zeros((1, 3)), 0.5, "abc", [0.1, None, 1.0]]


def test_the_compiled_call_takes_and_refuses_actions_as_the_python_step_does():
    """Each action of ACTIONS (lists, tuples, other dtypes, strided views, out of the Box,
    non-finite, wrong shapes, not numeric) between steps of a drive: the same results, the same
    ValueError, and a refused action changes nothing."""
    cfg = {"server": {"max_steps": 400}, "agents": [{"action": {"normalised": True}}]}

    def drive(compiled):
        env = MadrasEnv(cfg)
        if not compiled:
            env.core._compiled_step = lambda: None
        log = [env.reset(seed=3)]
        for a in ACTIONS:
            try:
                log.append(env.step(a))
            except ValueError as exc:
                log.append(str(exc))
            log.append(env.step(np.array([0.0, 0.6, -1.0])))
        assert (env.core._compiled is not None) == compiled
        return log

    ref, got = drive(False), drive(True)
    assert sum(isinstance(x, str) for x in ref) == 7
    for i, (a, b) in enumerate(zip(ref, got)):
        same(a if isinstance(a, str) else list(a), b if isinstance(b, str) else list(b), f"[{i}]")


@pytest.mark.parametrize("cfg", [
    {"server": {"tick_schedule": "torcs"}, "agents": [{}]},
    {"agents": [{"observation": {"mode": "Image", "image_size": 16}}]},
])
def test_where_it_does_not_apply_the_env_steps_in_python(cfg):
    env = MadrasEnv(cfg)
    env.reset(seed=0)
    assert env.core._compiled is None
    obs, *_ = env.step(env.action_space.sample())
    assert obs.shape == env.observation_space.shape
