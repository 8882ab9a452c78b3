"""`make_vec`: N `MadrasEnv` episodes as one batched gymnasium `VectorEnv`.

`MadrasVectorEnv` runs N independent copies of a one-learner scenario in one
`madsim.physics.world_batch.WorldBatch`: every tick advances all running episodes (and computes their
sensors) in one compiled call, the traffic cars of all episodes are driven by one compiled call
(madsim.agents.traffic_fleet), the built-in rewards and dones are one compiled call each
(madsim.agents.component_batch.ComponentBatch, the same code MadrasEnv runs); a tick's learner
side (controls through the T-S PID or S-A-B mapping, rewards, dones, totals, observations) is
three compiled calls over all episodes (madsim.agents.learner_kernel). Each episode keeps its
own track, cars, traffic, random streams, curriculum stage and autoreset, and everything it
returns is bit-identical to a `MadrasEnv` with the same config and seeds
(`tests/envs/test_vector.py` checks this against `gymnasium.vector.SyncVectorEnv` over
`MadrasEnv`s). What stays in Python, per episode: resets
(~0.3 ms each), observation noise and focus readings, action noise draws, user-defined
(registered) rewards, dones and traffic targets, and contact resolution (only when the broad
phase finds something near).

Slot e of the batch holds episode e; its rows follow the env: traffic first, the learner last.
Speed (benchmarks/bench_vector.py, per CPU-second of one core of this project's 2-core
machine): ~250,000 env-steps/s at N = 1024, ~55,000 with four traffic cars per episode, most of
it the cars' own physics sub-steps; for a single episode `MadrasEnv` is faster (the numpy
bookkeeping costs ~150 us per step whatever N; MadrasEnv's step is one compiled call). threads=True shares the compiled part
among numba's threads; on a machine shared with other work set OMP_WAIT_POLICY=passive.
Not supported: scenarios with more than one learning agent or with communication (ConfigError);
rendering.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from madsim.agents import dones as D
from madsim.agents import rewards as R
from madsim.agents.component_batch import ActionMap, ComponentBatch, speed_gear_many
from madsim.agents.curriculum import apply_stage, stage_index
from madsim.agents.learner_kernel import LearnerScratch, tally, tick_controls, tick_outcome
from madsim.agents.observations import ObservationBuilder
from madsim.agents.pid import PIDController
from madsim.agents import traffic_kernel as tk
from madsim.agents.traffic_fleet import TrafficFleet
from madsim.envs.backends import RANGEFINDER_ANGLES_DEG
from madsim.envs.config import ConfigError, ScenarioConfig, action_space, load_config
from madsim.envs.core import default_traffic_factory, episode_seed
from madsim.envs.episode import AssetCache, draw_plan, placements
from madsim.physics.world_batch import WorldBatch
from madsim.physics.schedule import TorcsClock
from madsim.physics.sensors import O_SX

__all__ = ["MadrasVectorEnv", "make_vec"]

TICK_S = R.TICK_S
_STOP = (0.0, 0.0, 1.0)


def make_vec(config=None, num_envs: int = 1, **kwargs) -> MadrasVectorEnv:
    """`MadrasVectorEnv(config, num_envs, **kwargs)`: num_envs episodes of a one-learner
    scenario stepped as one batch. Keywords: traffic_factory, autoreset_mode ("NextStep",
    "SameStep", "Disabled"), contact, fuel, damage, threads (see `MadrasVectorEnv`)."""
    return MadrasVectorEnv(config, num_envs, **kwargs)


class _TorcsTicks:
    """TORCS's driver-call schedule for many episodes at once: the sub-steps of each episode's
    next tick, looked up by its ticks since reset (TorcsClock gives the same sequence after
    every reset; the table grows from one clock as episodes get older)."""

    def __init__(self, n: int):
        self._clock = TorcsClock()
        self._table = np.zeros(0, dtype=np.int64)
        self.ticks = np.zeros(n, dtype=np.int64)      # per episode: ticks since its reset

    def next(self, slots: np.ndarray) -> np.ndarray:
        """(len(slots),) sub-steps of the coming tick of each episode in `slots`; counts it."""
        t = self.ticks[slots]
        need = int(t.max()) + 1 if t.size else 0
        if need > self._table.size:
            more = [self._clock.substeps() for _ in range(max(need, 2 * self._table.size, 256)
                                                          - self._table.size)]
            self._table = np.concatenate([self._table, np.array(more, dtype=np.int64)])
        self.ticks[slots] = t + 1
        return self._table[t]


class _Stage:
    """One curriculum stage's scenario and the scalar components its episodes copy from."""

    def __init__(self, cfg: ScenarioConfig):
        self.cfg = cfg
        agent, s = cfg.agents[0], cfg.server
        self.agent = agent
        self.rewards = R.RewardSet.from_terms(agent.rewards, target_speed=agent.target_speed)
        self.dones = D.DoneSet.from_names(agent.dones, max_steps=s.max_steps, laps=s.laps,
                                          track_limits=s.track_limits,
                                          target_speed=agent.target_speed)


