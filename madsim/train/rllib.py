"""Multi-agent PPO on Ray RLlib for `MadrasParallelEnv` (extra `rllib`).

The env reaches RLlib through RLlib's own PettingZoo wrapper, `ParallelPettingZooEnv`, in a
small subclass (`MadsimRllibEnv`) that fixes two things for madsim:
- episode end: the base class ends the episode when every agent *of this step* terminated, or
  every one truncated; an episode where one car crashed (terminated) while the last one timed
  out (truncated) would then never end, and the next step would hit a finished episode. Here
  the episode ends when no agent is left; it counts as truncated when every agent of the
  last step was truncated, else as terminated.
- spaces: per-agent `observation_spaces` / `action_spaces` dicts (RLlib's new API stack reads
  these) and `possible_agents` in config order.

`ppo_config` builds the PPO configuration: one policy (RLModule) per agent (`policies=
"per_agent"`, the default) or one shared by all agents (`"shared"`, needs equal spaces),
`num_env_runners` rollout workers (Ray actors, one process each). The MADRaS paper trained
with RLlib's PPO of its time (ray 0.8: lr 5e-5, 4000 steps per iteration, minibatch 128, 30
epochs, gamma 0.99, lambda 1.0, clip 0.3, KL 0.2, no entropy bonus), whose value function had
its own network (`vf_share_layers: False`) and whose `vf_clip_param` (10) bounded the value's
step per update. RLlib 2.x shares the encoder by default and reuses `vf_clip_param` as a clamp
of the squared value error, which leaves no gradient for any sample whose error exceeds 3.2
(madsim's returns are hundreds): `ppo_config` keeps the value network separate and the value
loss unclipped (`vf_clip_param` inf), the nearer of RLlib 2.x's options to the paper's. `train_rllib` runs it on a
local Ray instance (`address=None`: started here with `num_env_runners + 1` logical CPUs) or
joins an existing Ray cluster (`address="auto"` on a cluster node, or "ray://head:10001"), which
is how training uses more than one machine (docs/training.md).

The scenario config travels to the workers as plain data (`config_to_dict`), so workers on
other machines do not need the YAML file, only madsim installed.
"""

from __future__ import annotations

import csv
import json
import time
from collections.abc import Mapping
from pathlib import Path

import gymnasium

try:
    from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv
except ModuleNotFoundError as _exc:
    raise ModuleNotFoundError(f"madsim.train.rllib needs the rllib extra ({_exc.name} missing): "
                              "pip install 'madsim[train,rllib]'", name=_exc.name) from None

from madsim.envs.config import ScenarioConfig, config_to_dict, load_config
from madsim.train.threads import TRAINING_THREADS
from madsim.train.threads import torch_threads as threads

__all__ = ["MadsimRllibEnv", "ppo_config", "result_row", "train_rllib"]


class MadsimRllibEnv(ParallelPettingZooEnv):
    """A `MadrasParallelEnv` as an RLlib `MultiAgentEnv` (via `ParallelPettingZooEnv`).

    env_config: {"config": path, mapping or ScenarioConfig}; or an already built
    MadrasParallelEnv passed as `env`."""

    def __init__(self, env_config: Mapping | None = None, *, env=None):
        if env is None:
            from madsim.envs.parallel_env import MadrasParallelEnv

            env_config = dict(env_config or {})
            env = MadrasParallelEnv(env_config.get("config"))
        super().__init__(env)
        order = list(env.possible_agents)
        self.possible_agents = order
        self.agents = list(env.agents)
        self.observation_spaces = {a: env.observation_space(a) for a in order}
        self.action_spaces = {a: env.action_space(a) for a in order}
        self.observation_space = gymnasium.spaces.Dict(self.observation_spaces)
        self.action_space = gymnasium.spaces.Dict(self.action_spaces)

    def reset(self, *, seed=None, options=None):
        obs, infos = super().reset(seed=seed, options=options)
        self.agents = list(self.par_env.agents)
        return obs, infos

    def step(self, action_dict):
        obs, rewards, terminated, truncated, infos = self.par_env.step(action_dict)
        self.agents = list(self.par_env.agents)
        over = not self.agents
        all_truncated = over and all(truncated.values())
        terminated["__all__"] = over and not all_truncated
        truncated["__all__"] = all_truncated
        return obs, rewards, terminated, truncated, infos


def _scenario(config) -> ScenarioConfig:
    return config if isinstance(config, ScenarioConfig) else load_config(config)


