"""The engine under both envs: learning agents and traffic on a backend, tick by tick.

`MadrasCore` holds what the gymnasium env and the PettingZoo env share: the per-agent spaces
(built once, never rebuilt, so a user's `action_space.seed()` is never lost), each agent's
side of the env (action -> controls, rewards, dones), the traffic behaviours, the
communication hub, the curriculum, and the tick loop. Both envs are thin shells around `reset` and `step`, which
take and return dicts keyed by agent name.

One env step (ARCHITECTURE.md, "the tick"): actions are checked (shape, NaN -> ValueError)
and clipped to the action Box, messages are sent (communication), Gaussian action noise is
added from the episode's rng and the result clipped again; then K ticks of 0.02 s (K = 1 for
S-A-B, the PID latency for T-S; equal for every agent), each tick: controls of every car
(T-S agents run their PID on the latest sensors, traffic behaviours act on theirs) ->
backend tick -> sensors -> each agent's rewards (summed over the K ticks) and dones (checked
every tick). An agent that is done leaves at that tick (its observation is the sensors of
that tick), and its car brakes to a stop and stays where it is; the step ends early when no
agent is left.

Traffic behaviours come from `madsim.agents.traffic` (looked up when a config can draw
traffic) or from the `traffic_factory` hook: a callable `factory(entry: TrafficConfig)` ->
an object with `reset(rng, info)` (rng: numpy Generator; info: track_length m, track_width m,
index, row, car, placement (s m, n m), tick_s) and `act(row) -> (steer, accel, brake, gear)`,
row: the car's SCR sensors as a read-only mapping (like `SensorFrame.row`). Every tick one
`TrafficFleet` call drives them all (the built-in behaviours compiled, other objects by `act`).

Each agent's action mapping, T-S controller, rewards and dones are the batch-first code
make_vec runs over its episodes (`madsim.agents.component_batch`, `madsim.agents.learner_kernel`),
here a batch of one per agent. On a World in this process, with every learner's observation a
vector, a step of all learners is one compiled call from the actions on
(`madsim.envs.env_tick`: the same kernels in the same order, the actions' check, clip and take
included, each learner's outcome, MADRaS's episode end, each learner's observation at the tick
it leaves; one S-A-B learner ~13 us a step on a slow 2-core machine, ~4 us of it the Python
around the call), which leaves to Python only what it cannot do: action noise, the messages of
communication, Python traffic behaviours, contact near a car, sensor noise, Python rewards or
dones. The stage-by-stage loop of `step` remains for the rest: an SCR server's cars
(ScrBackend), TORCS's tick schedule, image observations.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Callable, Mapping
from typing import Any

import gymnasium
import numpy as np

from madsim.agents.component_batch import ActionMap, ComponentBatch
from madsim.agents.comms import CommHub
from madsim.agents.curriculum import apply_stage, stage_index
from madsim.agents.dones import DoneSet
from madsim.agents.learner_kernel import (LearnerScratch, begin_step, tally, tick_controls,
                                          tick_outcome)
from madsim.agents.observations import ObservationBuilder
from madsim.agents.pid import PIDController, speed_gear
from madsim.agents.sensor_row import SensorRow
from madsim.agents.rewards import TICK_S, RewardSet
from madsim.agents import traffic_kernel as tk
from madsim.agents.traffic_fleet import TrafficFleet
from madsim.envs.backends import RANGEFINDER_ANGLES_DEG, LocalBackend
from madsim.envs.config import (
    AgentConfig,
    ConfigError,
    ScenarioConfig,
    TrafficConfig,
    action_space,
    load_config,
)
from madsim.envs.env_tick import (ACTION, COMM, CONTROLS, DONE, EPISODE_END, NO_END, OUTCOME,
                                  SENSE, SERVER_END, ST_ANSWER, ST_LEARNER, ST_TICK, STEP, TRAFFIC,
                                  EnvTick)
from madsim.envs.episode import AssetCache, EpisodePlan, draw_plan, placements
from madsim.physics.sensors import O_SX, SensorFrame

__all__ = ["MadrasCore", "SensorRow", "default_traffic_factory", "episode_seed"]

_STOP = (0.0, 0.0, 1.0)           # steer, accel, brake: MADRaS's "stop" action
_WHY = {NO_END: (), EPISODE_END: ("EpisodeEnd",), SERVER_END: ("ServerEnded",)}
_SLOT0 = np.zeros(1, dtype=np.int64)


def default_traffic_factory() -> Callable[[TrafficConfig], Any]:
    """The traffic layer's factory: `madsim.agents.traffic.make_behaviour`, else a class from
    its `BEHAVIOURS` registry built with `from_config(entry)` or `cls(entry)`. ConfigError if
    the traffic layer is not installed."""
    try:
        module = importlib.import_module("madsim.agents.traffic")
    except ModuleNotFoundError as exc:
        if exc.name != "madsim.agents.traffic":
            raise
        raise ConfigError("this scenario drives traffic cars, but the traffic behaviours "
                          "(madsim.agents.traffic) are not installed; set server.traffic_count "
                          "to [0, 0] or pass traffic_factory=", key="traffic") from None
    make = getattr(module, "make_behaviour", None)
    if make is not None:
        return make
    registry = module.BEHAVIOURS

    def build(entry: TrafficConfig):
        cls = registry[entry.behaviour]
        return cls.from_config(entry) if hasattr(cls, "from_config") else cls(entry)
    return build


def episode_seed(seed: int | None, np_random: np.random.Generator) -> int:
    """The seed of an episode: the one given to reset, else a draw from the env's generator."""
    if seed is None:
        return int(np_random.integers(2**63 - 1))
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an int >= 0 or None, got {seed!r}")
    return int(seed)


