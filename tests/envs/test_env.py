"""MadrasEnv (gymnasium): API conformance, seeding, determinism, actions, latency, traffic hook."""

import math
import sys
import time
import warnings
from pathlib import Path

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from madsim.agents.pid import speed_gear
from madsim.envs import config as config_module
from madsim.envs.config import ConfigError, load_config
from madsim.envs.madras_env import MadrasEnv

CONFIGS = Path(config_module.__file__).parent / "configs"
SINGLE_AGENT = ["single_lap", "lap_with_noise", "traffic_overtaking", "mixed_traffic"]
FULL_THROTTLE = np.array([0.0, 1.0, -1.0])         # normalised S-A-B: accel 1, brake 0


class Cruise:
    """Stand-in traffic behaviour (the real ones are issue 6): hold the lane, ~40 km/h."""

    def __init__(self, entry):
        self.entry = entry
        self.resets = []

    def reset(self, rng, info):
        self.resets.append((rng, dict(info)))

    def act(self, row):
        steer = max(-1.0, min(1.0, row["angle"] - 0.3 * row["trackPos"]))
        return steer, (1.0 if row["speedX"] < 40.0 else 0.0), 0.0, 1


def fields_env(fields, **agent):
    """One S-A-B car on madsim-road observing SCR `fields` (mode Fields: gym_torcs's scalings,
    speeds in km/h / 50, distances and times as sent)."""
    cfg = {"server": {"max_steps": 100000},
           "agents": [{"observation": {"mode": "Fields", "fields": list(fields)},
                       "dones": [], **agent}]}
    return MadrasEnv(cfg)


def run(env, seed, actions):
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        o, r, term, trunc, info = env.step(a)
        out.append((o, r, term, trunc, info["reward_terms"]))
        if term or trunc:
            break
    return out


def same(a, b):
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and np.array_equal(a, b)
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    return a == b


# --- conformance ---------------------------------------------------------------------------


@pytest.mark.parametrize("name", SINGLE_AGENT)
def test_gymnasium_env_checker_passes_on_every_single_agent_example(name):
    env = MadrasEnv(CONFIGS / f"{name}.yml", traffic_factory=Cruise)
    if env.config.curriculum is not None:               # a stage that draws traffic
        env.curriculum_progress = env.config.curriculum.stages[-1].start
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")                 # the +-inf speed bounds are MADRaS's
        check_env(env, skip_render_check=True)


def test_stable_baselines3_env_checker():
    sb3 = pytest.importorskip("stable_baselines3.common.env_checker",
                              reason="stable-baselines3 not installed (needs torch)")
    sb3.check_env(MadrasEnv(CONFIGS / "single_lap.yml"), warn=False)


def test_bad_constructor_arguments_are_refused():
    with pytest.raises(ValueError, match="MadrasParallelEnv"):
        MadrasEnv(CONFIGS / "bottleneck_two_learners.yml", traffic_factory=Cruise)
    with pytest.raises(ValueError, match="render_mode"):
        MadrasEnv(render_mode="pictures")
    with pytest.raises(ConfigError, match="server.trakcs"):
        MadrasEnv({"server": {"trakcs": ["x"]}})


def test_traffic_without_the_traffic_layer_is_a_clear_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "madsim.agents.traffic", None)    # import fails
    with pytest.raises(ConfigError, match="traffic_factory"):
        MadrasEnv(CONFIGS / "traffic_overtaking.yml")
    MadrasEnv(CONFIGS / "single_lap.yml")                # no traffic: nothing needed


# --- seeding and determinism ------------------------------------------------------------------


def test_same_seed_and_actions_give_identical_episodes_across_instances_and_reuse():
    actions = [np.array([0.3 * math.sin(i / 7.0), 0.6, -0.9]) for i in range(150)]
    first = run(MadrasEnv(CONFIGS / "lap_with_noise.yml"), 11, actions)
    env = MadrasEnv(CONFIGS / "lap_with_noise.yml")
    run(env, 3, actions[:40])                            # another episode on the same World
    assert same(run(env, 11, actions), first)
    other = run(env, 12, actions)
    assert not same(other, first)                        # noise differs with the seed


