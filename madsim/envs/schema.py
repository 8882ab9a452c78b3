"""The scenario schema: frozen, validated dataclasses, one per section of a scenario file.

Every key, its unit and default is a field of the dataclasses below; each checks its own
ranges and relations in `__post_init__` and raises `ConfigError` with the key at fault.
YAML is read into them by `madsim.envs.loader`; MADRaS's files are first translated by
`madsim.envs.madras_format`. The YAML sections are the fields of `ScenarioConfig`; the
`server` section (MADRaS's name) holds the episode settings, `EpisodeConfig`.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar

from madsim.agents import curriculum as _curriculum
from madsim.agents.comms import COMM_VARIABLES
from madsim.agents.dones import DONES
from madsim.agents.observations import OBSERVATION_MODES, SCR_FIELDS
from madsim.agents.pid import MADRAS_ACCEL_GAINS, MADRAS_STEER_GAINS
from madsim.agents.rewards import REWARD_ALIASES, REWARDS, make_reward, reward_params
from madsim.physics.schedule import SCHEDULES as TICK_SCHEDULES
from madsim.physics.tables import QUICKRACE_GRID
from madsim.envs.validation import (
    ConfigError,
    as_number,
    as_pair,
    check_choice,
    check_positive,
    fail,
    frozen_map,
    join_key,
    set_field,
    unknown_name,
)

__all__ = [
    "DEFAULT_CAR",
    "DEFAULT_DONES",
    "DEFAULT_REWARDS",
    "DEFAULT_TRACK",
    "SECTIONS",
    "TRAFFIC_BEHAVIOURS",
    "TRAFFIC_PARAMS",
    "ActionConfig",
    "AgentConfig",
    "CommConfig",
    "CurriculumConfig",
    "EpisodeConfig",
    "GridConfig",
    "ObservationConfig",
    "PidConfig",
    "RewardTerm",
    "ScenarioConfig",
    "StageConfig",
    "TrafficConfig",
    "generated_track_args",
]

DEFAULT_TRACK = "madsim-road"
DEFAULT_CAR = "madsim-sedan"
QUICKRACE_DISTANCE_TO_START_M = QUICKRACE_GRID["distance to start"]


def _on_road(entry) -> None:
    """initial_trackpos must place a car on the road: trackPos is -1..1 edge to edge."""
    pos = entry.initial_trackpos
    if pos is not None and (pos[0] < -1.0 or pos[1] > 1.0):
        fail("initial_trackpos", "must lie within [-1, 1] (trackPos: -1 right edge, +1 left edge, "
             "0 centre line; beyond is off the road)", list(pos))


def generated_track_args(entry: str) -> dict | None:
    """Arguments of `generate_track_xml` for a "generated:<seed>[:<length_m>[:<width_m>]]"
    track entry; None for a track name or path. ValueError if malformed."""
    if not entry.startswith("generated:"):
        return None
    parts = entry.split(":")[1:]
    if not 1 <= len(parts) <= 3:
        raise ValueError("expected generated:<seed>[:<length_m>[:<width_m>]]")
    try:
        seed = int(parts[0])
        sizes = [float(p) for p in parts[1:]]
    except ValueError:
        raise ValueError("expected generated:<seed>[:<length_m>[:<width_m>]] with numbers") from None
    if seed < 0 or any(not math.isfinite(s) or s <= 0 for s in sizes):
        raise ValueError("seed must be >= 0 and sizes > 0")
    return dict(seed=seed, **dict(zip(("length_m", "width_m"), sizes)))


@dataclass(frozen=True, kw_only=True)
class GridConfig:
    """The race's starting grid as a TORCS race file gives it (its `Starting Grid` section; the
    values `madsim serve --grid` takes, same names with `_` for spaces), m. A value left out
    keeps TORCS's quickrace grid (2 rows, 25 m to the start line, columns 20 m apart, 10 m
    offset within a column); the track's own grid overrides all of them, as in TORCS. Cars
    take the slots in row order (traffic first, then the learners). The lateral position
    follows from `rows` as in TORCS: 1 row puts every car on the centre line; one car's own
    lateral start is `initial_trackpos: [p, p]`. E.g. {rows: 1, distance_to_start: 100} is the
    start of the real-TORCS traces."""

    rows: int | None = None
    distance_to_start: float | None = None
    distance_between_columns: float | None = None
    offset_within_a_column: float | None = None

    def __post_init__(self):
        check_positive(self, "rows")
        check_positive(self, "distance_to_start", "distance_between_columns",
                       "offset_within_a_column", allow_zero=True)

    def race_grid(self, distance_to_start: float) -> dict[str, float]:
        """The values under their TORCS names (`World.reset(grid=...)`); `distance_to_start`
        (server.distance_to_start) where this grid does not set it."""
        out = {"distance to start": float(distance_to_start)}
        for f in fields(self):
            value = getattr(self, f.name)
            if value is not None:
                out[f.name.replace("_", " ")] = float(value)
        return out


@dataclass(frozen=True, kw_only=True)
class EpisodeConfig:
    """What every episode draws from (MADRaS `server_config` and env-level keys).

    Per episode k (counted from 0 at the env's creation) and learning agent i:
    order "fixed": track = tracks[k mod len], car = cars[(k + i) mod len] (agents without a
    fixed `car`), traffic count = min + k mod (max - min + 1); order "random": uniform draws
    from the episode's rng (categorical track and car, discrete-uniform count; paper App. C).
    traffic_count None means every traffic entry, every episode. max_steps counts 0.02 s ticks
    (None: ceil(L / (target_speed * 0.02 s)), one lap at the target speed).

    tick_schedule: when the agents act. "fixed" (the default): every 0.02 s of simulated time.
    "torcs": on real TORCS's own driver-call schedule, 0.02 or 0.022 s apart
    (`madsim.physics.schedule.TorcsClock`, as `madsim serve --tick-schedule torcs`), tick for
    tick from each reset, so a real-TORCS trace can be replayed; ticks are still counted as
    0.02 s where time is derived from them (max_steps, AvgSpeed, traffic's clock).
    episode_end (several learners): "each" (the default, PettingZoo's way) lets the others drive
    on when one learner is done; "any" ends every learner's episode on the tick the first one is
    done, as MADRaS's multi-agent env does (`done["__all__"] = any`, its agents' PID sub-step
    loops stopped together); the others end terminated with the done "EpisodeEnd".
    grid: the starting grid (`GridConfig`); None: TORCS's quickrace grid with distance_to_start
    (a distance to start is given either here or as grid.distance_to_start, not both)."""

    tracks: tuple[str, ...] = (DEFAULT_TRACK,)
    cars: tuple[str, ...] = (DEFAULT_CAR,)
    traffic_car: str = DEFAULT_CAR
    traffic_count: tuple[int, int] | None = None
    order: str = "fixed"
    observation_noise: bool = False
    max_steps: int | None = 20000
    track_limits: tuple[float, float] = (-1.0, 1.0)
    distance_to_start: float = QUICKRACE_DISTANCE_TO_START_M
    laps: int = 1
    init_wait: int = 0
    tick_schedule: str = "fixed"
    episode_end: str = "each"
    grid: GridConfig | None = None

    def __post_init__(self):
        for name in ("tracks", "cars"):
            if not getattr(self, name):
                fail(name, "needs at least one entry", list(getattr(self, name)))
            for i, entry in enumerate(getattr(self, name)):
                if not entry:
                    fail(f"{name}[{i}]", "empty name", entry)
        for i, entry in enumerate(self.tracks):
            try:
                generated_track_args(entry)
            except ValueError as exc:
                fail(f"tracks[{i}]", str(exc), entry)
        if not self.traffic_car:
            fail("traffic_car", "empty name", self.traffic_car)
        if self.traffic_count is not None:
            low, high = self.traffic_count
            if low < 0 or low > high:
                fail("traffic_count", "needs 0 <= min <= max", list(self.traffic_count))
        check_choice(self, "order", ("fixed", "random"))
        check_choice(self, "tick_schedule", TICK_SCHEDULES)
        check_choice(self, "episode_end", ("each", "any"))
        check_positive(self, "max_steps", "laps")
        check_positive(self, "distance_to_start", "init_wait", allow_zero=True)
        if not self.track_limits[0] < self.track_limits[1]:
            fail("track_limits", "low must be < high", list(self.track_limits))
        if (self.grid is not None and self.grid.distance_to_start is not None
                and self.distance_to_start != QUICKRACE_DISTANCE_TO_START_M):
            fail("grid.distance_to_start", "also given as distance_to_start: give one",
                 self.grid.distance_to_start)


@dataclass(frozen=True, kw_only=True)
class ActionConfig:
    """Action space: SAB = [steer, accel, brake] (normalised: all in [-1, 1], pedals mapped by
    (a + 1) / 2; else [-1..1, 0..1, 0..1]); TS = [trackPos, speed] tracked by the PID
    (normalised: [-1, 1]^2 over track_limits and +-target_speed; else trackPos and km/h within
    +-max_speed_kmh). Manual gear adds a last component (see `action_space`)."""

    aliases: ClassVar[dict[str, str]] = {"normalized": "normalised", "normalize": "normalised"}

    space: str = "SAB"
    normalised: bool = True
    max_speed_kmh: float = 140.0

    def __post_init__(self):
        if isinstance(self.space, str):
            space = self.space.upper()
            set_field(self, "space", {"S-A-B": "SAB", "T-S": "TS"}.get(space, space))
        check_choice(self, "space", ("SAB", "TS"))
        check_positive(self, "max_speed_kmh")


@dataclass(frozen=True, kw_only=True)
class PidConfig:
    """Gains (Kp, Ki, Kd, per 0.02 s tick) and error scales of the T-S controller (spec 6.3);
    latency = ticks per env step; madras_compat reproduces MADRaS's PID exactly."""

    accel_gains: tuple[float, float, float] = MADRAS_ACCEL_GAINS
    steer_gains: tuple[float, float, float] = MADRAS_STEER_GAINS
    accel_scale: float = 1.0
    steer_scale: float = 0.1
    latency: int = 10
    madras_compat: bool = False

    def __post_init__(self):
        for name in ("accel_gains", "steer_gains"):
            if any(g < 0 for g in getattr(self, name)):
                fail(name, "gains must be >= 0", list(getattr(self, name)))
        check_positive(self, "accel_scale", "steer_scale", "latency")


@dataclass(frozen=True, kw_only=True)
class ObservationConfig:
    """Observation mode (see madsim.agents.observations), the field list of mode Fields,
    normalisation onto [-1, 1] and per-field ranges for it in raw SCR units."""

    aliases: ClassVar[dict[str, str]] = {"normalize": "normalised", "normalise": "normalised",
                                         "normalized": "normalised"}

    mode: str = "SingleAgentSimpleLapObs"
    fields: tuple[str, ...] = ()
    normalised: bool = False
    obs_min: Mapping[str, float] = field(default_factory=dict)
    obs_max: Mapping[str, float] = field(default_factory=dict)
    image_size: int = 64           # mode Image: side of the square RGB image, pixels
    image_metres: float = 48.0     # mode Image: width of ground the image covers, m

    def __post_init__(self):
        if not 8 <= self.image_size <= 512:
            fail("image_size", "must be 8..512 pixels", self.image_size)
        check_positive(self, "image_metres")
        set_field(self, "obs_min", frozen_map(self.obs_min))
        set_field(self, "obs_max", frozen_map(self.obs_max))
        check_choice(self, "mode", OBSERVATION_MODES)
        if self.mode == "Fields" and not self.fields:
            fail("fields", "mode Fields needs a list of SCR fields", [])
        if self.mode != "Fields" and self.fields:
            fail("fields", f"only used with mode Fields, not {self.mode}", list(self.fields))
        for i, name in enumerate(self.fields):
            if name not in SCR_FIELDS:
                raise unknown_name("SCR field", name, SCR_FIELDS, f"fields[{i}]")
        for bound in ("obs_min", "obs_max"):
            for name in getattr(self, bound):
                if name not in SCR_FIELDS:
                    raise unknown_name("SCR field", name, SCR_FIELDS, f"{bound}.{name}")
        for name in set(self.obs_min) & set(self.obs_max):
            if not self.obs_min[name] < self.obs_max[name]:
                fail(f"obs_max.{name}", "must exceed obs_min", self.obs_max[name])


@dataclass(frozen=True, kw_only=True)
class CommConfig:
    """What this agent hears: `variables` (SCR fields, peerActions/action) of each of
    `senders` (agent names), the last `buffer_length` messages, one step late."""

    senders: tuple[str, ...]
    variables: tuple[str, ...] = ("peerActions",)
    buffer_length: int = 1

    def __post_init__(self):
        if not self.senders:
            fail("senders", "needs at least one agent name", [])
        if len(set(self.senders)) != len(self.senders):
            fail("senders", "lists an agent twice", list(self.senders))
        if not self.variables:
            fail("variables", "needs at least one variable", [])
        for i, var in enumerate(self.variables):
            if var not in COMM_VARIABLES:
                raise unknown_name("variable", var, COMM_VARIABLES, f"variables[{i}]")
        check_positive(self, "buffer_length")


@dataclass(frozen=True, kw_only=True)
class RewardTerm:
    """One reward component: registry name, weight (>= 0; penalties are subtracted) and the
    component's own parameters."""

    name: str
    scale: float = 1.0
    params: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        set_field(self, "params", frozen_map(self.params))
        name = REWARD_ALIASES.get(self.name, self.name)
        if name not in REWARDS:
            raise unknown_name("reward", self.name, list(REWARDS) + list(REWARD_ALIASES), None)
        set_field(self, "name", name)
        if not (math.isfinite(self.scale) and self.scale >= 0):
            fail("scale", "must be a finite number >= 0 (penalties are subtracted)", self.scale)
        allowed = reward_params(name)
        for key in self.params:
            if key not in allowed:
                raise unknown_name(f"parameter of {name}", key, ["scale", *allowed], key)
        try:
            make_reward(name, self.params, target_speed=1.0)
        except (TypeError, ValueError) as exc:
            fail(None, str(exc))


DEFAULT_REWARDS = (RewardTerm(name="Progress2", scale=1.0), RewardTerm(name="AvgSpeed", scale=1.0),
                   RewardTerm(name="Collision", scale=10.0),
                   RewardTerm(name="TurnBackward", scale=10.0),
                   RewardTerm(name="AngularAcceleration", scale=5.0))   # paper, Experiment 1
DEFAULT_DONES = ("RaceOver", "TimeOut", "Collision", "TurnBackward", "OutOfTrack")


def _rewards_from_yaml(value, key: str) -> tuple[RewardTerm, ...]:
    if not isinstance(value, Mapping):
        fail(key, "expected a mapping of reward name -> {scale, parameters}", value)
    terms, seen = [], {}
    for name, entry in value.items():
        sub = join_key(key, str(name))
        if entry is None:
            entry = {}
        elif not isinstance(entry, Mapping):
            entry = {"scale": entry}
        params = {k: v for k, v in entry.items() if k != "scale"}
        scale = as_number(entry.get("scale", 1.0), join_key(sub, "scale"))
        try:
            term = RewardTerm(name=str(name), scale=scale, params=params)
        except ConfigError as exc:
            raise exc.under(sub) from None
        if term.name in seen:
            fail(sub, f"same reward as {seen[term.name]!r}", str(name))
        seen[term.name] = str(name)
        terms.append(term)
    return tuple(terms)


@dataclass(frozen=True, kw_only=True)
class AgentConfig:
    """One learning car. target_speed m/s (rewards' s_target, T-S speed scale);
    action_noise_std: sigma of Gaussian noise added to each action component; gear auto|manual;
    initial_distance / initial_trackpos: (low, high) uniform start ranges (m from the start
    line, trackPos), None = the car's grid slot; car: fixed model, None = drawn from
    server.cars."""

    name: str = ""
    car: str | None = None
    target_speed: float = 27.78
    action: ActionConfig = field(default_factory=ActionConfig)
    gear: str = "auto"
    action_noise_std: float = 0.0
    pid: PidConfig = field(default_factory=PidConfig)
    observation: ObservationConfig = field(default_factory=ObservationConfig)
    rewards: tuple[RewardTerm, ...] = field(default=DEFAULT_REWARDS,
                                            metadata={"convert": _rewards_from_yaml})
    dones: tuple[str, ...] = DEFAULT_DONES
    communication: CommConfig | None = None
    initial_distance: tuple[float, float] | None = None
    initial_trackpos: tuple[float, float] | None = None

    def __post_init__(self):
        if self.car == "":
            fail("car", "empty name", self.car)
        check_positive(self, "target_speed")
        check_positive(self, "action_noise_std", allow_zero=True)
        check_choice(self, "gear", ("auto", "manual"))
        for name in ("initial_distance", "initial_trackpos"):
            if getattr(self, name) is not None:
                set_field(self, name, as_pair(getattr(self, name), name))
        _on_road(self)
        for i, name in enumerate(self.dones):
            if name not in DONES:
                raise unknown_name("done", name, DONES, f"dones[{i}]")
        if len(set(self.dones)) != len(self.dones):
            fail("dones", "lists a done twice", list(self.dones))
        if self.communication is not None and self.observation.mode == "Image":
            fail("communication", "an Image observation cannot carry messages", "Image")


# Behaviour parameters of the built-in traffic (SI: m/s, s, m; lanes in trackPos units).
# A tuple default is a pair [a, b] (a range unless noted).
TRAFFIC_PARAMS: dict[str, dict[str, Any]] = {
    "ConstVel": {"target_speed": 13.89, "lane": 0.0},
    "SinusoidalSpeed": {"mean_speed": 13.89, "speed_amplitude": 13.89,
                        "speed_period": 125.66, "lane": 0.0},      # mean + A sin(2 pi t / T)
    "RandomLaneSwitch": {"target_speed": 27.78, "lane_change_interval": 0.1,
                         "lanes": (-0.75, 0.75)},          # the two lanes switched between
    "RandomStopping": {"target_speed": 13.89, "lane": 0.0, "stop_probability": 0.1,
                       "max_stop_duration": 0.1},          # probability per tick; s
    "DriveAndPark": {"target_speed": 13.89, "parking_lane": (-0.8, 0.0),
                     "parking_distance": (185.0, 200.0)},  # uniform ranges, trackPos and m
    "Parked": {},                                         # stands at its initial position
}
TRAFFIC_BEHAVIOURS = tuple(TRAFFIC_PARAMS)
_POSITIVE_PARAMS = ("speed_period", "lane_change_interval")
_NONNEGATIVE_PARAMS = ("target_speed", "mean_speed", "speed_amplitude", "stop_probability",
                       "max_stop_duration")
_UNORDERED_PAIRS = ("lanes",)


def _traffic_registry() -> Mapping | None:
    """`madsim.agents.traffic.BEHAVIOURS` (name -> class) if the traffic layer exists."""
    try:
        module = importlib.import_module("madsim.agents.traffic")
    except ModuleNotFoundError as exc:
        if exc.name == "madsim.agents.traffic":
            return None
        raise
    return getattr(module, "BEHAVIOURS", None)


@dataclass(frozen=True, kw_only=True)
class TrafficConfig:
    """One traffic car: behaviour name and parameters (TRAFFIC_PARAMS; written flat in YAML),
    car model (None = server.traffic_car), PID, collision look-ahead (s) and safety margin
    (m), uniform start ranges (m from the start line, trackPos; None = grid slot)."""

    behaviour: str
    car: str | None = None
    pid: PidConfig = field(default_factory=PidConfig)
    collision_time_window: float = 1.0
    min_safe_dist: float = 1.0
    initial_distance: tuple[float, float] | None = None
    initial_trackpos: tuple[float, float] | None = None
    params: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        registry = _traffic_registry()
        names = tuple(registry) if registry is not None else TRAFFIC_BEHAVIOURS
        if self.behaviour not in names:
            raise unknown_name("traffic behaviour", self.behaviour, names, "behaviour")
        if self.car == "":
            fail("car", "empty name", self.car)
        check_positive(self, "collision_time_window")
        check_positive(self, "min_safe_dist", allow_zero=True)
        for name in ("initial_distance", "initial_trackpos"):
            if getattr(self, name) is not None:
                set_field(self, name, as_pair(getattr(self, name), name))
        _on_road(self)
        defaults = TRAFFIC_PARAMS.get(self.behaviour)
        if defaults is None:                     # a behaviour only the traffic layer knows
            set_field(self, "params", frozen_map(self.params))
            return
        params = dict(defaults)
        for key, value in self.params.items():
            if key not in defaults:
                others = [f.name for f in fields(self) if f.name != "params"]
                raise unknown_name(f"parameter of {self.behaviour}", key, [*others, *defaults], key)
            if isinstance(defaults[key], tuple):
                value = as_pair(value, key, ordered=key not in _UNORDERED_PAIRS)
            else:
                value = as_number(value, key)
                if key in _POSITIVE_PARAMS and value <= 0:
                    fail(key, "must be > 0", value)
                if key in _NONNEGATIVE_PARAMS and value < 0:
                    fail(key, "must be >= 0", value)
                if key == "stop_probability" and value > 1:
                    fail(key, "is a probability, must be <= 1", value)
            params[key] = value
        set_field(self, "params", frozen_map(params))


@dataclass(frozen=True, kw_only=True)
class StageConfig:
    """One curriculum stage, in force from `start` (episodes or steps); None keeps the base
    scenario's value (see madsim.agents.curriculum for the eight axes)."""

    start: int = 0
    agents: int | None = None
    cars: tuple[str, ...] | None = None
    tracks: tuple[str, ...] | None = None
    traffic_count: tuple[int, int] | None = None
    traffic: tuple[TrafficConfig, ...] | None = None
    traffic_set: Mapping[str, Mapping[str, Any]] | None = None
    target_speed: float | None = None
    action_noise_std: float | None = None
    observation_noise: bool | None = None

    def __post_init__(self):
        check_positive(self, "start", allow_zero=True)
        check_positive(self, "agents", "target_speed")
        check_positive(self, "action_noise_std", allow_zero=True)
        if self.traffic_set is not None:
            set_field(self, "traffic_set", frozen_map(
                {str(k): frozen_map(v) for k, v in self.traffic_set.items()}))


@dataclass(frozen=True, kw_only=True)
class CurriculumConfig:
    """Stages ordered by `start`, counted in `unit` (episodes | steps); the first starts at 0."""

    unit: str = "episodes"
    stages: tuple[StageConfig, ...]

    def __post_init__(self):
        check_choice(self, "unit", ("episodes", "steps"))
        if not self.stages:
            fail("stages", "needs at least one stage", [])
        if self.stages[0].start != 0:
            fail("stages[0].start", "the first stage must start at 0", self.stages[0].start)
        for i in range(1, len(self.stages)):
            if self.stages[i].start <= self.stages[i - 1].start:
                fail(f"stages[{i}].start", "stages must start in increasing order",
                     self.stages[i].start)


@dataclass(frozen=True, kw_only=True)
class ScenarioConfig:
    """A whole scenario: server, learning agents, traffic, optional curriculum."""

    server: EpisodeConfig = field(default_factory=EpisodeConfig)
    agents: tuple[AgentConfig, ...] = field(default_factory=lambda: (AgentConfig(),))
    traffic: tuple[TrafficConfig, ...] = ()
    curriculum: CurriculumConfig | None = None
    plugins: tuple[str, ...] = ()

    def __post_init__(self):
        if not self.agents:
            fail("agents", "needs at least one learning agent", [])
        named = tuple(a if a.name else dataclasses.replace(a, name=f"agent_{i}")
                      for i, a in enumerate(self.agents))
        set_field(self, "agents", named)
        names = [a.name for a in named]
        for i, name in enumerate(names):
            if names.index(name) != i:
                fail(f"agents[{i}].name", "two agents have this name", name)
        for i, agent in enumerate(named):
            if agent.communication is not None:
                for j, sender in enumerate(agent.communication.senders):
                    if sender not in names:
                        raise unknown_name("agent", sender, names,
                                           f"agents[{i}].communication.senders[{j}]")
        if self.server.traffic_count is not None and self.server.traffic_count[1] > len(self.traffic):
            fail("server.traffic_count", f"max exceeds the {len(self.traffic)} traffic "
                 "entries", list(self.server.traffic_count))
        if self.curriculum is not None:
            base = dataclasses.replace(self, curriculum=None)
            for i, stage in enumerate(self.curriculum.stages):
                key = f"curriculum.stages[{i}]"
                if stage.agents is not None and stage.agents > len(self.agents):
                    fail(join_key(key, "agents"), f"the scenario has {len(self.agents)} agents",
                         stage.agents)
                try:
                    _curriculum.apply_stage(base, stage)
                except ConfigError as exc:
                    fail(key, f"makes the scenario invalid: {exc.key}: {exc.reason}",
                         exc.value)

    @property
    def agent_names(self) -> tuple[str, ...]:
        return tuple(a.name for a in self.agents)


SECTIONS = tuple(f.name for f in fields(ScenarioConfig))
"""The top-level keys of a scenario file in madsim's format."""
