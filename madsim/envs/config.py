"""Scenario configuration: one YAML file -> frozen, validated dataclasses (madsim's one schema).

A scenario has MADRaS's three sections plus a curriculum (paper, Appendix A):

    server:                        # what every episode draws from
      tracks: [madsim-road]        # names, paths or "generated:<seed>[:<length_m>[:<width_m>]]"
      cars: [madsim-sedan]         # learning-car models offered (one drawn per agent)
      traffic_car: madsim-sedan    # default model of traffic cars
      traffic_count: [4, 5]        # traffic cars per episode (null: every traffic entry)
      order: fixed                 # fixed: episode k uses entry k mod n; random: uniform draws
      observation_noise: false     # SCR's multiplicative sensor noise
      max_steps: 20000             # ticks (0.02 s) before TimeOut; null: one lap at target speed
      track_limits: [-1.0, 1.0]    # allowed trackPos range (OutOfTrack, T-S lane mapping)
      distance_to_start: 25.0      # m of grid before the start line
      laps: 1                      # RaceOver distance, laps
      init_wait: 0                 # env steps with the "stop" action after reset (MADRaS devel)
    agents:                        # one entry per learning car
      - name: agent_0
        target_speed: 27.78        # m/s
        action: {space: TS, normalised: true}   # SAB (steer-accel-brake) or TS (trackPos-speed)
        pid: {accel_gains: [10.5, 0.05, 2.8], steer_gains: [5.1, 0.001, 1.0e-6], latency: 5}
        observation: {mode: SingleAgentInTrafficObs}
        rewards: {Progress2: {scale: 1.0}, AngularAcceleration: {scale: 5.0, max_ang_accl: 2.0}}
        dones: [RaceOver, TimeOut, Collision, TurnBackward, OutOfTrack]
        communication: {senders: [agent_1], variables: [peerActions], buffer_length: 1}
    traffic:                       # the first n entries drive when n traffic cars are drawn
      - {behaviour: DriveAndPark, target_speed: 13.89, parking_lane: [-0.8, 0.0],
         parking_distance: [185, 200]}
    curriculum: {unit: episodes, stages: [{start: 0, tracks: [madsim-road]}, {start: 500, ...}]}

Every key, its unit and default is a field of the dataclasses below. `load_config` also reads
MADRaS's own files unchanged (master `madras_config.yml`, devel `sim_options_v2.yml` with its
`communications.yml`): their keys map onto these (table `_MADRAS_*` below), misspellings
included; keys that only mean something to TORCS are accepted with a `ConfigWarning`.
Any fault raises `ConfigError` naming the file, the dotted key path (as written in the file),
the bad value and the nearest valid key.
"""

from __future__ import annotations

import collections.abc
import dataclasses
import difflib
import importlib
import math
import os
import types
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, ClassVar, Union, get_args, get_origin, get_type_hints

import gymnasium
import numpy as np
import yaml

from madsim.agents import curriculum as _curriculum
from madsim.agents.comms import ACTION_VARIABLES, COMM_VARIABLES
from madsim.agents.dones import DONES
from madsim.agents.observations import FIELD_WIDTH, OBSERVATION_MODES, SCR_FIELDS, ObservationBuilder
from madsim.agents.pid import MADRAS_ACCEL_GAINS, MADRAS_STEER_GAINS
from madsim.agents.rewards import REWARD_ALIASES, REWARDS, make_reward, reward_params
from madsim.plugins import PluginError, import_plugins, resolve_plugin

__all__ = [
    "TRAFFIC_BEHAVIOURS",
    "TRAFFIC_PARAMS",
    "ActionConfig",
    "AgentConfig",
    "CommConfig",
    "ConfigError",
    "ConfigWarning",
    "CurriculumConfig",
    "ObservationConfig",
    "PidConfig",
    "RewardTerm",
    "ScenarioConfig",
    "ServerConfig",
    "StageConfig",
    "TrafficConfig",
    "action_space",
    "check_config",
    "config_to_dict",
    "generated_track_args",
    "load_config",
    "observation_size",
    "show_config",
]

DEFAULT_TRACK = "madsim-road"
DEFAULT_CAR = "madsim-sedan"
_NO_VALUE = object()