def test_unseeded_resets_are_reproducible_from_the_recorded_seed():
    env = MadrasEnv(CONFIGS / "lap_with_noise.yml")
    env.reset(seed=4)
    obs, info = env.reset()
    assert info["episode"] == 1 and info["seed"] != 4
    seed = info["seed"]
    again, info2 = MadrasEnv(CONFIGS / "lap_with_noise.yml").reset(seed=seed, options={"episode": 1})
    assert info2["seed"] == seed and np.array_equal(again, obs)


def test_action_space_seed_survives_resets():
    """highway-env rebuilds its spaces on reset and loses the user's seed; we do not."""
    env = MadrasEnv(CONFIGS / "single_lap.yml")
    space = env.action_space
    env.action_space.seed(3)
    env.reset(seed=0)
    env.reset()
    assert env.action_space is space
    reference = gymnasium.spaces.Box(space.low, space.high, dtype=np.float32, seed=3)
    assert np.array_equal(env.action_space.sample(), reference.sample())


def test_reset_info_names_the_episode():
    env = MadrasEnv(CONFIGS / "single_lap.yml")
    _, info = env.reset(seed=9)
    assert info["seed"] == 9 and info["episode"] == 0 and info["track"] == "madsim-road"
    assert info["car"] == "madsim-sedan" and info["traffic"] == () and info["traffic_count"] == 0
    assert info["track_length"] == pytest.approx(3037.91, abs=0.01)
    # grid slot 0 of the quick-race grid: 25 m before the start line
    assert info["placement"][0] == pytest.approx(info["track_length"] - 25.0, abs=1e-9)


# --- actions --------------------------------------------------------------------------------


def test_nan_or_misshapen_actions_raise_value_error_naming_the_agent():
    env = MadrasEnv(CONFIGS / "single_lap.yml")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="'driver'.*non-finite.*index 1"):
        env.step(np.array([0.0, np.nan, 0.0]))
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        env.step(np.zeros(2))
    with pytest.raises(ValueError, match="not numeric"):
        env.step(["a", "b", "c"])


def test_out_of_range_actions_are_clipped_to_the_box():
    a = run(fields_env(["speedX", "trackPos"]), 0, [np.array([3.0, 7.0, -9.0])] * 30)
    b = run(fields_env(["speedX", "trackPos"]), 0, [np.array([1.0, 1.0, -1.0])] * 30)
    assert same(a, b)


def test_sab_normalised_pedals_map_by_half_a_plus_one():
    """accel a = 0 means half throttle: slower than a = 1, faster than a = -1 (no throttle)."""
    def speed_after(accel):
        out = run(fields_env(["speedX"]), 0, [np.array([0.0, accel, -1.0])] * 100)
        return out[-1][0][0] * 50.0                      # km/h
    assert speed_after(-1.0) == pytest.approx(0.0, abs=0.5)
    assert 5.0 < speed_after(-0.5) < speed_after(0.0) < speed_after(1.0)


def test_automatic_gearbox_is_madras_speed_table():
    """The gear asked for each tick is snakeoil's table at the speed before the tick; the
    engaged gear (observed) follows it after the car's shift time."""
    env = fields_env(["speedX", "gear"])
    env.reset(seed=0)
    seen = set()
    for _ in range(700):
        speed_kmh = env.core.rows[0]["speedX"]
        obs = env.step(FULL_THROTTLE)[0]
        assert env.core.controls[0, 3] == speed_gear(speed_kmh)
        seen.add(int(obs[1]))
    assert {1, 2, 3} <= seen


