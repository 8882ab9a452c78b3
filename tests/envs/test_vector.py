"""make_vec / MadrasVectorEnv: the same episodes as N separate MadrasEnvs, float for float.

The reference is gymnasium's own SyncVectorEnv over MadrasEnvs (same config, same seeds, same
autoreset mode): observations, rewards, terminations, truncations and the whole info
structure (reset infos with their seeds, step infos, final_obs / final_info) must be equal,
with no tolerance, over enough steps that episodes end and autoreset several times.
"""

import contextlib

import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv

import madsim.agents.rewards as rewards_module
from madsim.envs.backends import LocalBackend
from madsim.envs.config import ConfigError
from madsim.envs.madras_env import MadrasEnv
from madsim.envs.vector import MadrasVectorEnv, make_vec


def same(a, b, path="."):
    """a == b exactly, recursively through dicts and object arrays (dtypes included)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and sorted(a) == sorted(b), (path, sorted(a), sorted(b))
        for key in a:
            same(a[key], b[key], f"{path}/{key}")
    elif isinstance(a, (tuple, list)) and any(isinstance(x, (np.ndarray, dict)) for x in a):
        assert type(a) is type(b) and len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            same(x, y, f"{path}[{i}]")
    elif isinstance(a, np.ndarray) and a.dtype == object:
        assert isinstance(b, np.ndarray) and b.dtype == object and a.shape == b.shape, path
        for i, (x, y) in enumerate(zip(a, b)):
            same(x, y, f"{path}[{i}]")
    elif isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and (a.dtype, a.shape) == (b.dtype, b.shape), \
            (path, a.dtype, b.dtype, a.shape, b.shape)
        assert np.array_equal(a, b), (path, a, b)
    else:
        assert type(a) is type(b) and a == b, (path, a, b)


def sab_actions(rng, n):
    """Normalised S-A-B: each episode steers its own way (episode i: (i - 1) / 8, plus noise),
    mostly throttle, no brake: episodes end at different times, by leaving the road, turning
    round or timing out."""
    a = np.empty((n, 3), dtype=np.float32)
    a[:, 0] = (np.arange(n) - 1.0) / 8.0 + rng.uniform(-0.2, 0.2, n)
    a[:, 1] = rng.uniform(0.2, 1.0, n)
    a[:, 2] = -1.0
    return a


def compare(cfg, n, steps, *, seed=11, mode=AutoresetMode.NEXT_STEP, actions=sab_actions,
            factory=None, **vec_kwargs):
    """Step both vector envs with the same actions; returns the reference's reset infos of
    every episode start seen and the number of episodes that ended. vec_kwargs go to make_vec
    and, for contact / fuel / damage, to the reference's LocalBackend."""
    physics = {k: v for k, v in vec_kwargs.items() if k in ("contact", "fuel", "damage")}
    ref = SyncVectorEnv([lambda: MadrasEnv(cfg, traffic_factory=factory,
                                           backend=LocalBackend(**physics))
                         for _ in range(n)], autoreset_mode=mode)
    vec = make_vec(cfg, n, autoreset_mode=mode, traffic_factory=factory, **vec_kwargs)
    expected, got = ref.reset(seed=seed), vec.reset(seed=seed)
    same(expected, got)
    starts, ended = [expected[1]], 0
    rng = np.random.default_rng(seed)
    for t in range(steps):
        a = actions(rng, n)
        expected, got = ref.step(a), vec.step(a)
        for name, x, y in zip(("obs", "reward", "terminated", "truncated", "infos"), expected, got):
            try:
                same(x, y)
            except AssertionError as exc:
                raise AssertionError(f"step {t}: {name} differs: {exc}") from None
        ended += int(np.sum(expected[2] | expected[3]))
        if "seed" in expected[4]:
            starts.append(expected[4])
    ref.close()
    vec.close()
    return starts, ended


def test_episodes_match_separate_envs_through_next_step_autoresets_on_several_tracks():
    cfg = {"server": {"tracks": ["madsim-road", "madsim-oval", "madsim-street"],
                      "cars": ["madsim-sedan", "madsim-gt"], "order": "random",
                      "max_steps": 150},
           "agents": [{"name": "learner"}]}
    starts, ended = compare(cfg, 4, 230)
    assert ended >= 5
    first = starts[0]
    assert first["seed"].tolist() == [11, 12, 13, 14]   # SyncVectorEnv's seed + i
    assert len(set(first["track"])) >= 2                # episodes on different tracks at once
    later = [s for s in starts[1:]]
    assert later and all(s["_seed"].sum() < 4 for s in later)   # autoresets are per episode