class _StageAgent:
    """One learning agent in one curriculum stage, as the env sees it: action -> controls every
    tick, its rewards and dones, a batch of one of the code make_vec runs over its episodes
    (madsim.agents.learner_kernel: `tick_controls` before a tick, `tick_outcome` after it; a
    plain-Python reward or done goes through `ComponentBatch.evaluate` and `tally`). Per-episode
    state lives in its action map and component batches (reset each episode); per-step
    outcome in its step arrays. (Not a driver: in madsim a driver chooses actions,
    `madsim.drivers`.)"""

    def __init__(self, agent: AgentConfig, cfg: ScenarioConfig, space: gymnasium.spaces.Box):
        s = cfg.server
        self.name = agent.name
        self.dim = space.shape[0]
        self.shape = (self.dim,)
        self.ts = agent.action.space == "TS"
        self.noise_std = float(agent.action_noise_std)
        self.target_speed = float(agent.target_speed)
        self.actions = ActionMap(space.low, space.high, ts=self.ts,
                                 normalised=agent.action.normalised,
                                 manual=agent.gear == "manual",
                                 pid=PIDController.from_config(agent.pid),
                                 track_limits=s.track_limits, n=1)
        rewards = RewardSet.from_terms(agent.rewards, target_speed=agent.target_speed).components
        dones = DoneSet.from_names(agent.dones, max_steps=s.max_steps, laps=s.laps,
                                   track_limits=s.track_limits,
                                   target_speed=agent.target_speed).components
        self.reward_names = [name for name, _, _ in rewards]
        self.weights = np.array([w for _, w, _ in rewards], dtype=np.float64)
        self.reward_components = [c for _, _, c in rewards]
        self.rewards = ComponentBatch(self.reward_components, 1)
        self.done_names = [name for name, _ in dones]
        self.is_trunc = np.array([c.truncation for _, c in dones], dtype=bool)
        self.done_components = [c for _, c in dones]
        self.dones = ComponentBatch(self.done_components, 1)
        self.python = bool(self.rewards.python or self.dones.python)
        k, kd = len(self.reward_names), len(self.done_names)
        self.scratch = LearnerScratch(1, k, kd)
        self.track_length = np.zeros(1)
        self.rows = np.zeros(1, dtype=np.int64)       # the agent's car row in the episode
        # the step's outcome, as make_vec's per-episode step arrays (one position)
        self.total, self.terms = np.zeros(1), np.zeros((k, 1))
        self._terms0 = self.terms[:, 0]       # the one position's terms (a view)
        self.ticks = np.zeros(1, dtype=np.int64)
        self.term, self.trunc = np.zeros(1, dtype=bool), np.zeros(1, dtype=bool)
        self.fired = np.zeros((1, kd), dtype=bool)
        self.running = np.zeros(1, dtype=np.int64)
        self.chosen = np.zeros((1, self.dim))  # the compiled step's checked action
        self.action: np.ndarray | None = None
        self.why = np.zeros(1, dtype=np.int64)  # an end that is not a done (env_tick's NO_END...)
        self.frame = None                       # the frame of its observation

    def array(self, action) -> np.ndarray:
        """The action as a float64 array of the Box's shape (dim,); ValueError if it is not
        numeric or has another shape."""
        try:
            a = np.asarray(action, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"action for agent {self.name!r} is not numeric: {action!r}") from None
        if a.shape != self.shape:
            raise ValueError(f"action for agent {self.name!r} must have shape ({self.dim},), "
                             f"got {a.shape}")
        return a

    def non_finite(self, index: int, value) -> ValueError:
        """The error of an action whose component `index` is `value`, not finite."""
        return ValueError(f"action for agent {self.name!r} has a non-finite value at "
                          f"index {index}: {value}")

    def check(self, action) -> np.ndarray:
        """The action (dim,) float64 clipped into the Box; ValueError if malformed."""
        a = self.array(action)
        clipped, bad = self.actions.check(a)
        if bad >= 0:
            raise self.non_finite(bad, a[bad])
        return clipped

    def begin(self, action: np.ndarray, rng: np.random.Generator) -> None:
        """Take this step's (checked) action: add noise, map to controls / PID targets; clear
        the step's outcome."""
        self.action = action
        a = self.actions
        ts = a.controller
        begin_step(_SLOT0, a.noised(_SLOT0, action[None, :], (rng,)), a.ts, a.normalised, a.manual,
                   ts.compat, ts.low, ts.high, ts.target_speed, a.sab, a.gear, ts.lane_des,
                   ts.speed_des_kmh, self.total, self.ticks, self.term, self.trunc, self.fired,
                   self.running)
        self.why[0] = NO_END

    def fill(self, flat: np.ndarray, u: np.ndarray) -> None:
        """Write the controls of the coming tick into the agent's row of u (N, 5) from the
        latest sensors flat (N, 79) (kept as the tick's `prev`)."""
        a, ts, sc = self.actions, self.actions.controller, self.scratch
        tick_controls(_SLOT0, self.rows, flat, sc.prev, a.ts, a.manual, a.sab, a.gear, ts.state,
                      ts.params, ts.fresh, ts.lane_des, ts.speed_des_kmh, sc.controls, u)

    def outcome(self, flat: np.ndarray, hits: np.ndarray, u: np.ndarray, first: bool) -> bool:
        """Rewards and dones of the tick just done from the sensors flat (N, 79) and contact
        flags hits (N,) after it; an agent that ended gets the stop controls in u. True while
        the agent is still running."""
        sc = self.scratch
        if not self.python:
            rw, dn = self.rewards, self.dones
            return tick_outcome(rw.codes, rw.par, rw.state, dn.codes, dn.par, dn.state,
                                self.weights, self.is_trunc, self.running, _SLOT0, self.rows,
                                flat, hits, self.track_length, sc.prev, sc.cur, sc.length,
                                sc.collision, sc.r_vals, sc.d_vals, first, self.total,
                                self.terms, self.ticks, self.term, self.trunc, self.fired,
                                u) > 0
        prev, cur = sc.prev[:1], flat[self.rows]
        hit = hits[self.rows]
        actions = [self.action.tolist()]
        r_vals = self.rewards.evaluate(_SLOT0, prev, cur, self.track_length, hit, actions)
        d_vals = self.dones.evaluate(_SLOT0, prev, cur, self.track_length, hit, actions)
        return tally(self.weights, self.is_trunc, self.running, self.rows, r_vals, d_vals, first,
                     self.total, self.terms, self.ticks, self.term, self.trunc, self.fired,
                     u) > 0

    def end(self, why: int, frame, u: np.ndarray, *, truncated: bool) -> None:
        """End the agent's step for a reason that is not one of its dones (SERVER_END: the
        server ended the race; EPISODE_END: another learner's done ended the episode); with u,
        its car stops (as env_tick's `_episode_end`)."""
        self.why[0] = why
        self.term[0], self.trunc[0] = not truncated, truncated
        self.frame = frame
        if u is not None:
            k = self.rows[0]
            u[k, :3] = _STOP
            u[k, 4] = 0.0

    def result(self) -> tuple[float, dict, bool, bool, tuple[str, ...], int]:
        """(reward, reward terms by name, terminated, truncated, dones fired, ticks) of the
        step."""
        ticks = int(self.ticks[0])
        terms = dict(zip(self.reward_names, self._terms0.tolist())) if ticks else {}
        term, trunc = bool(self.term[0]), bool(self.trunc[0])
        fired = ()
        if term or trunc:
            fired = _WHY[int(self.why[0])] or tuple(
                n for n, f in zip(self.done_names, self.fired[0].tolist()) if f)
        return float(self.total[0]), terms, term, trunc, fired, ticks

    def reset(self, k: int, row: np.ndarray, track_length: float) -> None:
        """Start an episode with the agent's car in row k from its first sensor row (79,) on a
        track of length m."""
        self.rows[0] = k
        self.why[0] = NO_END
        self.rewards.start(0, self.reward_components, track_length)
        self.dones.start(0, self.done_components, track_length)
        self.actions.start(0, row, self.target_speed, self.noise_std)
        self.track_length[0] = track_length