def ppo_config(config, *, policies: str = "per_agent", num_env_runners: int = 2,
               seed: int = 0, train_batch_size: int = 4000, minibatch_size: int = 500,
               num_epochs: int = 10, rollout_fragment_length: int | str = "auto",
               hidden: tuple[int, ...] = (64, 64), lr: float = 3e-4, gamma: float = 0.99):
    """An RLlib `PPOConfig` for the multi-agent scenario `config` (path, mapping or
    ScenarioConfig). Batch sizes count env steps of one agent's module (RLlib's
    `train_batch_size_per_learner`). Policy and value function: separate MLPs of `hidden`
    tanh units, value loss unclipped (module docstring)."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

    cfg = _scenario(config)
    names = list(cfg.agent_names)
    if policies not in ("per_agent", "shared"):
        raise ValueError(f"policies must be 'per_agent' or 'shared', got {policies!r}")
    if isinstance(num_env_runners, bool) or not isinstance(num_env_runners, int) or num_env_runners < 0:
        raise ValueError(f"num_env_runners must be an int >= 0, got {num_env_runners!r}")
    probe = MadsimRllibEnv({"config": cfg})
    if policies == "shared":
        first = (probe.observation_spaces[names[0]], probe.action_spaces[names[0]])
        if any((probe.observation_spaces[a], probe.action_spaces[a]) != first for a in names):
            raise ValueError("a shared policy needs every agent to have the same observation and "
                             "action spaces; use policies='per_agent'")
        modules = ["shared"]

        def mapping(agent_id, episode=None, **kwargs):
            return "shared"
    else:
        modules = list(names)          # in the scenario's order: a set's order changes with the
                                       # hash seed, and so would which module gets which initial weights

        def mapping(agent_id, episode=None, **kwargs):
            return agent_id
    probe.close()
    return (
        PPOConfig()
        .environment(MadsimRllibEnv, env_config={"config": config_to_dict(cfg)})
        .env_runners(num_env_runners=num_env_runners,
                     rollout_fragment_length=rollout_fragment_length)
        .multi_agent(policies=modules, policy_mapping_fn=mapping)
        .rl_module(model_config=DefaultModelConfig(fcnet_hiddens=list(hidden),
                                                   fcnet_activation="tanh", vf_share_layers=False))
        .training(train_batch_size_per_learner=train_batch_size, minibatch_size=minibatch_size,
                  num_epochs=num_epochs, lr=lr, gamma=gamma, vf_clip_param=float("inf"))
        .debugging(seed=seed)
    )


def result_row(result: Mapping, iteration: int, wall_s: float) -> dict:
    """The figures of one `algo.train()` result that go into rllib.csv: iteration, env steps
    so far, wall time, mean episode return and length, and each agent's mean return."""
    runners = result.get("env_runners", {})
    row = {"iteration": iteration,
           "env_steps": int(runners.get("num_env_steps_sampled_lifetime",
                                        result.get("num_env_steps_sampled_lifetime", 0)) or 0),
           "wall_s": round(wall_s, 2),
           "episode_return_mean": runners.get("episode_return_mean", float("nan")),
           "episode_len_mean": runners.get("episode_len_mean", float("nan"))}
    for agent, value in sorted(runners.get("agent_episode_returns_mean", {}).items()):
        row[f"return_{agent}"] = value
    return row


def train_rllib(config, out_dir, *, iterations: int, address: str | None = None,
                checkpoint_every: int = 10, keep_every: int = 0, log=print,
                torch_threads: int = TRAINING_THREADS, **ppo_kwargs) -> list[dict]:
    """Train `iterations` PPO iterations on `config` and write run folder `out_dir`:
    config.yml (resolved scenario), rllib.csv (one `result_row` per iteration), run.json, and
    checkpoint/ (RLlib's `algo.save`, every `checkpoint_every` iterations and at the end), and
    with `keep_every` > 0 a kept copy checkpoint-NNNN/ after every `keep_every`-th iteration
    before the last (NNNN: the iteration, 4 digits).
    address None starts a local Ray instance; else `ray.init(address=address)` joins that
    cluster. Ray is shut down at the end only if it was started here. torch_threads: torch's
    intra-op threads in this process while it samples (0 env runners) and updates
    (madsim.train.threads: the count changes an update's bits); Ray starts each env runner
    with one."""
    import ray
    import yaml

    cfg = _scenario(config)
    run = Path(out_dir)
    run.mkdir(parents=True, exist_ok=True)
    (run / "config.yml").write_text(yaml.safe_dump(config_to_dict(cfg), sort_keys=False),
                                    encoding="utf-8")
    started = not ray.is_initialized()
    if started:
        if address is None:
            ray.init(num_cpus=ppo_kwargs.get("num_env_runners", 2) + 1, include_dashboard=False,
                     log_to_driver=False)
        else:
            ray.init(address=address, log_to_driver=False)
    rows: list[dict] = []
    try:
        with threads(torch_threads):
            rows = _iterate(cfg, run, iterations, checkpoint_every, keep_every, log, ppo_kwargs)
        (run / "run.json").write_text(json.dumps({
            "iterations": iterations, "address": address, "torch_threads": torch_threads,
            "settings": {k: (list(v) if isinstance(v, tuple) else v) for k, v in ppo_kwargs.items()},
            "ray": ray.__version__, "last": rows[-1] if rows else None}, indent=2), encoding="utf-8")
    finally:
        if started:
            ray.shutdown()
    return rows


def _iterate(cfg, run: Path, iterations: int, checkpoint_every: int, keep_every: int, log,
             ppo_kwargs: dict) -> list[dict]:
    """train_rllib's loop: build the algorithm, train, write rllib.csv and the checkpoints."""
    rows: list[dict] = []
    algo = ppo_config(cfg, **ppo_kwargs).build_algo()
    t0 = time.time()
    with open(run / "rllib.csv", "w", newline="") as f:
        writer = None
        for i in range(1, iterations + 1):
            row = result_row(algo.train(), i, time.time() - t0)
            rows.append(row)
            if writer is None:
                writer = csv.DictWriter(f, fieldnames=list(row), extrasaction="ignore")
                writer.writeheader()
            writer.writerow(row)
            f.flush()
            log(f"iteration {i}: {row['env_steps']} env steps, return "
                f"{row['episode_return_mean']:.1f}, {row['wall_s']:.0f} s")
            if i % checkpoint_every == 0 or i == iterations:
                algo.save(str((run / "checkpoint").resolve()))
            if keep_every > 0 and i % keep_every == 0 and i < iterations:
                algo.save(str((run / f"checkpoint-{i:04d}").resolve()))
    algo.stop()
    return rows