def test_same_step_autoreset_with_traffic_and_a_steps_curriculum_matches():
    cfg = {"server": {"tracks": ["madsim-road", "madsim-oval"], "traffic_count": [0, 2],
                      "order": "random", "max_steps": 70, "init_wait": 2},
           "agents": [{"name": "learner", "observation": {"mode": "SingleAgentInTrafficObs"},
                       "rewards": {"Progress": 1.0, "Progress3": 1.0, "RankOne": 1.0,
                                   "Task": {"scale": 2.0, "position": 2},
                                   "SuccessfulOvertake": 1.0, "AvgSpeed": 1.0,
                                   "Collision": 3.0},
                       "dones": ["TimeOut", "Collision", "OutOfTrack", "Rank1", "RaceOver"]}],
           "traffic": [{"behaviour": "ConstVel", "target_speed": 8.0, "lane": -0.5},
                       {"behaviour": "Parked", "initial_distance": [0.0, 40.0]}],
           "curriculum": {"unit": "steps", "stages": [
               {"start": 0, "traffic_count": [0, 0]},
               {"start": 40, "target_speed": 20.0, "action_noise_std": 0.1},
               {"start": 90, "observation_noise": True}]}}
    starts, ended = compare(cfg, 3, 150, mode=AutoresetMode.SAME_STEP)
    assert ended >= 3
    assert max(int(s["traffic_count"].max()) for s in starts) > 0
    assert max(int(s["stage"].max()) for s in starts) == 2


def test_track_speed_actions_with_noise_and_manual_gear_match():
    cfg = {"server": {"tracks": ["madsim-oval"], "max_steps": 90, "observation_noise": True},
           "agents": [{"name": "learner", "action": {"space": "TS"}, "gear": "manual",
                       "pid": {"latency": 3}, "action_noise_std": 0.05,
                       "observation": {"mode": "TorcsObs", "normalised": True}}],
           "curriculum": {"unit": "episodes", "stages": [{"start": 0},
                                                         {"start": 1, "target_speed": 12.0}]}}

    def ts_actions(rng, n):
        return rng.uniform(-1.0, 1.0, (n, 3)).astype(np.float32)

    _, ended = compare(cfg, 3, 70, actions=ts_actions)
    assert ended >= 3


def test_track_speed_actions_among_traffic_match():
    cfg = {"server": {"tracks": ["madsim-street"], "max_steps": 200},
           "agents": [{"name": "learner", "action": {"space": "TS"}, "pid": {"latency": 3},
                       "observation": {"mode": "SingleAgentInTrafficObs"}}],
           "traffic": [{"behaviour": "ConstVel", "target_speed": 8.0, "lane": 0.5}]}

    def ts_actions(rng, n):
        return rng.uniform(-1.0, 1.0, (n, 2)).astype(np.float32)

    compare(cfg, 2, 10, actions=ts_actions)


def test_madras_compatible_pid_with_raw_units_matches():
    cfg = {"server": {"tracks": ["madsim-road"], "max_steps": 40},
           "agents": [{"name": "learner", "action": {"space": "TS", "normalised": False},
                       "pid": {"latency": 2, "madras_compat": True},
                       "observation": {"mode": "Fields",
                                       "fields": ["focus", "racePos", "damage", "speedX"]}}]}

    def raw_ts(rng, n):
        return np.stack([rng.uniform(-1, 1, n), rng.uniform(0, 120, n)], 1).astype(np.float32)

    _, ended = compare(cfg, 2, 45, actions=raw_ts)
    assert ended >= 2


@contextlib.contextmanager
def throttle_reward(name: str):
    """A reward registered as `name` for the block: it pays the step's accel action and the
    distance of the tick divided by its calls this episode (it needs the action, the rows and
    its own state: no batched form)."""
    @rewards_module.register_reward(name)
    class Throttle(rewards_module.RewardComponent):
        def reset(self):
            self.calls = 0

        def __call__(self, prev, cur, action, info):
            self.calls += 1
            return action[1] + (cur["distRaced"] - prev["distRaced"]) / self.calls

    try:
        yield
    finally:
        rewards_module.REWARDS.pop(name)


def test_a_registered_reward_without_batched_form_is_called_per_episode():
    with throttle_reward("TestVectorThrottle"):
        cfg = {"server": {"max_steps": 30},
               "agents": [{"rewards": {"TestVectorThrottle": 2.0, "Progress2": 1.0}}]}
        compare(cfg, 2, 35)


def test_without_contact_and_with_fuel_the_episodes_still_match():
    cfg = {"server": {"tracks": ["madsim-oval"], "max_steps": 100}, "agents": [{}]}
    _, ended = compare(cfg, 2, 120, contact=False, fuel=True)
    assert ended >= 2


def test_torcs_tick_schedule_and_grid_start_match_with_a_clock_per_episode():
    # episodes end (and restart their clocks) at different ticks; past tick 12 of each episode
    # TORCS's schedule has 11-sub-step ticks, so the batch runs 10- and 11-sub-step slots at once
    cfg = {"server": {"tracks": ["madsim-road", "madsim-oval"], "order": "random",
                      "max_steps": 35, "tick_schedule": "torcs",
                      "grid": {"rows": 1, "distance_to_start": 100}},
           "agents": [{"name": "learner"}],
           "traffic": [{"behaviour": "ConstVel", "target_speed": 8.0}]}
    starts, ended = compare(cfg, 3, 80)
    assert ended >= 4


