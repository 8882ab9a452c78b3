"""MadrasParallelEnv (PettingZoo): API test, agents leaving, communication, determinism."""

from pathlib import Path

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

from madsim.envs import config as config_module
from madsim.envs.config import ConfigError
from madsim.envs.parallel_env import MadrasParallelEnv

CONFIGS = Path(config_module.__file__).parent / "configs"
EXAMPLES = sorted(p.stem for p in CONFIGS.glob("*.yml"))


class Stand:
    """Stand-in traffic behaviour (the real ones are issue 6): stand still, brakes on."""

    def __init__(self, entry):
        self.entry = entry

    def reset(self, rng, info):
        pass

    def act(self, row):
        return 0.0, 0.0, 1.0, 1


def two_cars(agent_a, agent_b, **server):
    base = {"observation": {"mode": "Fields", "fields": ["speedX", "distRaced"]}}
    return {"server": {"max_steps": 100000, **server},
            "agents": [{"name": "a", **base, **agent_a}, {"name": "b", **base, **agent_b}]}


@pytest.mark.parametrize("name", EXAMPLES)
def test_pettingzoo_parallel_api_test_passes_on_every_example(name):
    env = MadrasParallelEnv(CONFIGS / f"{name}.yml", traffic_factory=Stand)
    if env.config.curriculum is not None:               # a stage that draws traffic
        env.curriculum_progress = env.config.curriculum.stages[-1].start
    parallel_api_test(env, num_cycles=200)


def test_spaces_are_per_agent_and_stable():
    env = MadrasParallelEnv(CONFIGS / "bottleneck_two_learners.yml", traffic_factory=Stand)
    assert env.possible_agents == ["first", "second"] and env.agents == []
    for agent in env.possible_agents:
        # SingleAgentInTrafficObs (60) + one message: the other's T-S action (2 values)
        assert env.observation_space(agent).shape == (62,)
        assert env.action_space(agent).shape == (2,)
        assert env.action_space(agent) is env.action_space(agent)
    obs, infos = env.reset(seed=0)
    assert env.agents == ["first", "second"] and set(obs) == set(infos) == {"first", "second"}
    assert infos["second"]["car"] == "madsim-gt" and infos["first"]["traffic_count"] == 2
    assert all(obs[a] in env.observation_space(a) for a in env.agents)


def test_an_agent_that_is_done_leaves_while_the_other_drives_on():
    env = MadrasParallelEnv(two_cars({"dones": ["TimeOut"]}, {"dones": ["RaceOver"]}, max_steps=100))
    env.reset(seed=0)
    go = np.array([0.0, 1.0, -1.0])
    for t in range(100):
        obs, rew, term, trunc, info = env.step({"a": go, "b": go})
        assert set(obs) == set(rew) == set(term) == set(trunc) == set(info) == {"a", "b"}
    assert trunc["a"] and not term["a"] and info["a"]["dones"] == ("TimeOut",)
    assert not trunc["b"] and env.agents == ["b"]
    car_a = env.core.agent_rows["a"]
    speed_then = env.core.rows[car_a]["speedX"]
    for _ in range(100):
        obs, rew, term, trunc, info = env.step({"b": go, "a": go})   # a's action is ignored
        assert set(obs) == {"b"}
    assert speed_then > 20.0 and env.core.rows[car_a]["speedX"] < 1.0  # braked to a stop
    assert obs["b"][0] * 50.0 > 20.0                                  # b accelerates on