def test_manual_gear_component_selects_the_gear():
    env = fields_env(["gear"], gear="manual")
    assert env.action_space.shape == (4,)
    env.reset(seed=0)
    # normalised gear component: gear = round(-1 + 3.5 (a + 1)): a = -1 -> -1, a = 1 -> 6
    for a, gear in ((-1.0, -1), (-3 / 7, 1), (1 / 7, 3), (1.0, 6)):
        for _ in range(30):                              # engaged after the shift time
            obs = env.step(np.array([0.0, -1.0, 1.0, a]))[0]
            assert env.core.controls[0, 3] == gear
        assert obs[0] == gear


def test_action_noise_comes_from_the_episode_rng():
    quiet = run(fields_env(["speedX", "trackPos"]), 1, [FULL_THROTTLE] * 50)
    noisy = [run(fields_env(["speedX", "trackPos"], action_noise_std=0.2), 1, [FULL_THROTTLE] * 50)
             for _ in range(2)]
    assert same(noisy[0], noisy[1]) and not same(noisy[0], quiet)


# --- T-S latency ----------------------------------------------------------------------------


def ts_env(latency, max_steps, rewards, fields=("distRaced",)):
    return MadrasEnv({"server": {"max_steps": max_steps},
                      "agents": [{"action": {"space": "TS"}, "pid": {"latency": latency},
                                  "target_speed": 15.0, "rewards": rewards,
                                  "observation": {"mode": "Fields", "fields": list(fields)},
                                  "dones": ["TimeOut"]}]})


def test_ts_rewards_are_summed_over_the_latency_window_and_timeout_checked_every_tick():
    """RankOne pays 1 per tick to a lone car (always first): a step of 5 ticks pays 5; with
    max_steps 12 the third step ends after 2 ticks, truncated."""
    env = ts_env(5, 12, {"RankOne": {"scale": 1.0}})
    env.reset(seed=0)
    got = [env.step(np.array([0.0, 0.5])) for _ in range(3)]
    assert [g[1] for g in got] == [5.0, 5.0, 2.0]
    assert [g[4]["ticks"] for g in got] == [5, 5, 2]
    assert [g[3] for g in got] == [False, False, True] and got[2][4]["dones"] == ("TimeOut",)
    assert [g[4]["reward_terms"]["RankOne"] for g in got] == [5.0, 5.0, 2.0]


def test_ts_progress_over_a_window_telescopes_to_the_distance_driven():
    """Progress = sum over the ticks of (d_t - d_{t-1}) / L = (d_end - d_start) / L."""
    env = ts_env(7, 10000, {"Progress": {"scale": 1.0}})
    obs, info = env.reset(seed=0)
    length = info["track_length"]
    for _ in range(20):
        new, reward, *_ = env.step(np.array([0.0, 0.8]))
        # observations are float32: distRaced < 1000 m carries < 1e-4 m of rounding
        assert reward == pytest.approx((new[0] - obs[0]) / length, abs=1e-4 / length)
        obs = new
    assert obs[0] > 20.0                                  # the PID drove the car forward


# --- traffic hook, randomisation, speed ---------------------------------------------------------


def traffic_config(count, order="random", **server):
    return {"server": {"traffic_count": count, "order": order, "tracks": ["madsim-road"], **server},
            "agents": [{"observation": {"mode": "SingleAgentInTrafficObs"}}],
            "traffic": [{"behaviour": "ConstVel", "target_speed": 11.0}] * 9}


def test_traffic_cars_are_driven_by_the_injected_behaviours():
    built = []

    def factory(entry):
        built.append(Cruise(entry))
        return built[-1]

    env = MadrasEnv(traffic_config([3, 3]), traffic_factory=factory)
    _, info = env.reset(seed=2)
    assert info["traffic_count"] == 3 and info["traffic"] == ("ConstVel",) * 3
    assert info["row"] == 3 and info["cars"] == ("madsim-sedan",) * 4
    used = built[:3]
    assert [b.resets[-1][1]["index"] for b in used] == [0, 1, 2]
    assert all(isinstance(b.resets[-1][0], np.random.Generator) for b in used)
    world = env.core.backend.world
    s0 = np.array(world.column("s"))
    for _ in range(200):
        env.step(np.array([0.0, -1.0, 1.0]))                # learner brakes, traffic cruises
    moved = np.mod(np.array(world.column("s")) - s0, info["track_length"])
    assert np.all(moved[:3] > 10.0) and moved[3] < 0.5
    # the traffic started ahead: it holds grid slots 0-2, the learner slot 3
    assert info["placement"][0] < s0[0]


