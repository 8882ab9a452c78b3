"""MadrasEnv's and MadrasParallelEnv's compiled step (madsim.envs.env_tick) against the same env
stepped stage by stage in Python: the same observations, rewards, flags and infos, bit for bit,
through the stages the compiled call leaves to Python (communication, traffic controls,
contact near a car, sensor noise, a reward written in Python), with one, two and three
learners, learners leaving one by one or all with the first done, and through resets."""

import contextlib

import numpy as np
import pytest

from madsim.envs import env_tick
from madsim.envs.core import MadrasCore
from madsim.envs.madras_env import MadrasEnv
from madsim.envs.parallel_env import MadrasParallelEnv
from tests.envs.test_vector import same, throttle_reward


@contextlib.contextmanager
def counted_stages():
    """EnvTick.run counting the stages it leaves to Python: yields the dict stage -> count."""
    stages = {}
    run = env_tick.EnvTick.run

    def counting(self, first, tick0, ticks):
        stage = run(self, first, tick0, ticks)
        stages[stage] = stages.get(stage, 0) + 1
        return stage
    env_tick.EnvTick.run = counting
    try:
        yield stages
    finally:
        env_tick.EnvTick.run = run


def episode_log(cfg, steps, actions, *, compiled, seed=5):
    """Everything `steps` env steps return (resets included), and the Python stages counted."""
    env = MadrasEnv(cfg)
    original = MadrasCore._compiled_step
    if not compiled:
        MadrasCore._compiled_step = lambda self: None
    try:
        with counted_stages() as stages:
            rng = np.random.default_rng(seed)
            log = [env.reset(seed=seed)]
            assert (env.core._compiled is not None) == compiled
            for _ in range(steps):
                out = env.step(actions(rng))
                log.append(out)
                if out[2] or out[3]:
                    log.append(env.reset())
    finally:
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
        return refusals(env, compiled, ACTIONS, np.array([0.0, 0.6, -1.0]))

    same_refusals(drive(False), drive(True), 7)


def refusals(env, compiled, tries, good):
    """After a reset, each action (or action dict) of `tries` followed by the action `good`:
    what the steps return, or a refused step's ValueError text."""
    log = [env.reset(seed=3)]
    for a in tries:
        try:
            log.append(env.step(a))
        except ValueError as exc:
            log.append(str(exc))
        log.append(env.step(good))
    assert (env.core._compiled is not None) == compiled
    return log


def same_refusals(ref, got, refused):
    """Two `refusals` logs equal entry by entry, `refused` steps refused in each."""
    assert sum(isinstance(x, str) for x in ref) == refused
    assert len(ref) == len(got)
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


# --- several learners (MadrasParallelEnv) ----------------------------------------------------------


def stage_path(env):
    """env's core without the compiled step: every step stage by stage in Python."""
    env.core._compiled_step = lambda: None
    return env


def parallel_log(cfg, steps, policy, *, compiled, seed=5, factory=None):
    """Everything `steps` steps of a MadrasParallelEnv return (resets included; policy(rng,
    name) -> an action for each live learner), and the Python stages counted."""
    env = MadrasParallelEnv(cfg, traffic_factory=factory)
    if not compiled:
        stage_path(env)
    with counted_stages() as stages:
        rng = np.random.default_rng(seed)
        log = [env.reset(seed=seed)]
        assert (env.core._compiled is not None) == compiled
        for _ in range(steps):
            if not env.agents:
                log.append(env.reset())
                continue
            log.append(env.step({name: policy(rng, name) for name in env.agents}))
    return log, stages


def compare_parallel(cfg, steps, policy, **kw):
    ref, _ = parallel_log(cfg, steps, policy, compiled=False, **kw)
    got, stages = parallel_log(cfg, steps, policy, compiled=True, **kw)
    assert len(ref) == len(got)
    for i, (a, b) in enumerate(zip(ref, got)):
        same(list(a), list(b), f"[{i}]")
    return ref, stages


def learners(n, **agent):
    return [{"name": f"car{i}", **agent} for i in range(n)]


def ends(log):
    """(step index, learner, infos' dones) of every learner's end in a log."""
    return [(i, name, step[4][name]["dones"]) for i, step in enumerate(log) if len(step) == 5
            for name in step[4] if step[2][name] or step[3][name]]