class ConfigError(ValueError):
    """A scenario config is wrong. Attributes: `file`, `key` (dotted path as written),
    `value` (the bad value, if any), `hint` (nearest valid key or value), `reason`."""

    def __init__(self, reason: str, *, key: str | None = None, value: Any = _NO_VALUE,
                 hint: str | None = None, file: str | None = None):
        super().__init__(reason)
        self.reason, self.key, self.value, self.hint, self.file = reason, key, value, hint, file

    def __str__(self) -> str:
        text = self.reason
        if self.value is not _NO_VALUE:
            text += f" (got {self.value!r})"
        if self.hint:
            text += f"; did you mean {self.hint!r}?"
        return ": ".join([p for p in (self.file, self.key) if p] + [text])

    def under(self, prefix: str) -> ConfigError:
        """The same error with its key placed under `prefix` (a dotted path)."""
        self.key = _join(prefix, self.key) if self.key else (prefix or None)
        return self


class ConfigWarning(UserWarning):
    """A config key was accepted but has no effect in madsim (e.g. a TORCS-only setting)."""


def _join(path: str, key: str | int) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    if key.startswith("["):
        return f"{path}{key}"
    return f"{path}.{key}" if path else key


def _nearest(word: str, candidates) -> str | None:
    candidates = [str(c) for c in candidates]
    same_letters = [c for c in candidates if c.lower() == str(word).lower()]
    if same_letters:
        return same_letters[0]
    match = difflib.get_close_matches(str(word), candidates, n=1, cutoff=0.5)
    return match[0] if match else None


def _unknown(what: str, name: str, candidates, key: str | None) -> ConfigError:
    hint = _nearest(name, candidates)
    if hint:
        return ConfigError(f"unknown {what} {name!r}", key=key, hint=hint)
    yours = (" (your own? list its module under `plugins:` or pass --import)"
             if what in ("reward", "done", "traffic behaviour") else "")
    return ConfigError(f"unknown {what} {name!r}{yours}; valid: {', '.join(map(str, candidates))}",
                       key=key)


def _fail(key: str | None, reason: str, value: Any = _NO_VALUE, hint: str | None = None):
    raise ConfigError(reason, key=key, value=value, hint=hint)


def _set(obj, name: str, value) -> None:
    object.__setattr__(obj, name, value)


def _choice(obj, name: str, choices) -> None:
    value = getattr(obj, name)
    if value not in choices:
        raise _unknown(f"{name} value", value, choices, name)


def _pair(value, key: str, *, ordered: bool = True) -> tuple[float, float]:
    """(low, high) from [a, b], (a, b) or {low: a, high: b}."""
    if isinstance(value, Mapping):
        extra = set(value) - {"low", "high"}
        if extra or len(value) != 2:
            _fail(key, "a range needs exactly the keys low and high", dict(value))
        value = (value["low"], value["high"])
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        _fail(key, "expected a pair [low, high]", value)
    out = tuple(_number(v, _join(key, i)) for i, v in enumerate(value))
    if ordered and out[0] > out[1]:
        _fail(key, "low must not exceed high", list(value))
    return out


def _on_road(entry) -> None:
    """initial_trackpos must place a car on the road: trackPos is -1..1 edge to edge."""
    pos = entry.initial_trackpos
    if pos is not None and (pos[0] < -1.0 or pos[1] > 1.0):
        _fail("initial_trackpos", "must lie within [-1, 1] (trackPos: -1 right edge, +1 left edge, "
              "0 centre line; beyond is off the road)", list(pos))


def _number(value, key: str) -> float:
    if isinstance(value, str):           # YAML 1.1 reads 1e-6 (no dot) as a string
        try:
            value = float(value)
        except ValueError:
            _fail(key, "expected a number", value)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        _fail(key, "expected a finite number", value)
    return float(value)


def _positive(obj, *names: str, allow_zero: bool = False) -> None:
    for name in names:
        v = getattr(obj, name)
        if v is not None and not (v >= 0 if allow_zero else v > 0):
            _fail(name, "must be >= 0" if allow_zero else "must be > 0", v)


def _frozen_map(value) -> Mapping:
    return value if isinstance(value, types.MappingProxyType) else types.MappingProxyType(dict(value))


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