def test_episode_end_any_ends_every_learner_with_the_first_done():
    """server.episode_end "any" (MADRaS's multi-agent env: done["__all__"] = any agent done,
    every agent's PID sub-step loop stopped with it): a times out at tick 100, in the middle
    of a T-S step of 5 ticks; b, which would drive on, ends terminated on that same tick."""
    ts = {"action": {"space": "TS"}, "pid": {"latency": 5}, "target_speed": 20.0}
    env = MadrasParallelEnv(two_cars({**ts, "dones": ["TimeOut"]}, {**ts, "dones": ["RaceOver"]},
                                     max_steps=98, episode_end="any"))
    env.reset(seed=0)
    go = np.array([0.0, 1.0])
    for _ in range(19):
        env.step({"a": go, "b": go})
    obs, rew, term, trunc, info = env.step({"a": go, "b": go})
    assert trunc["a"] and info["a"]["dones"] == ("TimeOut",) and info["a"]["ticks"] == 3
    assert term["b"] and not trunc["b"] and info["b"]["dones"] == ("EpisodeEnd",)
    assert info["b"]["ticks"] == 3 and env.agents == []
    with pytest.raises(ConfigError, match="episode_end"):
        MadrasParallelEnv(two_cars({}, {}, episode_end="first"))

def test_a_missing_or_unknown_action_is_refused():
    env = MadrasParallelEnv(two_cars({}, {}))
    env.reset(seed=0)
    with pytest.raises(ValueError, match="no action for live agent 'b'"):
        env.step({"a": np.zeros(3)})
    with pytest.raises(ValueError, match="unknown agent 'c'"):
        env.step({"a": np.zeros(3), "b": np.zeros(3), "c": np.zeros(3)})


def test_agents_must_share_the_ticks_per_step():
    with pytest.raises(ConfigError, match="same number of ticks"):
        MadrasParallelEnv(two_cars({"action": {"space": "TS"}, "pid": {"latency": 5}}, {}))


def test_peer_actions_arrive_in_the_receivers_observation():
    """b hears a's action (peerActions) with a buffer of 3: the last three actions of a, oldest
    first, zeros before a has acted; the action is the one a chose (clipped), not the noisy one."""
    cfg = two_cars({"action_noise_std": 0.5}, {"communication": {"senders": ["a"],
                                                                 "variables": ["peerActions"],
                                                                 "buffer_length": 3}})
    env = MadrasParallelEnv(cfg)
    assert env.observation_space("b").shape == (2 + 3 * 3,)
    obs, _ = env.reset(seed=0)
    assert np.array_equal(obs["b"][2:], np.zeros(9))
    sent = [np.array([0.1, 0.2, -0.3]), np.array([-0.4, 0.5, -0.6]), np.array([0.7, 9.0, -0.9])]
    for i, a in enumerate(sent):
        obs, *_ = env.step({"a": a, "b": np.zeros(3)})
    heard = obs["b"][2:].reshape(3, 3)
    expected = np.array([s.clip(-1, 1) for s in sent], dtype=np.float32)
    assert np.array_equal(heard, expected)


def test_same_seed_same_actions_identical_in_the_parallel_env():
    rng = np.random.default_rng(0)
    actions = [{n: rng.uniform(-1, 1, 2) for n in ("first", "second")} for _ in range(40)]

    def episode():
        env = MadrasParallelEnv(CONFIGS / "bottleneck_two_learners.yml", traffic_factory=Stand)
        out = [env.reset(seed=21)[0]]
        for acts in actions:
            if not env.agents:
                break
            out.append(env.step({n: acts[n] for n in env.agents})[:4])
        return out

    first, second = episode(), episode()
    assert len(first) == len(second)
    for x, y in zip(first, second):
        flat_x = x if isinstance(x, dict) else {i: d for i, d in enumerate(x)}
        flat_y = y if isinstance(y, dict) else {i: d for i, d in enumerate(y)}
        assert repr(flat_x) == repr(flat_y)


def test_step_after_the_episode_is_over_asks_for_reset():
    env = MadrasParallelEnv(two_cars({"dones": ["TimeOut"]}, {"dones": ["TimeOut"]}, max_steps=2))
    env.reset(seed=0)
    for _ in range(2):
        env.step({n: np.zeros(3) for n in env.agents})
    assert env.agents == []
    with pytest.raises(RuntimeError, match="reset"):
        env.step({})