def test_disabled_autoreset_restarts_only_the_masked_episodes():
    cfg = {"server": {"max_steps": 20}, "agents": [{}]}
    mode = AutoresetMode.DISABLED
    ref = SyncVectorEnv([lambda: MadrasEnv(cfg) for _ in range(2)], autoreset_mode=mode)
    vec = make_vec(cfg, 2, autoreset_mode=mode)
    same(ref.reset(seed=[4, 9]), vec.reset(seed=[4, 9]))
    a = np.tile([0.0, 0.5, -1.0], (2, 1)).astype(np.float32)
    for _ in range(20):
        expected, got = ref.step(a), vec.step(a)
        same(expected, got)
    assert got[3].all()                                     # TimeOut after 20 ticks
    with pytest.raises(RuntimeError, match="reset_mask"):
        vec.step(a)
    mask = np.array([False, True])
    same(ref.reset(options={"reset_mask": mask.copy()}), vec.reset(options={"reset_mask": mask}))
    _, infos = vec.reset(options={"reset_mask": np.array([True, False])})
    assert infos["_seed"].tolist() == [True, False]


def test_cars_of_different_episodes_never_interact():
    # every episode seeded alike puts its car on the same spot of the same track: they
    # would overlap completely if they shared a world
    cfg = {"server": {"max_steps": 200},
           "agents": [{"observation": {"mode": "SingleAgentInTrafficObs"},
                       "dones": ["Collision", "TimeOut"]}]}
    vec = make_vec(cfg, 3)
    alone = MadrasEnv(cfg)
    obs, info = vec.reset(seed=[7, 7, 7])
    assert len(set(map(tuple, info["placement"]))) == 1
    expected, _ = alone.reset(seed=7)
    assert np.array_equal(obs, np.tile(expected, (3, 1)))
    a = np.array([0.05, 0.8, -1.0], dtype=np.float32)
    for _ in range(60):
        obs, reward, term, _, _ = vec.step(np.tile(a, (3, 1)))
        e_obs, e_reward, e_term, _, _ = alone.step(a)
        assert np.array_equal(obs, np.tile(e_obs, (3, 1))) and (reward == e_reward).all()
        assert not term.any() and not e_term                # no Collision done
        assert (obs[:, 24:] == 1.0).all()                   # opponents: nobody within 200 m
    xy = vec.batch.state[vec._row][:, :2]
    assert (xy == xy[0]).all()                              # the three cars share one spot
    assert (vec.batch.race_pos[vec._row] == 1).all()        # each leads its own race
    assert not vec.batch.hits.any()


def test_bad_input_is_refused_with_clear_errors():
    with pytest.raises(ValueError, match="num_envs"):
        make_vec({}, 0)
    with pytest.raises(ConfigError, match="one learning car"):
        make_vec({"agents": [{"name": "a"}, {"name": "b"}]}, 2)
    env = make_vec({}, 2)
    assert isinstance(env, MadrasVectorEnv)
    assert env.action_space.shape == (2, 3) and env.observation_space.shape == (2, 24)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros((2, 3)))
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(num_envs, 3\)"):
        env.step(np.zeros((3, 3)))
    bad = np.zeros((2, 3))
    bad[1, 2] = np.nan
    with pytest.raises(ValueError, match="episode 1 .* index 2"):
        env.step(bad)
    with pytest.raises(ValueError, match="seeds for 2 episodes"):
        env.reset(seed=[1, 2, 3])
    with pytest.raises(ValueError, match="reset_mask"):
        env.reset(options={"reset_mask": np.zeros(2, dtype=bool)})


def test_curriculum_progress_is_one_counter_per_episode_and_can_be_set():
    cfg = {"curriculum": {"unit": "episodes", "stages": [{"start": 0},
                                                         {"start": 3, "target_speed": 12.0}]}}
    env = make_vec(cfg, 2)
    _, info = env.reset(seed=0)
    assert info["stage"].tolist() == [0, 0] and env.curriculum_progress.tolist() == [0, 0]
    env.curriculum_progress = [5, 1]
    _, info = env.reset(seed=0)                        # every reset after the first counts
    assert env.curriculum_progress.tolist() == [6, 2]
    assert info["stage"].tolist() == [1, 0]


def test_make_vec_is_reachable_from_madsim_and_gymnasium():
    import gymnasium

    import madsim

    env = madsim.make_vec({"server": {"max_steps": 20}}, num_envs=3)
    obs, _ = env.reset(seed=4)
    assert obs.shape[0] == 3
    env.close()
    g = gymnasium.make_vec("madsim/SingleLap-v0", num_envs=2, vectorization_mode="vector_entry_point")
    obs, _ = g.reset(seed=1)
    assert obs.shape[0] == 2 and type(g).__name__ == "MadrasVectorEnv"
    g.close()
