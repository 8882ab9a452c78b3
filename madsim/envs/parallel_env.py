"""`MadrasParallelEnv`: several learning cars (plus traffic) as a PettingZoo ParallelEnv."""

from __future__ import annotations

from typing import Any, ClassVar

from gymnasium.utils import seeding
from pettingzoo import ParallelEnv

from madsim.envs.front import EnvFront

__all__ = ["MadrasParallelEnv"]


class MadrasParallelEnv(EnvFront, ParallelEnv):
    """
    ## Description
    Several learning cars race together, possibly among programmed traffic cars, as in
    MADRaS's multi-agent version: one config entry per agent, each with its own action space,
    observation mode, rewards, dones and communication (what it hears of which other agents,
    with a buffer of the last messages). PettingZoo semantics: `possible_agents` is fixed
    (the config's agent names), `agents` holds those still driving, and every dict is keyed
    by agent name. Same scenario config, backends and options as `MadrasEnv`.

    ## Action Space
    `action_space(agent)`: the agent's Box, exactly as in `MadrasEnv` (S-A-B or T-S,
    normalised or not, optional manual gear). All agents must take the same number of ticks
    per step (S-A-B: 1; T-S: `pid.latency`).

    ## Observation Space
    `observation_space(agent)`: the agent's observation mode (as in `MadrasEnv`) followed by
    its communication vector, `buffer_length` x message width (a message: each sender's
    listed variables, `peerActions` = the sender's action). Messages arrive one step late;
    senders that have left send zeros.

    ## Rewards
    Per agent, as in `MadrasEnv`: weighted components minus weighted penalties, summed over
    the ticks of the step; `infos[agent]["reward_terms"]` has the components.

    ## Starting State
    `reset(seed=...)` determines track, each agent's car, traffic and placements (grid slots:
    traffic first, then the agents in config order; or uniform draws) and noise.

    ## Episode Termination
    Each agent's dones are checked every tick; an agent that is done leaves `agents` (its car
    brakes to a stop and stays on the track as an obstacle) while the others go on. The
    episode is over when `agents` is empty. Actions of agents that have left are ignored;
    actions for unknown names raise ValueError.

    ## Arguments
    `config`, `backend`, `traffic_factory`, `render_mode` as in `MadrasEnv`;
    `reset(options={"episode": k})` and `curriculum_progress` likewise.

    ## Version History
    - v0: first version (madsim 0.1).
    """

    metadata: ClassVar[dict] = {"name": "madsim_parallel_v0", "render_modes": ["human", "rgb_array"],
                                "render_fps": 50, "is_parallelizable": True}

    def __init__(self, config=None, *, backend=None, traffic_factory=None,
                 render_mode: str | None = None, render_options: dict | None = None):
        self._open(config, backend, traffic_factory, render_mode, render_options)
        self.possible_agents = list(self.core.names)
        self.agents: list[str] = []
        self.observation_spaces = dict(self.core.observation_spaces)
        self.action_spaces = dict(self.core.action_spaces)
        self._np_random = None

    def observation_space(self, agent: str):
        return self.observation_spaces[agent]

    def action_space(self, agent: str):
        return self.action_spaces[agent]

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None):
        if seed is not None or self._np_random is None:
            self._np_random, _ = seeding.np_random(seed)
        obs, infos = self.core.new_episode(seed, options, self._np_random)
        self.agents = list(self.core.live)
        self._shown()
        return obs, infos

    def step(self, actions: dict[str, Any]):
        actions = {name: a for name, a in actions.items()
                   if name in self.core.live or name not in self.possible_agents}
        result = self.core.step(actions)
        self.agents = list(self.core.live)
        self._shown()
        return result