def wobbly(rng, name):
    """S-A-B: car0 drives straight, the others wander more the higher their number, so they
    leave the road one after another."""
    k = int(name[3:])
    return np.array([rng.uniform(-0.05, 0.05) + 0.12 * k, rng.uniform(0.4, 1.0), -1.0])


@pytest.mark.parametrize("n", [2, 3])
def test_learners_that_leave_one_by_one_step_compiled_as_in_python(n):
    cfg = {"server": {"max_steps": 300},
           "agents": learners(n, dones=["TimeOut", "OutOfTrack", "TurnBackward"],
                              rewards={"Progress": 1.0, "Collision": 2.0})}
    log, stages = compare_parallel(cfg, 400, wobbly)
    assert stages[env_tick.DONE] == sum(1 for step in log if len(step) == 5)
    assert set(stages) <= {env_tick.DONE, env_tick.STEP}     # only cars near each other
    assert any(len(step) == 5 and len(step[0]) < n for step in log)   # some drove on alone
    assert len({i for i, _, _ in ends(log)}) >= n


@pytest.mark.parametrize("n", [2, 3])
def test_the_first_done_ends_every_learners_step_compiled_as_in_python(n):
    """server.episode_end "any": car0 times out at tick 98, the second of a T-S step of 3
    ticks; the others, which would drive on, end with it (EpisodeEnd) on that tick."""
    ts = {"action": {"space": "TS", "normalised": True}, "pid": {"latency": 3},
          "dones": ["RaceOver", "OutOfTrack"]}
    agents = learners(n, **ts)
    agents[0]["dones"] = ["TimeOut"]
    cfg = {"server": {"max_steps": 98, "episode_end": "any"}, "agents": agents}

    def lanes(rng, name):
        return np.array([0.2 * int(name[3:]) * rng.uniform(0.5, 2.0), rng.uniform(0.0, 1.0)])

    log, _ = compare_parallel(cfg, 100, lanes)
    together = [step for step in log if len(step) == 5 and any(
        info["dones"] == ("EpisodeEnd",) for info in step[4].values())]
    assert len(together) == 2
    for step in together:                # every learner out at once, on the same tick
        assert step[4]["car0"]["dones"] == ("TimeOut",)
        assert all(step[2][a] or step[3][a] for a in step[0])
        assert {info["ticks"] for info in step[4].values()} == {2}


@pytest.mark.parametrize("contact", ["parked", "moving"])
def test_learners_among_traffic_t_s_and_s_a_b_compiled_as_in_python(contact):
    """Three learners, one of them T-S at latency 1 with the others S-A-B, among traffic: built-in
    behaviours that draw nothing are compiled; ones that draw are Python's, in the same
    order; contact near a car leaves the narrow phase to Python."""
    agents = learners(3, observation={"mode": "SingleAgentInTrafficObs"},
                      dones=["TimeOut", "OutOfTrack", "TurnBackward"],
                      rewards={"Progress": 1.0, "Collision": 3.0, "SuccessfulOvertake": 1.0})
    agents[1].update(action={"space": "TS"}, pid={"latency": 1})
    traffic = ([{"behaviour": "ConstVel", "target_speed": 4.0, "lane": 0.0,
                 "initial_distance": [12.0, 12.0]},
                {"behaviour": "Parked", "initial_distance": [30.0, 40.0]}]
               if contact == "parked" else
               [{"behaviour": "RandomLaneSwitch", "target_speed": 9.0},
                {"behaviour": "SinusoidalSpeed"}])
    cfg = {"server": {"tracks": ["madsim-street"], "max_steps": 250},
           "agents": agents, "traffic": traffic}

    def act(rng, name):
        if name == "car1":
            return np.array([rng.uniform(-0.5, 0.5), rng.uniform(0.3, 1.0)])
        return np.array([rng.uniform(-0.03, 0.03), rng.uniform(0.3, 1.0), -1.0])

    log, stages = compare_parallel(cfg, 260, act)
    if contact == "parked":
        assert stages.get(env_tick.TRAFFIC, 0) == 0
        assert stages.get(env_tick.STEP, 0) > 0
    else:
        assert stages.get(env_tick.TRAFFIC, 0) >= 200