# --- the schema -----------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class ServerConfig:
    """What every episode draws from (MADRaS `server_config` and env-level keys).

    Per episode k (counted from 0 at the env's creation) and learning agent i:
    order "fixed": track = tracks[k mod len], car = cars[(k + i) mod len] (agents without a
    fixed `car`), traffic count = min + k mod (max - min + 1); order "random": uniform draws
    from the episode's rng (categorical track and car, discrete-uniform count; paper App. C).
    traffic_count None means every traffic entry, every episode. max_steps counts 0.02 s ticks
    (None: ceil(L / (target_speed * 0.02 s)), one lap at the target speed)."""

    tracks: tuple[str, ...] = (DEFAULT_TRACK,)
    cars: tuple[str, ...] = (DEFAULT_CAR,)
    traffic_car: str = DEFAULT_CAR
    traffic_count: tuple[int, int] | None = None
    order: str = "fixed"
    observation_noise: bool = False
    max_steps: int | None = 20000
    track_limits: tuple[float, float] = (-1.0, 1.0)
    distance_to_start: float = 25.0
    laps: int = 1
    init_wait: int = 0

    def __post_init__(self):
        for name in ("tracks", "cars"):
            if not getattr(self, name):
                _fail(name, "needs at least one entry", list(getattr(self, name)))
            for i, entry in enumerate(getattr(self, name)):
                if not entry:
                    _fail(f"{name}[{i}]", "empty name", entry)
        for i, entry in enumerate(self.tracks):
            try:
                generated_track_args(entry)
            except ValueError as exc:
                _fail(f"tracks[{i}]", str(exc), entry)
        if not self.traffic_car:
            _fail("traffic_car", "empty name", self.traffic_car)
        if self.traffic_count is not None:
            low, high = self.traffic_count
            if low < 0 or low > high:
                _fail("traffic_count", "needs 0 <= min <= max", list(self.traffic_count))
        _choice(self, "order", ("fixed", "random"))
        _positive(self, "max_steps", "laps")
        _positive(self, "distance_to_start", "init_wait", allow_zero=True)
        if not self.track_limits[0] < self.track_limits[1]:
            _fail("track_limits", "low must be < high", list(self.track_limits))


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
            _set(self, "space", {"S-A-B": "SAB", "T-S": "TS"}.get(self.space.upper(),
                                                                 self.space.upper()))
        _choice(self, "space", ("SAB", "TS"))
        _positive(self, "max_speed_kmh")


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
                _fail(name, "gains must be >= 0", list(getattr(self, name)))
        _positive(self, "accel_scale", "steer_scale", "latency")


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
            _fail("image_size", "must be 8..512 pixels", self.image_size)
        _positive(self, "image_metres")
        _set(self, "obs_min", _frozen_map(self.obs_min))
        _set(self, "obs_max", _frozen_map(self.obs_max))
        _choice(self, "mode", OBSERVATION_MODES)
        if self.mode == "Fields" and not self.fields:
            _fail("fields", "mode Fields needs a list of SCR fields", [])
        if self.mode != "Fields" and self.fields:
            _fail("fields", f"only used with mode Fields, not {self.mode}", list(self.fields))
        for i, name in enumerate(self.fields):
            if name not in SCR_FIELDS:
                raise _unknown("SCR field", name, SCR_FIELDS, f"fields[{i}]")
        for bound in ("obs_min", "obs_max"):
            for name in getattr(self, bound):
                if name not in SCR_FIELDS:
                    raise _unknown("SCR field", name, SCR_FIELDS, f"{bound}.{name}")
        for name in set(self.obs_min) & set(self.obs_max):
            if not self.obs_min[name] < self.obs_max[name]:
                _fail(f"obs_max.{name}", "must exceed obs_min", self.obs_max[name])


@dataclass(frozen=True, kw_only=True)
class CommConfig:
    """What this agent hears: `variables` (SCR fields, peerActions/action) of each of
    `senders` (agent names), the last `buffer_length` messages, one step late."""

    senders: tuple[str, ...]
    variables: tuple[str, ...] = ("peerActions",)
    buffer_length: int = 1

    def __post_init__(self):
        if not self.senders:
            _fail("senders", "needs at least one agent name", [])
        if len(set(self.senders)) != len(self.senders):
            _fail("senders", "lists an agent twice", list(self.senders))
        if not self.variables:
            _fail("variables", "needs at least one variable", [])
        for i, var in enumerate(self.variables):
            if var not in COMM_VARIABLES:
                raise _unknown("variable", var, COMM_VARIABLES, f"variables[{i}]")
        _positive(self, "buffer_length")


