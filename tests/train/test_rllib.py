"""Multi-agent PPO on Ray RLlib (extra `rllib`): the env wrapper and one training iteration."""

import csv
import json
from typing import ClassVar

import gymnasium
import numpy as np
import pytest

pytest.importorskip("ray.rllib", reason="Ray RLlib not installed: pip install 'madsim[rllib]'")
pytest.importorskip("torch", reason="torch not installed: pip install 'madsim[train]'")

from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv

from madsim.envs.registration import CONFIG_DIR
from madsim.train.rllib import MadsimRllibEnv, ppo_config, train_rllib

BOTTLENECK = CONFIG_DIR / "bottleneck_two_learners.yml"


class ScriptedEnding:
    """A two-agent ParallelEnv whose agents end on a script: per step, who terminates and who
    truncates (the situation of a crash on the very tick the other car times out)."""

    possible_agents: ClassVar[list[str]] = ["a", "b"]

    def __init__(self, script):
        self.script = script
        self.agents = []

    def observation_space(self, agent):
        return gymnasium.spaces.Box(-1, 1, (2,), np.float32)

    def action_space(self, agent):
        return gymnasium.spaces.Box(-1, 1, (1,), np.float32)

    def reset(self, seed=None, options=None):
        self.agents = list(self.possible_agents)
        self.t = 0
        return {a: np.zeros(2, np.float32) for a in self.agents}, {a: {} for a in self.agents}

    def step(self, actions):
        ending = self.script[self.t]
        self.t += 1
        live = list(self.agents)
        term = {a: ending.get(a) == "term" for a in live}
        trunc = {a: ending.get(a) == "trunc" for a in live}
        self.agents = [a for a in live if not (term[a] or trunc[a])]
        return ({a: np.zeros(2, np.float32) for a in live}, {a: 0.0 for a in live}, term, trunc,
                {a: {} for a in live})


def _steps(env):
    env.reset()
    flags = []
    while True:
        _, _, term, trunc, _ = env.step({a: np.zeros(1, np.float32) for a in env.par_env.agents})
        flags.append((term["__all__"], trunc["__all__"]))
        if term["__all__"] or trunc["__all__"] or len(flags) > 5:
            return flags


def test_episode_ends_when_the_last_agent_leaves_however_it_leaves():
    # a crashes (terminated) on the step b times out (truncated): the episode is over.
    mixed = [{"a": "term", "b": "trunc"}]
    assert _steps(MadsimRllibEnv(env=ScriptedEnding(mixed))) == [(True, False)]
    # RLlib's own wrapper misses that end (neither "all terminated" nor "all truncated"),
    # which is why madsim subclasses it.
    base = ParallelPettingZooEnv(ScriptedEnding(mixed))
    base.reset()
    _, _, term, trunc, _ = base.step({"a": np.zeros(1, np.float32), "b": np.zeros(1, np.float32)})
    assert not base.par_env.agents and (term["__all__"], trunc["__all__"]) == (False, False)
    # one leaves early, the other times out later: truncated at the end, not before
    staged = [{"a": "term"}, {}, {"b": "trunc"}]
    assert _steps(MadsimRllibEnv(env=ScriptedEnding(staged))) == [(False, False)] * 2 + [(False, True)]


def test_bottleneck_env_exposes_each_agents_spaces_in_config_order():
    env = MadsimRllibEnv({"config": str(BOTTLENECK)})
    assert env.possible_agents == ["first", "second"]
    obs, _ = env.reset(seed=1)
    for a in ("first", "second"):
        assert env.get_observation_space(a).contains(obs[a])
        assert env.get_action_space(a).shape == (2,)              # T-S: [lane, speed]
    env.close()


def test_shared_policy_needs_equal_spaces(tmp_path):
    cfg = ppo_config(BOTTLENECK, policies="shared", num_env_runners=0)
    assert set(cfg.policies) == {"shared"}
    assert set(ppo_config(BOTTLENECK, num_env_runners=0).policies) == {"first", "second"}
    with pytest.raises(ValueError, match="per_agent"):
        ppo_config(BOTTLENECK, policies="each")


@pytest.mark.timeout(280)
def test_one_training_iteration_with_two_rollout_workers(tmp_path):
    """One PPO iteration of the two-learner bottleneck on a local Ray instance with 2 rollout
    workers (EnvRunner actors), tiny batch: it samples at least the batch from both agents,
    logs the iteration and leaves a checkpoint."""
    import torch

    threads_before = torch.get_num_threads()
    rows = train_rllib(BOTTLENECK, tmp_path, iterations=1, num_env_runners=2, train_batch_size=200,
                       minibatch_size=100, num_epochs=1, rollout_fragment_length=50,
                       log=lambda line: None)
    assert len(rows) == 1 and rows[0]["env_steps"] >= 200
    with open(tmp_path / "rllib.csv", newline="") as f:
        logged = list(csv.DictReader(f))
    assert [int(r["iteration"]) for r in logged] == [1]
    assert (tmp_path / "checkpoint").is_dir() and any((tmp_path / "checkpoint").iterdir())
    assert (tmp_path / "config.yml").is_file() and (tmp_path / "run.json").is_file()
    # the update ran on one torch thread (its bits depend on the count), and the caller's
    # count is back afterwards
    import torch

    assert json.loads((tmp_path / "run.json").read_text())["torch_threads"] == 1
    assert torch.get_num_threads() == threads_before


def test_value_function_has_its_own_network_and_an_unclipped_loss():
    """The paper's RLlib PPO (ray 0.8) kept the value function's network apart from the policy's
    (vf_share_layers False) and only bounded the value's step per update; RLlib 2.x shares the
    encoder by default and clamps the squared value error at vf_clip_param (10), leaving no
    gradient once the error exceeds 3.2. The value loss's gradient must not reach the policy,
    and a value error of 100 must still be learned from."""
    import torch
    from ray.rllib.core.columns import Columns

    cfg = ppo_config(BOTTLENECK, num_env_runners=0, hidden=(8, 8))
    env = MadsimRllibEnv({"config": str(BOTTLENECK)})
    spaces = {a: (env.observation_spaces[a], env.action_spaces[a]) for a in env.possible_agents}
    env.close()
    module = cfg.get_multi_rl_module_spec(spaces=spaces).build()["first"]
    obs = torch.as_tensor(np.stack([spaces["first"][0].sample() for _ in range(4)]))

    def vf_loss_grads(target):          # RLlib 2.x's value loss: clamp(squared error, 0, vf_clip)
        module.zero_grad(set_to_none=True)
        values = module.compute_values({Columns.OBS: obs})
        torch.clamp((values - target(values)) ** 2, 0, cfg.vf_clip_param).mean().backward()
        return {id(p) for p in module.parameters() if p.grad is not None and p.grad.any()}

    policy_out = module.forward_train({Columns.OBS: obs})[Columns.ACTION_DIST_INPUTS]
    policy = {id(p) for p in module.parameters()
              if torch.autograd.grad(policy_out.sum(), p, retain_graph=True, allow_unused=True)[0] is not None}
    small = vf_loss_grads(lambda v: v.detach() + 1.0)     # an error of 1: within any clip
    assert policy and small and not small & policy        # value learning leaves the policy alone
    assert vf_loss_grads(lambda v: 100.0) == small        # an error of 100 is learned from too