def test_communication_noise_and_a_python_reward_among_learners():
    """car0 hears the others' actions and car2's speed; car1 draws action noise (its step
    starts after Python's noise), car2 has a reward written in Python (its outcome in
    Python, the others' compiled, in order); sensor noise on."""
    with throttle_reward("TestEnvTickThrottle3"):
        agents = learners(3, dones=["TimeOut", "OutOfTrack"])
        agents[0]["communication"] = {"senders": ["car1", "car2"],
                                      "variables": ["peerActions", "speedX"], "buffer_length": 2}
        agents[1]["action_noise_std"] = 0.1
        agents[2]["rewards"] = {"TestEnvTickThrottle3": 1.0, "Progress2": 1.0}
        cfg = {"server": {"max_steps": 90, "observation_noise": True}, "agents": agents}
        log, stages = compare_parallel(cfg, 120, wobbly)
    assert stages.get(env_tick.OUTCOME, 0) >= 90 and stages.get(env_tick.SENSE, 0) >= 90
    heard = [step[0]["car0"][-2 * 7:] for step in log if len(step) == 5 and "car0" in step[0]]
    assert any(np.any(h != 0.0) for h in heard)


@pytest.mark.parametrize("space", ["SAB", "TS"])
def test_communication_without_noise_stops_once_for_the_messages(space):
    """Each hears the other's action; the step goes on after the messages from its first tick
    (T-S: all 3 of its ticks)."""
    agents = learners(2, action={"space": space}, pid={"latency": 3 if space == "TS" else 1})
    agents[0]["communication"] = {"senders": ["car1"], "variables": ["peerActions"]}
    agents[1]["communication"] = {"senders": ["car0"], "variables": ["peerActions", "speedX"]}
    cfg = {"server": {"max_steps": 120}, "agents": agents}

    def act(rng, name):
        a = wobbly(rng, name)
        return a[:2] if space == "TS" else a

    log, stages = compare_parallel(cfg, 60, act)
    n = sum(1 for step in log if len(step) == 5)
    assert stages == {env_tick.COMM: n, env_tick.DONE: n}
    assert all(info["ticks"] == (3 if space == "TS" else 1) for step in log[1:41]
               for info in step[4].values())


BAD = [{"car0": [0.1, 0.5, -1.0], "car1": [0.1, np.nan, -1.0], "car2": [0.0, 0.5]},
       {"car0": [0.1, 0.5, -1.0], "car1": [0.1, 0.5], "car2": [np.inf, 0.5, -1.0]},
       {"car0": [0.1, 0.5, np.inf], "car1": "abc", "car2": [0.0, 0.5, -1.0]},
       {"car0": [0.1, 0.5, -1.0], "car2": [0.0, 0.5, -1.0]},
       {"car1": [0.1, 0.5, -1.0], "car0": [0.0, 0.5, np.nan], "car2": [0.0, 0.5, -1.0]},
       {"car0": np.float32([0.1, 2.0, -3.0]), "car1": (1, 1, 0), "car2": np.arange(6.0)[::2]},
       {"car0": [0.1, 0.5, -1.0], "car1": [0.1, 0.5, -1.0], "car2": [0.1, 0.5, -1.0, 0.0]}]


def test_actions_of_several_learners_are_taken_and_refused_as_in_python():
    """Each action set of BAD between steps: the same results, the same ValueError (the first
    learner in order whose action is missing, malformed or not finite), nothing changed by a
    refused one."""
    cfg = {"server": {"max_steps": 400}, "agents": learners(3)}

    def drive(compiled):
        env = MadrasParallelEnv(cfg)
        if not compiled:
            stage_path(env)
        good = {name: np.array([0.0, 0.6, -1.0]) for name in env.possible_agents}
        return refusals(env, compiled, BAD, good)

    same_refusals(drive(False), drive(True), 6)


def test_the_shipped_bottleneck_scenario_compiled_as_in_python():
    """bottleneck_two_learners.yml: two T-S learners (latency 5) hearing each other's action,
    two parked cars, a generated track."""
    from pathlib import Path

    from madsim.envs import config as config_module
    cfg = Path(config_module.__file__).parent / "configs" / "bottleneck_two_learners.yml"

    def act(rng, name):
        return np.array([rng.uniform(-0.3, 0.3), rng.uniform(0.0, 1.0)])

    log, stages = compare_parallel(cfg, 150, act)
    assert stages[env_tick.COMM] == stages[env_tick.DONE] == 150
    assert all(info["ticks"] == 5 for info in log[1][4].values())