@dataclass(frozen=True, kw_only=True)
class RewardTerm:
    """One reward component: registry name, weight (>= 0; penalties are subtracted) and the
    component's own parameters."""

    name: str
    scale: float = 1.0
    params: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        _set(self, "params", _frozen_map(self.params))
        name = REWARD_ALIASES.get(self.name, self.name)
        if name not in REWARDS:
            raise _unknown("reward", self.name, list(REWARDS) + list(REWARD_ALIASES), None)
        _set(self, "name", name)
        if not (math.isfinite(self.scale) and self.scale >= 0):
            _fail("scale", "must be a finite number >= 0 (penalties are subtracted)", self.scale)
        allowed = reward_params(name)
        for key in self.params:
            if key not in allowed:
                raise _unknown(f"parameter of {name}", key, ["scale", *allowed], key)
        try:
            make_reward(name, self.params, target_speed=1.0)
        except (TypeError, ValueError) as exc:
            _fail(None, str(exc))


DEFAULT_REWARDS = (RewardTerm(name="Progress2", scale=1.0), RewardTerm(name="AvgSpeed", scale=1.0),
                   RewardTerm(name="Collision", scale=10.0),
                   RewardTerm(name="TurnBackward", scale=10.0),
                   RewardTerm(name="AngularAcceleration", scale=5.0))   # paper, Experiment 1
DEFAULT_DONES = ("RaceOver", "TimeOut", "Collision", "TurnBackward", "OutOfTrack")


def _rewards_from_yaml(value, key: str) -> tuple[RewardTerm, ...]:
    if not isinstance(value, Mapping):
        _fail(key, "expected a mapping of reward name -> {scale, parameters}", value)
    terms, seen = [], {}
    for name, entry in value.items():
        sub = _join(key, str(name))
        if entry is None:
            entry = {}
        elif not isinstance(entry, Mapping):
            entry = {"scale": entry}
        params = {k: v for k, v in entry.items() if k != "scale"}
        scale = _number(entry.get("scale", 1.0), _join(sub, "scale"))
        try:
            term = RewardTerm(name=str(name), scale=scale, params=params)
        except ConfigError as exc:
            raise exc.under(sub) from None
        if term.name in seen:
            _fail(sub, f"same reward as {seen[term.name]!r}", str(name))
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
            _fail("car", "empty name", self.car)
        _positive(self, "target_speed")
        _positive(self, "action_noise_std", allow_zero=True)
        _choice(self, "gear", ("auto", "manual"))
        for name in ("initial_distance", "initial_trackpos"):
            if getattr(self, name) is not None:
                _set(self, name, _pair(getattr(self, name), name))
        _on_road(self)
        for i, name in enumerate(self.dones):
            if name not in DONES:
                raise _unknown("done", name, DONES, f"dones[{i}]")
        if len(set(self.dones)) != len(self.dones):
            _fail("dones", "lists a done twice", list(self.dones))
        if self.communication is not None and self.observation.mode == "Image":
            _fail("communication", "an Image observation cannot carry messages", "Image")


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
            raise _unknown("traffic behaviour", self.behaviour, names, "behaviour")
        if self.car == "":
            _fail("car", "empty name", self.car)
        _positive(self, "collision_time_window")
        _positive(self, "min_safe_dist", allow_zero=True)
        for name in ("initial_distance", "initial_trackpos"):
            if getattr(self, name) is not None:
                _set(self, name, _pair(getattr(self, name), name))
        _on_road(self)
        defaults = TRAFFIC_PARAMS.get(self.behaviour)
        if defaults is None:                     # a behaviour only the traffic layer knows
            _set(self, "params", _frozen_map(self.params))
            return
        params = dict(defaults)
        for key, value in self.params.items():
            if key not in defaults:
                others = [f.name for f in fields(self) if f.name != "params"]
                raise _unknown(f"parameter of {self.behaviour}", key, [*others, *defaults], key)
            if isinstance(defaults[key], tuple):
                value = _pair(value, key, ordered=key not in _UNORDERED_PAIRS)
            else:
                value = _number(value, key)
                if key in _POSITIVE_PARAMS and value <= 0:
                    _fail(key, "must be > 0", value)
                if key in _NONNEGATIVE_PARAMS and value < 0:
                    _fail(key, "must be >= 0", value)
                if key == "stop_probability" and value > 1:
                    _fail(key, "is a probability, must be <= 1", value)
            params[key] = value
        _set(self, "params", _frozen_map(params))


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
        _positive(self, "start", allow_zero=True)
        _positive(self, "agents", "target_speed")
        _positive(self, "action_noise_std", allow_zero=True)
        if self.traffic_set is not None:
            _set(self, "traffic_set", _frozen_map(
                {str(k): _frozen_map(v) for k, v in self.traffic_set.items()}))


