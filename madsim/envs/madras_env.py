"""`MadrasEnv`: one learning car (plus traffic) as a gymnasium environment."""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium

from madsim.envs.front import EnvFront

__all__ = ["MadrasEnv"]


class MadrasEnv(EnvFront, gymnasium.Env):
    """
    ## Description
    One learning car drives a TORCS-like race, possibly among programmed traffic cars, as in
    MADRaS (Santara et al., JAIR 2021). Everything about the scenario comes from one YAML
    config (`madsim.envs.config`; MADRaS's own `madras_config.yml` loads too): tracks and cars
    to draw from, traffic, action and observation modes, rewards, dones, noise, curriculum.
    The simulation runs in this process (`LocalBackend`) or against an SCR server
    (`ScrBackend`: `madsim serve` or TORCS).

    ## Action Space
    A `Box` (float32) set by the agent's `action` config:
    - S-A-B (`space: SAB`): [steer, accel, brake], steer in [-1, 1] (left +); normalised: all
      in [-1, 1], pedals mapped by (a + 1) / 2; else accel and brake in [0, 1]. One action
      drives one tick (0.02 s; with `server.tick_schedule: torcs`, TORCS's own 0.02-or-0.022 s
      driver calls, counted from each reset).
    - T-S (`space: TS`): [track position, speed] tracked by MADRaS's PID controller for
      `pid.latency` ticks per step; normalised: both in [-1, 1] (the track limits, and
      +-target_speed); else trackPos and km/h in [-max_speed_kmh, max_speed_kmh].
    - `gear: manual` appends a gear component (normalised: gear = round(-1 + 3.5 (a + 1)),
      else -1..6); by default gears are chosen by MADRaS's automatic gearbox.
    Actions outside the Box are clipped; a NaN or a wrong shape raises ValueError. With
    `action_noise_std` > 0 Gaussian noise is added to each component every step.

    ## Observation Space
    A `Box` (float32) of the agent's `observation.mode`, with MADRaS's scalings (angle / pi,
    distances / 200 m, speeds km/h / 50): `SingleAgentSimpleLapObs` (24: angle, track[19],
    trackPos, speedX/Y/Z), `SingleAgentInTrafficObs` (60: those + opponents[36]),
    `TorcsObs` (29), or `Fields` (listed SCR fields); optionally normalised onto [-1, 1];
    followed by the communication buffer if the agent listens to others (not in this
    single-car env unless it hears itself). Observation noise (`server.observation_noise`)
    is SCR's multiplicative sensor noise.

    ## Rewards
    Per tick, the weighted sum of the configured components minus the weighted penalties
    (Progress, Progress2, Progress3, AvgSpeed, Collision, TurnBackward, AngularAcceleration,
    SuccessfulOvertake, RankOne, Task; `madsim.agents.rewards`), summed over the ticks of the
    step. `info["reward_terms"]` holds each weighted component of the step.

    ## Starting State
    `reset(seed=...)` fully determines the episode: track, car, traffic count and placements
    (MADRaS's grid, a TORCS race's grid from `server.grid` as `madsim serve --grid`, or uniform
    draws within `initial_distance` / `initial_trackpos`) and the noise. Cars start at rest;
    `server.init_wait` steps of braking may follow.

    ## Episode Termination
    Any configured done (RaceOver, LapCompleted, TimeOut, Collision, TurnBackward,
    OutOfTrack, Rank1; checked every tick) ends the episode: TimeOut truncates, the others
    terminate. `info["dones"]` names the ones that fired.

    ## Arguments
    `config`: path, mapping or ScenarioConfig (default: all defaults, one S-A-B car on
    madsim-road); `backend`: `LocalBackend()` (default) or `ScrBackend(host, port)`;
    `traffic_factory`: builds traffic behaviours (see `madsim.envs.core`);
    `render_mode`: None (rendering lives in `madsim.render`).
    `reset(options={"episode": k})` selects the index used by `server.order: fixed`
    (otherwise 0 after a seeded reset, +1 per reset). `curriculum_progress` (episodes or
    steps) selects the curriculum stage; it counts itself and may be set by a callback.
    Reset info: seed, episode, stage, track, track_length, car, cars, traffic,
    traffic_count, row, placement. Step info: reward_terms, dones, ticks.

    ## Version History
    - v0: first version (madsim 0.1).
    """

    metadata: ClassVar[dict] = {"render_modes": ["human", "rgb_array"], "render_fps": 50}

    def __init__(self, config=None, *, backend=None, traffic_factory=None,
                 render_mode: str | None = None, render_options: dict | None = None):
        self._open(config, backend, traffic_factory, render_mode, render_options)
        self.agent = self.core.names[0]
        self.action_space = self.core.action_spaces[self.agent]
        self.observation_space = self.core.observation_spaces[self.agent]

    def _check_core(self) -> None:
        if len(self.core.names) != 1:
            raise ValueError(f"MadrasEnv drives one learning car, the config has "
                             f"{len(self.core.names)} ({', '.join(self.core.names)}); "
                             "use MadrasParallelEnv")

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        obs, infos = self.core.new_episode(seed, options, self.np_random)
        self._shown()
        return obs[self.agent], infos[self.agent]

    def step(self, action):
        out = self.core.step_one(self.agent, action)
        self._shown()
        return out