def test_traffic_count_is_discrete_uniform_over_seeds():
    env = MadrasEnv(traffic_config([0, 3]), traffic_factory=Cruise)
    counts = np.bincount([env.reset(seed=s)[1]["traffic_count"] for s in range(400)], minlength=4)
    # 100 expected per value; binomial sd ~8.7, so +-35 is a 4-sigma band
    assert counts.sum() == 400 and np.all(np.abs(counts - 100) < 35), counts


def test_reset_of_a_ten_car_scenario_takes_under_10_ms():
    env = MadrasEnv(traffic_config([9, 9]), traffic_factory=Cruise)
    env.reset(seed=0)
    times = []
    for s in range(15):
        t0 = time.perf_counter()
        env.reset(seed=s)
        times.append(time.perf_counter() - t0)
    assert len(env.core.backend.world.cars) == 10
    assert np.median(times) < 0.010, times


def test_fixed_order_cycles_tracks_and_seeded_reset_restarts_the_cycle():
    env = MadrasEnv({"server": {"tracks": ["madsim-road", "madsim-oval"], "order": "fixed"}})
    tracks = [env.reset(seed=1)[1]["track"]] + [env.reset()[1]["track"] for _ in range(3)]
    assert tracks == ["madsim-road", "madsim-oval"] * 2
    assert env.reset(seed=5)[1]["track"] == "madsim-road"
    assert env.reset(seed=5, options={"episode": 3})[1]["track"] == "madsim-oval"


def test_curriculum_stages_follow_the_episode_count_and_can_be_set():
    env = MadrasEnv(CONFIGS / "mixed_traffic_curriculum.yml", traffic_factory=Cruise)
    _, info = env.reset(seed=0)
    assert info["stage"] == 0 and info["traffic_count"] == 0
    env.curriculum_progress = 1499
    _, info = env.reset(seed=0)                         # the 1500th episode: stage 2
    assert info["stage"] == 2 and env.curriculum_progress == 1500
    assert 2 <= info["traffic_count"] <= 6


def test_init_wait_brakes_before_the_first_observation():
    env = MadrasEnv({"server": {"init_wait": 30},
                     "agents": [{"observation": {"mode": "Fields", "fields": ["curLapTime"]}}]})
    obs, _ = env.reset(seed=0)
    assert obs[0] == pytest.approx(30 * 0.02, abs=1e-9)


def test_madras_master_config_drives():
    """MADRaS's own file (master layout) runs as it is, minus its traffic (not ours yet)."""
    raw = {"torcs_server_port": 60934, "server_config": {"max_cars": 1, "learning_car": ["madsim-sedan"],
                                                          "track_names": ["madsim-road"]},
           "client_max_steps": -1, "pid_assist": True, "normalize_actions": True,
           "pid_settings": {"accel_pid": [10.5, 0.05, 2.8], "steer_pid": [5.1, 0.001, 1e-6],
                            "accel_scale": 1.0, "steer_scale": 0.1, "pid_latency": 10},
           "observations": {"mode": "SingleAgentSimpleLapObs"}, "rewards": {"ProgressReward2": {"scale": 1.0}},
           "dones": ["RaceOver", "TimeOut"], "max_steps": 1000, "target_speed": 13.89}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cfg = load_config(raw)
    env = MadrasEnv(cfg)
    env.reset(seed=0)
    total = sum(env.step(np.array([0.0, 1.0]))[1] for _ in range(30))
    assert env.action_space.shape == (2,) and total > 30      # ~ one reward unit per 1/10 s