@dataclass(frozen=True, kw_only=True)
class CurriculumConfig:
    """Stages ordered by `start`, counted in `unit` (episodes | steps); the first starts at 0."""

    unit: str = "episodes"
    stages: tuple[StageConfig, ...]

    def __post_init__(self):
        _choice(self, "unit", ("episodes", "steps"))
        if not self.stages:
            _fail("stages", "needs at least one stage", [])
        if self.stages[0].start != 0:
            _fail("stages[0].start", "the first stage must start at 0", self.stages[0].start)
        for i in range(1, len(self.stages)):
            if self.stages[i].start <= self.stages[i - 1].start:
                _fail(f"stages[{i}].start", "stages must start in increasing order",
                      self.stages[i].start)


@dataclass(frozen=True, kw_only=True)
class ScenarioConfig:
    """A whole scenario: server, learning agents, traffic, optional curriculum."""

    server: ServerConfig = field(default_factory=ServerConfig)
    agents: tuple[AgentConfig, ...] = field(default_factory=lambda: (AgentConfig(),))
    traffic: tuple[TrafficConfig, ...] = ()
    curriculum: CurriculumConfig | None = None
    plugins: tuple[str, ...] = ()

    def __post_init__(self):
        if not self.agents:
            _fail("agents", "needs at least one learning agent", [])
        named = tuple(a if a.name else dataclasses.replace(a, name=f"agent_{i}")
                      for i, a in enumerate(self.agents))
        _set(self, "agents", named)
        names = [a.name for a in named]
        for i, name in enumerate(names):
            if names.index(name) != i:
                _fail(f"agents[{i}].name", "two agents have this name", name)
        for i, agent in enumerate(named):
            if agent.communication is not None:
                for j, sender in enumerate(agent.communication.senders):
                    if sender not in names:
                        raise _unknown("agent", sender, names,
                                       f"agents[{i}].communication.senders[{j}]")
        if self.server.traffic_count is not None and self.server.traffic_count[1] > len(self.traffic):
            _fail("server.traffic_count", f"max exceeds the {len(self.traffic)} traffic "
                  "entries", list(self.server.traffic_count))
        if self.curriculum is not None:
            base = dataclasses.replace(self, curriculum=None)
            for i, stage in enumerate(self.curriculum.stages):
                key = f"curriculum.stages[{i}]"
                if stage.agents is not None and stage.agents > len(self.agents):
                    _fail(_join(key, "agents"), f"the scenario has {len(self.agents)} agents",
                          stage.agents)
                try:
                    _curriculum.apply_stage(base, stage)
                except ConfigError as exc:
                    _fail(key, f"makes the scenario invalid: {exc.key}: {exc.reason}",
                          exc.value)

    @property
    def agent_names(self) -> tuple[str, ...]:
        return tuple(a.name for a in self.agents)


# --- spaces derived from the schema --------------------------------------------------------

MANUAL_GEARS = (-1, 6)     # reverse .. sixth


def action_space(agent: AgentConfig, track_limits: tuple[float, float] = (-1.0, 1.0)
                 ) -> gymnasium.spaces.Box:
    """The agent's action Box (spec 6.1). SAB: [steer, accel, brake]; TS: [trackPos, speed]
    (not normalised: trackPos within track_limits, speed in km/h); manual gear appends a gear
    component: normalised in [-1, 1] (gear = round(-1 + 3.5 (a + 1))), else in [-1, 6]."""
    a = agent.action
    if a.normalised:
        low, high = [-1.0, -1.0, -1.0], [1.0, 1.0, 1.0]
        if a.space == "TS":
            low, high = low[:2], high[:2]
    elif a.space == "SAB":
        low, high = [-1.0, 0.0, 0.0], [1.0, 1.0, 1.0]
    else:
        low = [float(track_limits[0]), -a.max_speed_kmh]
        high = [float(track_limits[1]), a.max_speed_kmh]
    if agent.gear == "manual":
        low.append(-1.0 if a.normalised else float(MANUAL_GEARS[0]))
        high.append(1.0 if a.normalised else float(MANUAL_GEARS[1]))
    return gymnasium.spaces.Box(np.array(low, np.float32), np.array(high, np.float32),
                                dtype=np.float32)