@dataclasses.dataclass
class _Stage:
    cfg: ScenarioConfig
    agents: dict[str, _StageAgent]
    traffic: list            # behaviour objects, one per cfg.traffic entry (None: not built)


class MadrasCore:
    """Agents, traffic, backend and tick loop shared by MadrasEnv and MadrasParallelEnv.

    config: a path, a mapping or a ScenarioConfig; backend: LocalBackend() by default;
    traffic_factory: see the module docstring (default: the traffic layer's).
    """

    def __init__(self, config=None, *, backend=None, traffic_factory=None):
        cfg = config if isinstance(config, ScenarioConfig) else load_config(config)
        self.config = cfg
        self.names = cfg.agent_names
        limits = cfg.server.track_limits
        self.action_spaces = {a.name: action_space(a, limits) for a in cfg.agents}
        self.builders = {a.name: ObservationBuilder.from_config(a.observation) for a in cfg.agents}
        links = {a.name: a.communication for a in cfg.agents if a.communication is not None}
        self.hub = CommHub(links, self.action_spaces) if links else None
        self.observation_spaces = {}
        for a in cfg.agents:
            space = self.builders[a.name].space
            if self.hub is not None and a.name in links:
                comm = self.hub.space(a.name)
                space = gymnasium.spaces.Box(np.concatenate([space.low, comm.low]),
                                             np.concatenate([space.high, comm.high]),
                                             dtype=np.float32)
            self.observation_spaces[a.name] = space
        ticks = {a.name: a.pid.latency if a.action.space == "TS" else 1 for a in cfg.agents}
        if len(set(ticks.values())) > 1:
            raise ConfigError("all agents of a scenario must take the same number of ticks per "
                              "step (S-A-B: 1, T-S: pid.latency); got "
                              + ", ".join(f"{n}: {k}" for n, k in ticks.items()), key="agents")
        self.ticks_per_step = next(iter(ticks.values()))
        self.backend = backend if backend is not None else LocalBackend()
        self.backend.check(cfg)
        self.assets = AssetCache()
        self._factory = traffic_factory
        if self._factory is None and self._may_drive_traffic():
            self._factory = default_traffic_factory()
        self._stages: dict[int, _Stage] = {}
        self.progress = 0            # episodes or steps, the curriculum's unit
        self._count_steps = self._unit() == "steps"
        self.episode = -1            # index k of the current episode (order "fixed")
        self.resets = 0
        self.live: list[str] = []
        self._end_together = False   # server.episode_end "any": the first done ends every learner
        self.plan: EpisodePlan | None = None
        self._compiled: EnvTick | None = None      # the episode's compiled step, if any
        self._learner: dict[str, int] = {}         # its learners' indices, by name
        self.fleet = TrafficFleet(0)
        self.stage: _Stage = self._stage(0)

    # --- configuration per curriculum stage -----------------------------------------------

    def _may_drive_traffic(self) -> bool:
        cfgs = [self.config]
        if self.config.curriculum is not None:
            cfgs += [apply_stage(self.config, st) for st in self.config.curriculum.stages]
        for c in cfgs:
            count = c.server.traffic_count
            if c.traffic and (count is None or count[1] > 0):
                return True
        return False

    def stage_index(self) -> int:
        """Index of the curriculum stage in force at the current progress (0 without one)."""
        cur = self.config.curriculum
        return 0 if cur is None else stage_index(cur, self.progress)

    def _stage(self, index: int) -> _Stage:
        stage = self._stages.get(index)
        if stage is None:
            cfg = self.config
            if cfg.curriculum is not None:
                cfg = apply_stage(cfg, cfg.curriculum.stages[index])
            agents = {a.name: _StageAgent(a, cfg, self.action_spaces[a.name]) for a in cfg.agents}
            stage = self._stages[index] = _Stage(cfg, agents, [None] * len(cfg.traffic))
        return stage

    def _behaviour(self, stage: _Stage, j: int):
        if stage.traffic[j] is None:
            stage.traffic[j] = self._factory(stage.cfg.traffic[j])
        return stage.traffic[j]

    # --- episode --------------------------------------------------------------------------

    def new_episode(self, seed: int | None, options: Mapping | None,
                    np_random: np.random.Generator) -> tuple[dict, dict]:
        """reset() of both envs: the episode seed (`seed`, else drawn from the env's
        generator), the episode index (0 after a seeded reset, else +1; `options["episode"]`
        overrides; other options are ignored) and the curriculum's episode count."""
        ep_seed = episode_seed(seed, np_random)
        self.episode = 0 if seed is not None else self.episode + 1
        if options and "episode" in options:
            episode = options["episode"]
            if isinstance(episode, bool) or not isinstance(episode, (int, np.integer)) or episode < 0:
                raise ValueError(f'options["episode"] must be an int >= 0, got {episode!r}')
            self.episode = int(episode)
        if self.resets and self._unit() == "episodes":
            self.progress += 1
        self.resets += 1
        return self.reset(ep_seed, self.episode)

    def _unit(self) -> str | None:
        cur = self.config.curriculum
        return None if cur is None else cur.unit

    def reset(self, seed: int, episode: int) -> tuple[dict, dict]:
        """Start episode `episode` from `seed`; returns (observations, infos) by agent."""
        self.stage = stage = self._stage(self.stage_index())
        cfg = stage.cfg
        scenario_ss, obs_ss, action_ss, traffic_ss = np.random.SeedSequence(seed).spawn(4)
        scenario_rng = np.random.default_rng(scenario_ss)
        self.action_rng = np.random.default_rng(action_ss)
        self.plan = plan = draw_plan(cfg, episode, seed, scenario_rng)
        self.track = track = self.assets.track(plan.track)
        cars = [self.assets.car(c) for c in plan.cars]
        for builder in self.builders.values():
            if hasattr(builder, "reset"):          # image observations: this episode's track
                builder.reset(track, cars)
        where = placements(cfg, plan, track, scenario_rng)
        frame = self.backend.start((plan.track, plan.cars), track, cars, where,
                                   noisy=cfg.server.observation_noise,
                                   rng=np.random.default_rng(obs_ss),
                                   tick_schedule=cfg.server.tick_schedule)
        self.frame = frame
        self.controls = np.zeros((len(plan.cars), 5))
        self.agent_rows = {name: plan.row(name) for name in plan.agents}
        self.behaviours = [self._behaviour(stage, j) for j in range(plan.n_traffic)]
        if self.fleet.n != len(plan.cars):
            self.fleet = TrafficFleet(len(plan.cars))
        self.fleet.clear(slice(None))
        for j, (b, ss) in enumerate(zip(self.behaviours, traffic_ss.spawn(plan.n_traffic))):
            b.reset(np.random.default_rng(ss), {
                "track_length": track.length, "track_width": track.width, "index": j,
                "row": j, "car": plan.traffic_cars[j], "tick_s": TICK_S,
                "placement": (float(where[j, 0]), float(where[j, 1]))})
            self.fleet.put(j, b)
        self._traffic_rows = np.arange(plan.n_traffic)
        self._cast_read_rays(plan.n_traffic)
        self.live = list(plan.agents)
        self._end_together = cfg.server.episode_end == "any"
        self.tick = 0
        self._init_wait(cfg.server.init_wait * self.ticks_per_step)
        for name in self.live:
            k = self.agent_rows[name]
            stage.agents[name].reset(k, self.frame.flat[k], track.length)
        self._no_hits = np.zeros(len(plan.cars), dtype=bool)
        self._compiled = self._compiled_step()
        if self.hub is not None:
            self.hub.reset()
        shared = {"seed": plan.seed, "episode": plan.episode, "stage": self.stage_index(),
                  "track": plan.track, "track_length": float(track.length), "cars": plan.cars,
                  "traffic": tuple(t.behaviour for t in plan.traffic),
                  "traffic_count": plan.n_traffic}
        infos = {}
        for name, car in zip(plan.agents, plan.agent_cars):
            k = self.agent_rows[name]
            infos[name] = dict(shared, car=car, row=k,
                               placement=(float(where[k, 0]), float(where[k, 1])))
        obs = {name: self._observe(name, self.frame, self.agent_rows[name]) for name in self.live}
        return obs, infos

    def _compiled_step(self) -> EnvTick | None:
        """The episode's compiled step (`madsim.envs.env_tick`) where it applies: every
        learner's observation a vector, a World in this process with contact and fixed 0.02 s
        ticks. Else None: the step runs stage by stage in Python."""
        backend = self.backend
        if not isinstance(backend, LocalBackend) or backend.clock is not None \
                or backend.world.tick_args is None:
            return None
        builders = [self.builders[name] for name in self.live]
        if not all(isinstance(b, ObservationBuilder) for b in builders):
            return None
        tick = EnvTick(backend.world, backend.suite, self.controls,
                       [self.stage.agents[name] for name in self.live], builders,
                       self.frame.flat, self.fleet, self._traffic_rows,
                       together=self._end_together, comm=self.hub is not None)
        self._learner = {name: j for j, name in enumerate(self.live)}
        self.frame = SensorFrame(tick.flat, tick.cars)      # the latest sensors, in place
        return tick

    def view_state(self):
        """What an `EnvView` draws of the current tick (madsim.render.envview.ViewState):
        every car, the first live learner followed; None before the first reset."""
        plan = self.plan
        if plan is None:
            return None
        from madsim.render.envview import ViewState

        live = [plan.row(n) for n in self.live] or [plan.row(n) for n in plan.agents]
        k = live[0]
        self._complete_rays()
        world = getattr(self.backend, "world", None)
        suite = getattr(self.backend, "suite", None)
        cars = [self.assets.car(name) for name in plan.cars]
        return ViewState(
            track=self.track, frame=self.frame, focus=k, world=world,
            ids=tuple(f"T{j}" for j in range(plan.n_traffic)) + plan.agents, kinds=plan.kinds,
            angles_deg=suite.angles_deg[k] if suite is not None else RANGEFINDER_ANGLES_DEG,
            ticks_per_step=self.ticks_per_step,
            body_m=np.array([(c.body_length, c.body_width) for c in cars], dtype=np.float64))

    @property
    def rows(self) -> list[SensorRow]:
        """The latest sensors of every car, as SensorRows (by car row)."""
        self._complete_rays()
        return [SensorRow(v) for v in self.frame.flat.tolist()]

    def _cast_read_rays(self, n_traffic: int) -> None:
        """Compiled traffic cars get only the rays their behaviours read cast each tick
        (`traffic_kernel.RAYS_READ`; not with sensor noise); `_complete_rays` casts the rest
        for a public read."""
        suite = getattr(self.backend, "suite", None)
        if suite is None:
            return
        suite.cast_all()
        compiled = np.flatnonzero(np.isin(self.fleet.kind[:n_traffic], tk.COMPILED_KINDS))
        if compiled.size and not suite.noisy:
            suite.cast_only(compiled, tk.RAYS_READ)

    def _complete_rays(self) -> None:
        """Every ray of the latest frame cast (the rays `_cast_read_rays` left out)."""
        suite, frame = getattr(self.backend, "suite", None), getattr(self, "frame", None)
        if suite is not None and frame is not None:
            suite.complete(frame.flat, frame.cars)

    def _init_wait(self, ticks: int) -> None:
        """MADRaS devel's init_wait: learners hold the stop action, traffic drives."""
        for _ in range(ticks):
            for name in self.live:
                k = self.agent_rows[name]
                self.controls[k, :3] = _STOP
                self.controls[k, 3] = speed_gear(self.frame.flat[k, O_SX])
            self._traffic_controls(self.frame)
            frame = self.backend.step(self.controls)
            if frame is None:
                raise ConnectionError("the simulator ended the race during init_wait")
            self.frame = frame

    def _traffic_controls(self, frame) -> None:
        """Traffic controls for the coming tick from the latest sensors (one fleet call)."""
        self.fleet.act(frame.flat, self.controls, self._traffic_rows)

    def _observe(self, name: str, frame, k: int) -> np.ndarray:
        obs = self.builders[name].from_frame(frame, k)
        if self.hub is not None and name in self.hub.buffers:
            obs = np.concatenate([obs, self.hub.vector(name)])
        return obs

    # --- step -----------------------------------------------------------------------------

    def step(self, actions: Mapping[str, Any]):
        """One env step for every live agent; returns (obs, rewards, terminated, truncated,
        infos), dicts over the agents that were live at the start of the step."""
        if not self.live:
            raise RuntimeError("the episode is over (or never started): call reset()")
        for name in actions:
            if name not in self.action_spaces:
                raise ValueError(f"action for unknown agent {name!r}; agents: {self.names}")
        tick = self._compiled
        if tick is not None and tick.fused:
            if tick.m == 1:
                name = self.live[0]
                if name not in actions:
                    raise ValueError(f"no action for live agent {name!r}")
                obs, reward, term, trunc, info = self.step_one(name, actions[name])
                return {name: obs}, {name: reward}, {name: term}, {name: trunc}, {name: info}
            self._hand_in(actions)
            return self._step_compiled(ACTION)
        agents = self.stage.agents
        chosen = {}
        for name in self.live:
            if name not in actions:
                raise ValueError(f"no action for live agent {name!r}")
            chosen[name] = agents[name].check(actions[name])
        if self.hub is not None:
            self._send(chosen)
        stepping = [agents[name] for name in self.live]
        for agent in stepping:
            agent.begin(chosen[agent.name], self.action_rng)
        if tick is not None:
            return self._step_compiled(CONTROLS)
        running = stepping
        u = self.controls
        backend = self.backend
        frame = self.frame
        for t in range(self.ticks_per_step):
            flat = frame.flat
            for agent in running:
                agent.fill(flat, u)
            if self.behaviours:
                self._traffic_controls(frame)    # this tick's sensors, not the step's first
            new = backend.step(u)
            self.tick += 1
            if new is None:                          # the server ended the race
                for agent in running:
                    agent.end(SERVER_END, frame, None, truncated=True)
                running = []
                break
            frame = new
            hits = backend.collisions()
            if hits is None:
                hits = self._no_hits
            still = []
            for agent in running:
                if agent.outcome(frame.flat, hits, u, t == 0):
                    still.append(agent)
                else:
                    agent.frame = frame
            if self._end_together and len(still) < len(running):
                for agent in still:    # MADRaS: the first done ends every learner's episode
                    agent.end(EPISODE_END, frame, u, truncated=False)
                still = []
            running = still
            if not running:
                break
        self.frame = frame
        for agent in running:
            agent.frame = frame
        agent_rows = self.agent_rows
        obs, rewards, terminated, truncated, infos = {}, {}, {}, {}, {}
        for agent in stepping:
            name = agent.name
            r, terms, term, trunc, fired, ticks = agent.result()
            obs[name] = self._observe(name, agent.frame, agent_rows[name])
            rewards[name] = r
            terminated[name] = term
            truncated[name] = trunc
            infos[name] = {"reward_terms": terms, "dones": fired, "ticks": ticks}
        self.live = [n for n in self.live if not (terminated[n] or truncated[n])]
        if self._count_steps:
            self.progress += 1
        return obs, rewards, terminated, truncated, infos

    def _send(self, chosen: Mapping[str, np.ndarray]) -> None:
        """Communication: the live learners' messages of this step (their sensors before it,
        their checked actions) into the hub."""
        rows, agent_rows = self.rows, self.agent_rows
        self.hub.send({n: rows[agent_rows[n]] for n in self.live},
                      {n: a.tolist() for n, a in chosen.items()})

    def step_one(self, name: str, action):
        """`step({name: action})` for `name`, the one learner (MadrasEnv's door), as (obs,
        reward, terminated, truncated, info): on the fused compiled step no dict is built."""
        tick = self._compiled
        if tick is None or not tick.fused or tick.m != 1 or not self.live:
            obs, rewards, terminated, truncated, infos = self.step({name: action})
            return obs[name], rewards[name], terminated[name], truncated[name], infos[name]
        # the compiled step from ACTION: the action's check, clip and take in the call
        agent = tick.agents[0]
        a = action
        if type(a) is not np.ndarray or a.dtype.kind != "f" or a.shape != agent.shape:
            a = agent.array(action)           # anything else as check() takes it, or its error
        tick.action_rows[0][:] = a            # float64, as np.asarray(a, dtype=np.float64)
        self._run_compiled(ACTION)
        r, terms, term, trunc, fired, n = agent.result()
        if term or trunc:
            self.live = []
        obs = tick.obs_rows[0].copy() if self.hub is None else self._compiled_obs(0, name)
        return obs, r, term, trunc, {"reward_terms": terms, "dones": fired, "ticks": n}

    def _hand_in(self, actions: Mapping[str, Any]) -> None:
        """The live learners' actions into the compiled step's action rows, as float64; the
        stage path's ValueError for the first learner (in order) whose action is missing, not
        numeric, of another shape or, before it, not finite."""
        tick = self._compiled
        agents, index = tick.agents, self._learner
        for i, name in enumerate(self.live):
            j = index[name]
            agent = agents[j]
            try:
                if name not in actions:
                    raise ValueError(f"no action for live agent {name!r}")
                a = actions[name]
                if type(a) is not np.ndarray or a.dtype.kind != "f" or a.shape != agent.shape:
                    a = agent.array(a)
            except ValueError:
                for earlier in self.live[:i]:    # the stage path checks them in order
                    agents[index[earlier]].check(actions[earlier])
                raise
            tick.action_rows[j][:] = a

    def _compiled_obs(self, j: int, name: str) -> np.ndarray:
        """Learner j's observation after the compiled step (a copy), its messages appended."""
        obs = self._compiled.obs_rows[j].copy()
        if self.hub is not None and name in self.hub.buffers:
            obs = np.concatenate([obs, self.hub.vector(name)])
        return obs

    def _run_compiled(self, first: int) -> None:
        """`step`'s ticks as `EnvTick` calls from stage `first` (one, unless a stage is left to
        Python: the messages, traffic controls, the contact narrow phase, sensor noise, Python
        rewards or dones)."""
        tick = self._compiled
        ticks = self.ticks_per_step
        stage = tick.run(first, 0, ticks)
        while stage != DONE:
            k = int(tick.status[ST_TICK])
            if stage == ACTION:                      # nothing has changed
                j = int(tick.status[ST_LEARNER])
                raise tick.agents[j].non_finite(k, tick.action_rows[j][k])
            if stage == COMM:
                agents, index = tick.agents, self._learner
                self._send({n: agents[index[n]].chosen[0] for n in self.live})
            elif stage == TRAFFIC:
                self._traffic_controls(self.frame)
            elif stage == STEP:
                tick.finish_step()
            elif stage == SENSE:
                self.backend.suite.finish_frame(tick.flat, tick.cars, tick.due)
            else:                                   # OUTCOME: a learner's Python reward or done
                agent = tick.agents[int(tick.status[ST_LEARNER])]
                tick.status[ST_ANSWER] = agent.outcome(tick.flat, tick.hits, self.controls, k == 0)
                stage = tick.run(OUTCOME, k, ticks)     # on from that learner's answer
                continue
            stage = tick.run(stage + 1, k, ticks)
        self.tick += int(tick.status[ST_TICK]) + 1
        if self._count_steps:
            self.progress += 1

    def _step_compiled(self, first: int):
        """`step` on the compiled step from stage `first`: (obs, rewards, terminated,
        truncated, infos) of the learners live at its start."""
        stepping = self.live
        self._run_compiled(first)
        tick, index = self._compiled, self._learner
        obs, rewards, terminated, truncated, infos = {}, {}, {}, {}, {}
        for name in stepping:
            j = index[name]
            r, terms, term, trunc, fired, n = tick.agents[j].result()
            obs[name] = self._compiled_obs(j, name)
            rewards[name] = r
            terminated[name] = term
            truncated[name] = trunc
            infos[name] = {"reward_terms": terms, "dones": fired, "ticks": n}
        self.live = [n for n in stepping if not (terminated[n] or truncated[n])]
        return obs, rewards, terminated, truncated, infos

    def close(self) -> None:
        self.backend.close()


class CurriculumProgress:
    """Mixin for the envs: `curriculum_progress`, the episodes started (or steps taken, per the
    curriculum's unit) so far; a training callback may set it."""

    core: MadrasCore

    @property
    def curriculum_progress(self) -> int:
        return self.core.progress

    @curriculum_progress.setter
    def curriculum_progress(self, value: int) -> None:
        self.core.progress = int(value)