class MadrasVectorEnv(VectorEnv):
    """
    ## Description
    `num_envs` independent episodes of a one-learner MADRaS scenario (see `MadrasEnv`),
    stepped together: one batched World advances every running episode each tick. Cars of
    different episodes never meet (no contact, no opponent readings, separate race positions);
    each episode has its own track, cars, traffic, random streams, curriculum stage and
    autoreset. Episode e behaves exactly as `MadrasEnv(config)` reset with the e-th seed.

    ## Action Space
    `single_action_space`: the learner's Box (as `MadrasEnv`); `action_space` batches it:
    (num_envs, dim) float32. A NaN or a wrong shape raises ValueError naming the episode.

    ## Observation Space
    `single_observation_space` as `MadrasEnv`; observations come as (num_envs, size) float32.

    ## Rewards
    (num_envs,) float64, as `MadrasEnv` per episode.

    ## Starting State
    `reset(seed=s)` seeds episode e with s + e (a list gives one seed per episode; None draws
    from each episode's generator), as `gymnasium.vector.SyncVectorEnv` does; `options` as
    `MadrasEnv` (`{"episode": k}`), plus `reset_mask` ((num_envs,) bool) to reset some only.

    ## Episode Termination
    As `MadrasEnv`, per episode. `autoreset_mode` (gymnasium): "NextStep" (default; the step
    after an episode ended resets it, ignores its action and returns its first observation with
    reward 0 and both flags False), "SameStep" (it is reset in the step that ended it; the last
    observation and info are in `infos["final_obs"]`, `infos["final_info"]`) or "Disabled"
    (reset ended episodes with `reset(options={"reset_mask": ...})`).

    ## Arguments
    `config` (path, mapping or ScenarioConfig, one learning agent, no communication),
    `num_envs`, `traffic_factory` (as `MadrasEnv`), `autoreset_mode`; `contact`, `fuel`,
    `damage` as `LocalBackend`; `threads`: share the episodes among numba's threads
    (bit-identical results). Infos are gymnasium vector infos (arrays with `_key` masks) of the
    `MadrasEnv` infos: reset: seed, episode, stage, track, track_length, car, cars, traffic,
    traffic_count, row, placement; step: reward_terms, dones, ticks.
    `curriculum_progress`: (num_envs,) int array, one counter per episode, writable.

    ## Version History
    - v0: first version (madsim 0.1).
    """

    metadata: ClassVar[dict] = {"render_modes": [], "render_fps": 50,
                                "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, config=None, num_envs: int = 1, *, traffic_factory=None,
                 autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP,
                 contact: bool = True, fuel: bool = False, damage: bool = True,
                 threads: bool = False):
        cfg = config if isinstance(config, ScenarioConfig) else load_config(config)
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) \
                or num_envs < 1:
            raise ValueError(f"num_envs must be an int >= 1, got {num_envs!r}")
        if len(cfg.agents) != 1:
            raise ConfigError(f"make_vec drives one learning car per episode, the config has "
                              f"{len(cfg.agents)}", key="agents")
        if cfg.agents[0].communication is not None:
            raise ConfigError("make_vec does not support communication",
                              key="agents[0].communication")
        self.autoreset_mode = AutoresetMode(autoreset_mode)
        self.metadata = dict(self.metadata, autoreset_mode=self.autoreset_mode)
        self.config = cfg
        self.num_envs = n = int(num_envs)
        self.render_mode = None
        agent = cfg.agents[0]
        self.agent = agent.name
        limits = cfg.server.track_limits
        self.single_action_space = action_space(agent, limits)
        self.builder = ObservationBuilder.from_config(agent.observation)
        self.single_observation_space = self.builder.space
        self.action_space = batch_space(self.single_action_space, n)
        self.observation_space = batch_space(self.single_observation_space, n)
        ts = agent.action.space == "TS"
        self._actions = ActionMap(self.single_action_space.low, self.single_action_space.high,
                                  ts=ts, normalised=agent.action.normalised,
                                  manual=agent.gear == "manual",
                                  pid=PIDController.from_config(agent.pid), track_limits=limits,
                                  n=n)
        self._dim = self._actions.dim
        self.ticks_per_step = agent.pid.latency if ts else 1

        stage_cfgs = [cfg] if cfg.curriculum is None else [
            apply_stage(cfg, st) for st in cfg.curriculum.stages]
        self._stages = [_Stage(c) for c in stage_cfgs]
        capacity = 1 + max(len(c.traffic) if c.server.traffic_count is None
                           else c.server.traffic_count[1] for c in stage_cfgs)
        self._factory = traffic_factory
        if self._factory is None and capacity > 1 and any(c.traffic for c in stage_cfgs):
            self._factory = default_traffic_factory()
        first = self._stages[0]
        self._reward_names = [name for name, _, _ in first.rewards.components]
        self._weights = np.array([w for _, w, _ in first.rewards.components], dtype=np.float64)
        self._rewards = ComponentBatch([c for _, _, c in first.rewards.components], n)
        self._done_names = [name for name, _ in first.dones.components]
        self._is_trunc = np.array([c.truncation for _, c in first.dones.components], dtype=bool)
        self._dones = ComponentBatch([c for _, c in first.dones.components], n)
        self._scalar = bool(self._rewards.python or self._dones.python)
        needs_focus = "focus" in self.builder.fields
        self.batch = WorldBatch(n, capacity, contact=contact, fuel=fuel, damage=damage,
                                threads=threads, focus=needs_focus,
                                angles_deg=RANGEFINDER_ANGLES_DEG)
        self.assets = AssetCache()
        self._torcs = _TorcsTicks(n) if cfg.server.tick_schedule == "torcs" else None

        # per episode
        self._np_random: list = [None] * n         # each episode's gymnasium Env.np_random
        self._action_rng: list = [None] * n
        self.fleet = TrafficFleet(self.batch.sensors.shape[0])   # traffic rows of the batch
        self._traffic_rows = np.arange(capacity - 1)               # traffic: rows 0 .. n - 2
        self._behaviour_cache: dict = {}           # (episode, stage, entry) -> behaviour
        self._n_traffic = np.zeros(n, dtype=np.int64)
        self._stage_of = np.zeros(n, dtype=np.int64)
        self._episode = np.full(n, -1, dtype=np.int64)
        self._resets = np.zeros(n, dtype=np.int64)
        self._progress = np.zeros(n, dtype=np.int64)
        self._row = np.zeros(n, dtype=np.int64)    # the learner's row in the batch
        self._length = np.zeros(n)
        self._live = np.zeros(n, dtype=bool)
        self._started = False
        self._obs = np.zeros((n, self.builder.size), dtype=np.float32)
        self._scratch = LearnerScratch(n, len(self._reward_names), len(self._done_names))
        self._dones_template = np.empty(n, dtype=object)
        for e in range(n):
            self._dones_template[e] = ()

    @property
    def curriculum_progress(self) -> np.ndarray:
        """(num_envs,) episodes started (or steps taken, per the curriculum's unit) so far,
        one counter per episode (MadrasEnv.curriculum_progress of each)."""
        return self._progress

    @curriculum_progress.setter
    def curriculum_progress(self, value) -> None:
        self._progress[:] = np.broadcast_to(np.asarray(value, dtype=np.int64), self._progress.shape)

    # --- episodes ----------------------------------------------------------------------------

    def reset(self, *, seed: int | list | None = None, options: dict[str, Any] | None = None):
        """Reset every episode (or those in options["reset_mask"]); returns (obs, infos)."""
        n = self.num_envs
        if seed is None:
            seeds = [None] * n
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)
            if len(seeds) != n:
                raise ValueError(f"reset: {len(seeds)} seeds for {n} episodes")
        options = dict(options or {})
        mask = options.pop("reset_mask", None)
        if mask is None:
            mask = np.ones(n, dtype=bool)
        else:
            mask = np.asarray(mask)
            if mask.shape != (n,) or mask.dtype != np.bool_ or not mask.any():
                raise ValueError(f'options["reset_mask"] must be a (num_envs,) = ({n},) bool '
                                 'array with at least one True')
        slots = np.flatnonzero(mask)
        infos = self._reset_slots(slots, [seeds[e] for e in slots], options)
        self._started = True
        return self._obs.copy(), infos

    def _reset_slots(self, slots: np.ndarray, seeds: list, options: dict) -> dict:
        """MadrasEnv.reset (MadrasCore.new_episode) for each episode in `slots`."""
        episode_opt = options.get("episode")
        if episode_opt is not None and (isinstance(episode_opt, bool) or not isinstance(
                episode_opt, (int, np.integer)) or episode_opt < 0):
            raise ValueError(f'options["episode"] must be an int >= 0, got {episode_opt!r}')
        cur = self.config.curriculum
        started = []
        for e, seed in zip(slots.tolist(), seeds):
            if seed is not None:
                self._np_random[e], _ = seeding.np_random(seed)
            elif self._np_random[e] is None:
                self._np_random[e], _ = seeding.np_random()
            ep_seed = episode_seed(seed, self._np_random[e])
            self._episode[e] = 0 if seed is not None else self._episode[e] + 1
            if episode_opt is not None:
                self._episode[e] = int(episode_opt)
            if self._resets[e] and cur is not None and cur.unit == "episodes":
                self._progress[e] += 1
            self._resets[e] += 1
            stage = 0 if cur is None else stage_index(cur, int(self._progress[e]))
            started.append(self._start(e, ep_seed, int(self._episode[e]), stage))
        mask = np.zeros(self.num_envs, dtype=bool)
        mask[slots] = True
        batch = self.batch
        batch.sense(mask)
        wait = self.config.server.init_wait * self.ticks_per_step
        rows = self._row[slots]
        for _ in range(wait):           # MADRaS devel's init_wait: stop action, traffic drives
            batch.controls[rows, :3] = _STOP
            batch.controls[rows, 3] = speed_gear_many(batch.sensors[rows, O_SX])
            self._traffic_controls(slots)
            self._tick(mask)
        infos: dict = {}
        for e, info in zip(slots.tolist(), started):
            st = self._stages[self._stage_of[e]]
            length = self._length[e]
            self._rewards.start(e, [c for _, _, c in st.rewards.components], length)
            self._dones.start(e, [c for _, c in st.dones.components], length)
            self._actions.start(e, batch.sensors[self._row[e]], st.agent.target_speed,
                                st.agent.action_noise_std)
            infos = self._add_info(infos, info, e)
        self.builder.observe_rows(batch.sensors, rows, self._obs, slots)
        self._live[slots] = True
        return infos

    def _start(self, e: int, seed: int, episode: int, stage_i: int) -> dict:
        """MadrasCore.reset up to init_wait: draws, placements, the batch slot, traffic."""
        self._stage_of[e] = stage_i
        stage = self._stages[stage_i]
        cfg = stage.cfg
        scenario_ss, obs_ss, action_ss, traffic_ss = np.random.SeedSequence(seed).spawn(4)
        scenario_rng = np.random.default_rng(scenario_ss)
        self._action_rng[e] = np.random.default_rng(action_ss)
        plan = draw_plan(cfg, episode, seed, scenario_rng)
        track = self.assets.track(plan.track)
        cars = [self.assets.car(c) for c in plan.cars]
        where = placements(cfg, plan, track, scenario_rng)
        self.batch.start(e, (plan.track, plan.cars), track, cars, where,
                         noisy=cfg.server.observation_noise, rng=np.random.default_rng(obs_ss))
        if self._torcs is not None:
            self._torcs.ticks[e] = 0
        k = plan.row(self.agent)
        self._row[e] = self.batch.offsets[e] + k
        self._length[e] = track.length
        a = int(self.batch.offsets[e])
        self.fleet.clear(slice(a, a + self.batch.capacity))
        for j, ss in enumerate(traffic_ss.spawn(plan.n_traffic)):
            b = self._behaviour_cache.get((e, stage_i, j))
            if b is None:
                b = self._behaviour_cache[(e, stage_i, j)] = self._factory(cfg.traffic[j])
            b.reset(np.random.default_rng(ss), {
                "track_length": track.length, "track_width": track.width, "index": j,
                "row": j, "car": plan.traffic_cars[j], "tick_s": TICK_S,
                "placement": (float(where[j, 0]), float(where[j, 1]))})
            self.fleet.put(a + j, b)
        compiled = a + np.flatnonzero(np.isin(self.fleet.kind[a:a + plan.n_traffic], tk.COMPILED_KINDS))
        if compiled.size and not cfg.server.observation_noise:   # only the rays they read
            self.batch.cast_only(compiled, tk.RAYS_READ)
        self._n_traffic[e] = plan.n_traffic
        return {"seed": plan.seed, "episode": plan.episode, "stage": stage_i,
                "track": plan.track, "track_length": float(track.length), "cars": plan.cars,
                "traffic": tuple(t.behaviour for t in plan.traffic),
                "traffic_count": plan.n_traffic, "car": plan.agent_cars[0], "row": k,
                "placement": (float(where[k, 0]), float(where[k, 1]))}

    def _tick(self, mask: np.ndarray) -> None:
        """One tick of the episodes in `mask`: 0.02 s, or each episode's next TORCS driver call
        (10 or 11 sub-steps; one batch call per length)."""
        if self._torcs is None:
            self.batch.step(mask)
            return
        slots = np.flatnonzero(mask)
        substeps = self._torcs.next(slots)
        for k in np.unique(substeps).tolist():
            part = np.zeros_like(mask)
            part[slots[substeps == k]] = True
            self.batch.step(part, k)

    def _traffic_controls(self, slots) -> None:
        """Controls of the traffic cars of episodes `slots`, one fleet call."""
        rows = (self.batch.offsets[slots][:, None] + self._traffic_rows).ravel()
        rows = rows[self.fleet.kind[rows] != 0]
        if rows.size:
            self.fleet.act(self.batch.sensors, self.batch.controls, rows)

    # --- step --------------------------------------------------------------------------------

    def step(self, actions):
        """One env step of every episode; returns (obs, rewards, terminations, truncations,
        infos) as arrays over episodes (see the class docstring for autoreset)."""
        if not self._started:
            raise RuntimeError("call reset() before step()")
        n = self.num_envs
        try:
            a = np.asarray(actions, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"actions are not numeric: {actions!r}") from None
        if a.shape != (n, self._dim):
            raise ValueError(f"actions must have shape (num_envs, {self._dim}) = ({n}, "
                             f"{self._dim}), got {a.shape}")
        resetting = ~self._live
        if resetting.any() and self.autoreset_mode == AutoresetMode.DISABLED:
            raise RuntimeError(f"episodes {np.flatnonzero(resetting).tolist()} are over: reset "
                               'them with reset(options={"reset_mask": ...})')
        slots = np.flatnonzero(self._live)
        rewards = np.zeros(n)
        terminated = np.zeros(n, dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        infos: dict = {}
        if slots.size:
            chosen, bad = self._actions.check(a[slots])
            if bad >= 0:
                i, j = divmod(bad, self._dim)
                raise ValueError(f"action for episode {slots[i]} has a non-finite value at "
                                 f"index {j}: {a[slots[i], j]}")
            infos = self._step_slots(slots, chosen, rewards, terminated, truncated)
        if resetting.any() and self.autoreset_mode == AutoresetMode.NEXT_STEP:
            infos = self._merge(infos, self._reset_slots(np.flatnonzero(resetting),
                                                         [None] * int(resetting.sum()), {}))
        ended = np.flatnonzero(terminated | truncated)
        if ended.size and self.autoreset_mode == AutoresetMode.SAME_STEP:
            step_infos = self._slot_infos(infos, ended)
            infos = _drop(infos, ended)
            for e, info in zip(ended.tolist(), step_infos):
                infos = self._add_info(infos, {"final_obs": self._obs[e].copy(),
                                               "final_info": info}, e)
            infos = self._merge(infos, self._reset_slots(ended, [None] * ended.size, {}))
        return self._obs.copy(), rewards, terminated, truncated, infos

    def _step_slots(self, slots, chosen, rewards, terminated, truncated) -> dict:
        """MadrasCore.step for the episodes `slots` with their checked actions (m, dim)."""
        self._actions.begin(slots, chosen, self._action_rng)
        m = slots.shape[0]
        total = np.zeros(m)
        ticks = np.zeros(m, dtype=np.int64)
        term, trunc = np.zeros(m, dtype=bool), np.zeros(m, dtype=bool)
        fired = np.zeros((m, len(self._done_names)), dtype=bool)
        running = np.arange(m)
        mask = np.zeros(self.num_envs, dtype=bool)
        traffic = bool(self._n_traffic[slots].any())
        if self._scalar:                    # MadrasCore hands the checked actions to them
            terms = self._ticks_numpy(slots, running, chosen.tolist(), mask, traffic, total,
                                      ticks, term, trunc, fired)
        else:
            terms = self._ticks_compiled(slots, running, mask, traffic, total, ticks, term,
                                         trunc, fired)
        self.builder.observe_rows(self.batch.sensors, self._row[slots], self._obs, slots)
        rewards[slots] = total
        terminated[slots], truncated[slots] = term, trunc
        self._live[slots] = ~(term | trunc)
        cur = self.config.curriculum
        if cur is not None and cur.unit == "steps":
            self._progress[slots] += 1
        # vector infos as gymnasium's _add_info builds them from MadrasEnv's step infos
        n = self.num_envs
        stepped = np.zeros(n, dtype=bool)
        stepped[slots] = True
        reward_terms: dict = {}
        for name, v in zip(self._reward_names, terms):
            full = np.zeros(n)
            full[slots] = v
            reward_terms[name] = full
            reward_terms["_" + name] = stepped.copy()
        dones = self._dones_template.copy()
        dones[~stepped] = None
        names = self._done_names
        for i in np.flatnonzero(fired.any(axis=1)).tolist():
            dones[slots[i]] = tuple(nm for nm, f in zip(names, fired[i]) if f)
        all_ticks = np.zeros(n, dtype=np.int64)
        all_ticks[slots] = ticks
        return {"reward_terms": reward_terms, "_reward_terms": stepped,
                "dones": dones, "_dones": stepped.copy(),
                "ticks": all_ticks, "_ticks": stepped.copy()}

    def _ticks_compiled(self, slots, running, mask, traffic, total, ticks, term, trunc,
                        fired) -> np.ndarray:
        """The step's ticks of episodes `slots` with built-in rewards and dones only: the
        learners' controls before a tick and its rewards and dones after it in one compiled
        call each (madsim.agents.learner_kernel). Fills total, ticks, term, trunc, fired (per
        position in slots); returns the reward terms (k, m)."""
        batch = self.batch
        u, flat, hits = batch.controls, batch.sensors, batch.hits
        acts, rw, dn = self._actions, self._rewards, self._dones
        ts = acts.controller
        sc = self._scratch
        m = slots.shape[0]
        terms = np.zeros((len(self._reward_names), m))
        left = m
        for k in range(self.ticks_per_step):
            run = slots[running[:left]] if left < m else slots
            rows = self._row[run]
            tick_controls(run, rows, flat, sc.prev, acts.ts, acts.manual, acts.sab, acts.gear,
                          ts.state, ts.params, ts.fresh, ts.lane_des, ts.speed_des_kmh,
                          sc.controls, u)
            if traffic:
                self._traffic_controls(run)
            mask[:] = False
            mask[run] = True
            self._tick(mask)
            left = tick_outcome(rw.codes, rw.par, rw.state, dn.codes, dn.par, dn.state,
                                self._weights, self._is_trunc, running[:left], run, rows, flat,
                                hits, self._length, sc.prev, sc.cur, sc.length, sc.collision,
                                sc.r_vals, sc.d_vals, k == 0, total, terms, ticks, term, trunc,
                                fired, u)
            if left == 0:
                break
        return terms

    def _ticks_numpy(self, slots, running, checked, mask, traffic, total, ticks, term, trunc,
                     fired) -> np.ndarray:
        """`_ticks_compiled` where a reward or done is plain Python: it gets each episode's
        rows and checked action (ComponentBatch.evaluate, numpy over the episodes around the
        compiled built-ins; the bookkeeping is `tick_outcome`'s own, `tally`)."""
        batch = self.batch
        u, flat, hits = batch.controls, batch.sensors, batch.hits
        m = slots.shape[0]
        terms = np.zeros((len(self._reward_names), m))
        for k in range(self.ticks_per_step):
            run = slots[running]
            rows = self._row[run]
            prev = flat[rows]
            u[rows, :4] = self._actions.controls(run, prev)
            if traffic:
                self._traffic_controls(run)
            mask[:] = False
            mask[run] = True
            self._tick(mask)
            cur = flat[rows]
            length = self._length[run]
            collision = hits[rows]
            actions = [checked[i] for i in running.tolist()]
            r_vals = self._rewards.evaluate(run, prev, cur, length, collision, actions)
            d_vals = self._dones.evaluate(run, prev, cur, length, collision, actions)
            left = tally(self._weights, self._is_trunc, running, rows, r_vals, d_vals, k == 0,
                         total, terms, ticks, term, trunc, fired, u)
            running = running[:left]
            if left == 0:
                break
        return terms

    def _slot_infos(self, infos: dict, slots) -> list[dict]:
        """The MadrasEnv step infos of some episodes, taken out of the vector infos."""
        out = []
        terms = infos.get("reward_terms", {})
        for e in slots.tolist():
            out.append({"reward_terms": {k: float(v[e]) for k, v in terms.items()
                                         if not k.startswith("_")},
                        "dones": infos["dones"][e], "ticks": int(infos["ticks"][e])})
        return out

    def _merge(self, infos: dict, more: dict) -> dict:
        """Vector infos of two disjoint sets of episodes in one (as _add_info would build)."""
        for key, value in more.items():
            if key.startswith("_") or key not in infos:
                if key.startswith("_") and key in infos:
                    infos[key] = infos[key] | value
                else:
                    infos[key] = value
                continue
            mask = more["_" + key]
            if isinstance(value, dict):
                infos[key] = self._merge(infos[key], value)
            else:
                infos[key][mask] = value[mask]
        return infos

    def close_extras(self, **kwargs) -> None:
        self.batch = None


def _drop(infos: dict, slots: np.ndarray) -> dict:
    """Vector infos without the entries of `slots` (keys nobody has any more disappear)."""
    out = {}
    for key, value in infos.items():
        if key.startswith("_"):
            continue
        mask = infos["_" + key].copy()
        mask[slots] = False
        if not mask.any():
            continue
        if isinstance(value, dict):
            value = _drop(value, slots)
        else:
            value = value.copy()
            value[slots] = None if value.dtype == object else 0
        out[key], out["_" + key] = value, mask
    return out