def observation_size(cfg: ScenarioConfig, agent_name: str) -> int:
    """Length of an agent's observation: its mode's size + buffer_length * message width."""
    agents = {a.name: a for a in cfg.agents}
    agent = agents[agent_name]
    o = agent.observation
    if o.mode == "Image":
        return o.image_size * o.image_size * 3
    size = ObservationBuilder(o.mode, o.fields).size
    link = agent.communication
    if link is not None:
        limits = cfg.server.track_limits
        width = sum(action_space(agents[s], limits).shape[0] if v in ACTION_VARIABLES
                    else FIELD_WIDTH[v] for s in link.senders for v in link.variables)
        size += link.buffer_length * width
    return size


# --- the strict loader -----------------------------------------------------------------------

_HINTS: dict[type, dict] = {}


def _hints(cls) -> dict:
    if cls not in _HINTS:
        _HINTS[cls] = get_type_hints(cls)
    return _HINTS[cls]


def _convert(tp, value, key: str):
    """`value` read from YAML as type `tp` (an annotation of the schema)."""
    origin, args = get_origin(tp), get_args(tp)
    if origin in (Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        (inner,) = [a for a in args if a is not type(None)]
        return _convert(inner, value, key)
    if tp is Any:
        return value
    if tp is bool:
        if not isinstance(value, bool):
            _fail(key, "expected true or false", value)
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            _fail(key, "expected a whole number", value)
        return value
    if tp is float:
        return _number(value, key)
    if tp is str:
        if not isinstance(value, str):
            _fail(key, "expected a string", value)
        return value
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            if isinstance(value, str) and args[0] is str:
                value = [value]                          # "tracks: forza" means [forza]
            if not isinstance(value, (list, tuple)):
                _fail(key, "expected a list", value)
            return tuple(_convert(args[0], v, _join(key, i)) for i, v in enumerate(value))
        if len(args) == 2 and isinstance(value, Mapping):
            value = _pair(value, key, ordered=False)     # {low: .., high: ..}
        if not isinstance(value, (list, tuple)) or len(value) != len(args):
            _fail(key, f"expected a list of {len(args)} values", value)
        return tuple(_convert(a, v, _join(key, i)) for i, (a, v) in enumerate(zip(args, value)))
    if origin in (collections.abc.Mapping, dict) or tp is Mapping:
        if not isinstance(value, Mapping):
            _fail(key, "expected a mapping", value)
        inner = args[1] if args else Any
        return _frozen_map({str(k): _convert(inner, v, _join(key, str(k)))
                            for k, v in value.items()})
    if dataclasses.is_dataclass(tp):
        return _build(tp, value, key)
    raise TypeError(f"schema type {tp!r} not handled")        # a bug in this module


def _build(cls, data, key: str):
    """A schema dataclass from a YAML mapping: unknown keys are refused with the nearest
    valid one; TrafficConfig puts them into its behaviour params."""
    if data is None:
        data = {}
    if not isinstance(data, Mapping):
        _fail(key or None, f"expected a mapping of {cls.__name__} keys", data)
    known = {f.name: f for f in fields(cls) if f.name != "params"}
    aliases = getattr(cls, "aliases", {})
    kwargs: dict[str, Any] = {}
    params: dict[str, Any] = {}
    for raw_key, value in data.items():
        name = aliases.get(str(raw_key), str(raw_key))
        sub = _join(key, str(raw_key))
        if name not in known:
            if cls is TrafficConfig:
                params[name] = value
                continue
            raise _unknown("key", raw_key, [*known, *aliases], sub)
        if name in kwargs:
            _fail(sub, f"given twice (also as {name!r})", value)
        convert = known[name].metadata.get("convert")
        kwargs[name] = convert(value, sub) if convert else _convert(_hints(cls)[name], value, sub)
    if params:
        kwargs["params"] = params
    missing = [f.name for f in fields(cls) if f.name not in kwargs
               and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING]
    if missing:
        _fail(key or None, f"missing required key {missing[0]!r}")
    try:
        return cls(**kwargs)
    except ConfigError as exc:
        raise exc.under(key) from None


def _is_path(entry: str) -> bool:
    return "/" in entry or os.sep in entry or entry.endswith((".xml", ".mtrack"))


def _resolve_paths(cfg: ScenarioConfig, base: Path) -> ScenarioConfig:
    """Relative track and car paths in a file are relative to the file's folder."""
    def fix(entry):
        if entry is None or not _is_path(entry) or os.path.isabs(entry):
            return entry
        return str((base / entry).resolve())

    def fix_all(entries):
        return None if entries is None else tuple(fix(e) for e in entries)

    server = dataclasses.replace(cfg.server, tracks=fix_all(cfg.server.tracks),
                                 cars=fix_all(cfg.server.cars),
                                 traffic_car=fix(cfg.server.traffic_car))
    agents = tuple(dataclasses.replace(a, car=fix(a.car)) for a in cfg.agents)
    traffic = tuple(dataclasses.replace(t, car=fix(t.car)) for t in cfg.traffic)
    curriculum = cfg.curriculum
    if curriculum is not None:
        stages = tuple(dataclasses.replace(
            s, tracks=fix_all(s.tracks), cars=fix_all(s.cars),
            traffic=None if s.traffic is None else tuple(
                dataclasses.replace(t, car=fix(t.car)) for t in s.traffic))
            for s in curriculum.stages)
        curriculum = dataclasses.replace(curriculum, stages=stages)
    plugins = tuple(resolve_plugin(p, base) for p in cfg.plugins)
    return dataclasses.replace(cfg, server=server, agents=agents, traffic=traffic,
                               curriculum=curriculum, plugins=plugins)


_OURS = ("server", "agents", "traffic", "curriculum", "plugins")


# --- public API ------------------------------------------------------------------------------


def _read_yaml(path: Path) -> Any:
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(f"cannot read the file: {exc.strerror}", file=str(path)) from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark else None
        problem = getattr(exc, "problem", None) or str(exc)
        raise ConfigError(f"not valid YAML: {problem}", key=where, file=str(path)) from None


def load_config(source: str | os.PathLike | Mapping | None = None, *,
                communications: str | os.PathLike | Mapping | None = None) -> ScenarioConfig:
    """A validated ScenarioConfig from a YAML file path, a mapping, or None (all defaults).

    MADRaS files are recognised by their keys. For a MADRaS devel file with `agents`, the
    `communications` file (path or mapping) defaults to a `communications.yml` next to it, as
    MADRaS reads it. TORCS-only keys raise a ConfigWarning; every fault a ConfigError.
    """
    file = None
    if source is None:
        raw: Any = {}
    elif isinstance(source, Mapping):
        raw = source
    else:
        path = Path(source)
        file = str(path)
        raw = _read_yaml(path)
    if raw is None and file is not None:
        raise ConfigError("the file is empty: a scenario needs at least one section (server, agents, "
                          "traffic; see `madsim config show` of a shipped example), or give no file for "
                          "the defaults", file=file)
    raw = {} if raw is None else raw
    if not isinstance(raw, Mapping):
        raise ConfigError("a scenario file must be a mapping of sections", value=raw, file=file)
    _import_plugins(raw, file)
    comms_file = None
    try:
        from madsim.envs.madras_format import _MADRAS_HINTS, _looks_madras, _Madras

        if _looks_madras(raw):
            comms = communications
            if comms is None and file is not None and "agents" in raw:
                sibling = Path(file).with_name("communications.yml")
                comms = sibling if sibling.is_file() else None
            if comms is not None and not isinstance(comms, Mapping):
                comms_file = str(comms)
                comms = _read_yaml(Path(comms))
                if comms is not None and not isinstance(comms, Mapping):
                    raise ConfigError("expected a mapping of receiver agents", file=comms_file)
            madras = _Madras(comms_file)
            ours = madras.translate(raw, comms)
            try:
                cfg = _build(ScenarioConfig, ours, "")
            except ConfigError as exc:
                if madras.from_comms(exc.key):
                    exc.file = comms_file
                exc.key = madras.source_key(exc.key)
                exc.hint = _MADRAS_HINTS.get(exc.hint, exc.hint)
                raise
            _warn_madras(madras, file)
        else:
            if communications is not None:
                raise ConfigError("a communications file goes with MADRaS files; in madsim's "
                                  "format give each agent a `communication:` entry")
            for k in raw:
                if k not in _OURS:
                    raise _unknown("section", k, _OURS, str(k))
            cfg = _build(ScenarioConfig, raw, "")
    except ConfigError as exc:
        if exc.file is None:
            exc.file = file
        raise exc from None
    if file is not None:
        cfg = _resolve_paths(cfg, Path(file).resolve().parent)
    return cfg


def _import_plugins(raw: Mapping, file: str | None) -> None:
    """Import the `plugins:` modules before validation, so the names they register are known."""
    entries = raw.get("plugins") if "plugins" in raw else None
    if entries is None:
        return
    if isinstance(entries, str) or not isinstance(entries, (list, tuple)):
        raise ConfigError("expected a list of module names or .py paths", key="plugins", value=entries,
                          file=file)
    try:
        import_plugins(entries, Path(file).resolve().parent if file else None)
    except PluginError as exc:
        raise ConfigError(str(exc), key="plugins", file=file) from None


def _warn_madras(madras, file: str | None) -> None:
    where = f"{file}: " if file else ""
    if madras.ignored:
        warnings.warn(f"{where}MADRaS keys without effect in madsim (TORCS, client or unused "
                      f"settings), accepted and ignored: {', '.join(madras.ignored)}",
                      ConfigWarning, stacklevel=3)
    for note in madras.notes:
        warnings.warn(where + note, ConfigWarning, stacklevel=3)


def _plain(obj) -> Any:
    if isinstance(obj, TrafficConfig):
        out = {f.name: _plain(getattr(obj, f.name)) for f in fields(obj) if f.name != "params"}
        out.update(_plain(obj.params))
        return out
    if isinstance(obj, StageConfig):
        return {f.name: _plain(getattr(obj, f.name)) for f in fields(obj)
                if getattr(obj, f.name) is not None}
    if dataclasses.is_dataclass(obj):
        out = {}
        for f in fields(obj):
            value = getattr(obj, f.name)
            if f.name == "rewards":
                out[f.name] = {t.name: {"scale": t.scale, **_plain(t.params)} for t in value}
            else:
                out[f.name] = _plain(value)
        return out
    if isinstance(obj, Mapping):
        return {k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, (tuple, list)):
        return [_plain(v) for v in obj]
    return obj


def config_to_dict(cfg: ScenarioConfig) -> dict:
    """The fully resolved config (every default filled in) as plain YAML-able data in madsim's
    format; `load_config(config_to_dict(cfg)) == cfg`."""
    return _plain(cfg)


def show_config(path: str | os.PathLike | Mapping) -> str:
    """YAML text of the fully resolved config (for `madsim config show`)."""
    return yaml.safe_dump(config_to_dict(load_config(path)), sort_keys=False,
                          default_flow_style=None, width=100)


def check_config(path: str | os.PathLike | Mapping) -> str:
    """Validate a config, including that its tracks and cars can be found; a short report of
    what it sets up (for `madsim config check`). Raises ConfigError."""
    from madsim.cars.loader import find_car
    from madsim.tracks.generate import generate_track_xml
    from madsim.tracks.library import find_track

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConfigWarning)
        cfg = load_config(path)
    file = None if isinstance(path, Mapping) else str(path)
    stages = cfg.curriculum.stages if cfg.curriculum else ()
    tracks = {t for t in cfg.server.tracks} | {t for s in stages for t in (s.tracks or ())}
    cars = ({*cfg.server.cars, cfg.server.traffic_car} | {a.car for a in cfg.agents if a.car}
            | {t.car for t in cfg.traffic if t.car} | {c for s in stages for c in (s.cars or ())})
    for track in sorted(tracks):
        args = generated_track_args(track)
        try:
            if args is None:
                find_track(track)
            else:
                generate_track_xml(**args)       # ~10 ms; some seed/size pairs cannot close
        except ValueError as exc:
            raise ConfigError(str(exc), key="tracks", value=track, file=file) from None
    for car in sorted(cars):
        try:
            find_car(car)
        except ValueError as exc:
            raise ConfigError(str(exc), key="cars", file=file) from None
    s = cfg.server
    count = (f"all {len(cfg.traffic)}" if s.traffic_count is None
             else f"{s.traffic_count[0]}-{s.traffic_count[1]}")
    lines = [f"OK {file or '<mapping>'}",
             f"  tracks ({s.order}): {', '.join(s.tracks)}",
             f"  learning cars: {', '.join(s.cars)}; traffic car: {s.traffic_car}",
             f"  traffic: {len(cfg.traffic)} entries, {count} per episode"]
    for a in cfg.agents:
        lines.append(f"  agent {a.name} ({a.car or 'drawn car'}): {a.action.space}, "
                     f"{a.observation.mode} "
                     f"({observation_size(cfg, a.name)} values), rewards "
                     f"{', '.join(t.name for t in a.rewards) or '-'}; dones {', '.join(a.dones) or '-'}")
    if cfg.curriculum:
        lines.append(f"  curriculum: {len(stages)} stages by {cfg.curriculum.unit}")
    lines += [f"  warning: {w.message}" for w in caught if issubclass(w.category, ConfigWarning)]
    return "\n".join(lines)
