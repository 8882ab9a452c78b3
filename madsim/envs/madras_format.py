"""MADRaS's own configuration files read into madsim's schema.

`madras_config.yml` (MADRaS master) and `sim_options_v2.yml` + `communications.yml` (devel) load
unchanged: their keys, including the misspelt ones, map onto the dataclasses of
`madsim.envs.schema`; TORCS-only keys are accepted with a ConfigWarning. Used by `load_config`
(madsim.envs.loader), which detects the format with `looks_madras`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import fields
from typing import Any

from madsim.agents.comms import COMM_VARIABLES
from madsim.agents.rewards import TICK_S
from madsim.envs.schema import SECTIONS, AgentConfig
from madsim.envs.validation import ConfigError, as_number, fail, join_key, unknown_name

__all__ = ["MadrasTranslation", "looks_madras"]

# --- tables ----------------------------------------------------------------------

# keys that only configure TORCS, the snakeoil client or are unused by MADRaS itself
_MADRAS_IGNORED = ("torcs_server_port", "visualise", "no_of_visualisations",
                   "no_of_visualizations", "torcs_server_config_dir", "scr_server_config_dir",
                   "track_category", "client_max_steps", "track_len", "track_width", "state_dim",
                   "early_stop", "multi_flag", "pid_latency", "accel_pid", "steer_pid")
_MADRAS_AGENT = ("vision", "throttle", "gear_change", "client_max_steps", "target_speed",
                 "state_dim", "early_stop", "normalize_actions", "pid_assist", "pid_settings",
                 "observations", "rewards", "dones", "add_noise_to_actions", "action_noise_std")
_MADRAS_SERVER = ("server_config", "randomize_env", "randomoze_env", "noisy_observations",
                  "max_steps", "track_limits", "init_wait")
_MADRAS_M1 = (*_MADRAS_SERVER, *_MADRAS_AGENT, "torcs_server_port", "visualise",
              "no_of_visualisations", "no_of_visualizations", "track_len", "track_width",
              "traffic", "pid_latency", "accel_pid", "steer_pid")
_MADRAS_M2 = (*_MADRAS_SERVER, "agents", "traffic", "vision", "torcs_server_port", "visualise",
              "no_of_visualisations", "no_of_visualizations", "track_len", "track_width")
_MADRAS_SERVER_CONFIG = ("max_cars", "min_traffic_cars", "track_category", "track_names",
                         "distance_to_start", "torcs_server_config_dir", "scr_server_config_dir",
                         "traffic_car", "learning_car")
_MADRAS_PID = {"accel_pid": "accel_gains", "steer_pid": "steer_gains",
               "accel_scale": "accel_scale", "steer_scale": "steer_scale",
               "pid_latency": "latency"}
_MADRAS_OBS = {"mode": "mode", "normalize": "normalised", "obs_min": "obs_min",
               "obs_max": "obs_max"}
_MADRAS_TRAFFIC = {"ConstVelTrafficAgent": "ConstVel", "SinusoidalSpeedAgent": "SinusoidalSpeed",
                   "RandomLaneSwitchAgent": "RandomLaneSwitch",
                   "RandomStoppingAgent": "RandomStopping", "ParkedAgent": "DriveAndPark",
                   "DriveAndParkAgent": "DriveAndPark"}
# MADRaS traffic key -> (madsim key, factor to SI); speeds km/h, durations in 0.02 s steps
_KMH = 1.0 / 3.6
_MADRAS_TRAFFIC_KEYS = {
    "target_speed": ("target_speed", _KMH), "target_lane_pos": ("lane", 1.0),
    "speed_amplitude": ("speed_amplitude", _KMH),
    "speed_time_period": ("speed_period", 2.0 * math.pi * TICK_S),   # sin(t / P), t in steps
    "lane_change_interval": ("lane_change_interval", TICK_S),
    "max_stop_duration": ("max_stop_duration", TICK_S),
    "parking_lane_pos": ("parking_lane", None), "parking_dist_from_start": ("parking_distance", None),
    "collision_time_window": ("collision_time_window", 1.0), "min_safe_dist": ("min_safe_dist", 1.0),
    "initial_distance": ("initial_distance", None), "initial_trackpos": ("initial_trackpos", None),
}
_MADRAS_HINTS = {ours: theirs for theirs, (ours, _) in _MADRAS_TRAFFIC_KEYS.items()}
_MADRAS_TRAFFIC_IGNORED = ("vision", "throttle", "gear_change", "visualise", "client_max_steps",
                           "track_len")


def looks_madras(raw: Mapping) -> bool:
    """Whether a scenario mapping is in MADRaS's format (master or devel), by its keys."""
    if set(raw) - set(SECTIONS):
        return bool(set(raw) & (set(_MADRAS_M1) | set(_MADRAS_M2)))
    agent_keys = {f.name for f in fields(AgentConfig)}
    entries = [e for section in ("agents", "traffic") for e in (raw.get(section) or [])
               if isinstance(raw.get(section), list)]
    return any(isinstance(e, Mapping) and len(e) == 1 and "behaviour" not in e
               and not set(e) & agent_keys and isinstance(next(iter(e.values())), (Mapping, type(None)))
               for e in entries)


class MadrasTranslation:
    """Translate a MADRaS config (master or devel) into madsim's format, remembering for every
    translated key where it came from so errors name the key as written in the file."""

    def __init__(self, comms_file: str | None = None):
        self.comms_file = comms_file
        self.origin: dict[str, str] = {}
        self.comm_keys: list[str] = []        # translated keys that come from the comms file
        self.ignored: list[str] = []
        self.notes: list[str] = []

    def source_hint(self, hint: str | None) -> str | None:
        """A hint (a madsim key) as the MADRaS key a user would write instead."""
        return _MADRAS_HINTS.get(hint, hint)

    def from_comms(self, key: str | None) -> bool:
        return bool(key) and any(key == k or key.startswith(k + ".") for k in self.comm_keys)

    def source_key(self, key: str | None) -> str | None:
        if not key:
            return key
        for ours in sorted(self.origin, key=len, reverse=True):
            if key == ours or key.startswith((ours + ".", ours + "[")):
                return self.origin[ours] + key[len(ours):]
        return key

    def put(self, dst: dict, name: str, value, ours: str, src: str) -> None:
        dst[name] = value
        self.origin[join_key(ours, name)] = src

    @staticmethod
    def mapping(value, src: str) -> Mapping:
        if value is None:
            return {}
        if not isinstance(value, Mapping):
            fail(src, "expected a mapping", value)
        return value

    @staticmethod
    def flag(value, src: str) -> bool:
        if not isinstance(value, bool):
            fail(src, "expected true or false", value)
        return value

    @staticmethod
    def check_keys(src_map: Mapping, allowed, prefix: str) -> None:
        for k in src_map:
            if k not in allowed:
                raise unknown_name("key", k, allowed, join_key(prefix, str(k)))

    def translate(self, raw: Mapping, comms: Mapping | None) -> dict:
        devel = "agents" in raw
        self.check_keys(raw, _MADRAS_M2 if devel else _MADRAS_M1, "")
        for k in raw:
            if k in _MADRAS_IGNORED:
                self.ignored.append(k)
        if "vision" in raw and self.flag(raw["vision"], "vision"):
            fail("vision", "vision input is not supported by madsim", True)
        if devel:
            if not isinstance(raw["agents"], list) or not raw["agents"]:
                fail("agents", "expected a list of `- MadrasAgent: {...}` entries", raw["agents"])
            sources = []
            for i, entry in enumerate(raw["agents"]):
                if not isinstance(entry, Mapping) or len(entry) != 1:
                    fail(f"agents[{i}]", "expected one `<AgentClass>: {settings}` entry", entry)
                (cls_name, settings), = entry.items()
                sources.append((f"{cls_name}_{i}", self.mapping(settings, f"agents[{i}].{cls_name}"),
                                f"agents[{i}].{cls_name}"))
        else:
            sources = [("MadrasAgent_0", {k: v for k, v in raw.items() if k in _MADRAS_AGENT}, "")]
        traffic_raw = raw.get("traffic") or []
        if not isinstance(traffic_raw, list):
            fail("traffic", "expected a list of `- <TrafficClass>: {...}` entries", traffic_raw)
        server, cars = self.server(raw, len(sources), len(traffic_raw))
        agents = []
        for i, (name, settings, src) in enumerate(sources):
            agents.append(self.agent(settings, src, f"agents[{i}]", name,
                                     None if cars is None else cars[i]))
        out = {"server": server, "agents": agents,
               "traffic": [self.traffic(e, f"traffic[{i}]") for i, e in enumerate(traffic_raw)]}
        if comms is not None:
            try:
                self.communications(comms, out["agents"])
            except ConfigError as exc:
                exc.file = exc.file or self.comms_file
                raise
        for agent in out["agents"]:
            if "_buff_size" in agent:
                if "communication" not in agent:
                    self.ignored.append(agent["_buff_size"][1])
                del agent["_buff_size"]
        return out

    def server(self, raw: Mapping, n_agents: int, n_traffic: int):
        sc = self.mapping(raw.get("server_config"), "server_config")
        self.check_keys(sc, _MADRAS_SERVER_CONFIG, "server_config")
        for k in sc:
            if k in _MADRAS_IGNORED:
                self.ignored.append(f"server_config.{k}")
        randomize = self.flag(raw.get("randomize_env", raw.get("randomoze_env", False)),
                              "randomize_env")
        out: dict[str, Any] = {"order": "random" if randomize else "fixed"}
        if "track_names" in sc:
            tracks = sc["track_names"]
            if not isinstance(tracks, list) or not tracks:
                fail("server_config.track_names", "expected a list of track names", tracks)
            self.put(out, "tracks", tracks if randomize else tracks[:1], "server",
                     "server_config.track_names")
        cars = None
        if "learning_car" in sc:
            lc = sc["learning_car"]
            lc = [lc] if isinstance(lc, str) else lc
            if not isinstance(lc, list) or not lc:
                fail("server_config.learning_car", "expected a list of car names", lc)
            if randomize:
                self.put(out, "cars", lc, "server", "server_config.learning_car")
            elif len(lc) < n_agents:
                fail("server_config.learning_car", f"needs one car per learning agent "
                     f"({n_agents}) when randomize_env is false", lc)
            else:
                cars = lc[:n_agents]
        for ours, theirs in (("traffic_car", "traffic_car"), ("distance_to_start", "distance_to_start")):
            if theirs in sc:
                self.put(out, ours, sc[theirs], "server", f"server_config.{theirs}")
        max_cars, min_traffic = sc.get("max_cars", 10), sc.get("min_traffic_cars", 0)
        for k, v in (("max_cars", max_cars), ("min_traffic_cars", min_traffic)):
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                fail(f"server_config.{k}", "expected a whole number >= 0", v)
        high = max_cars - n_agents
        if high < 0:
            fail("server_config.max_cars", f"is below the number of learning agents ({n_agents})",
                 max_cars)
        if high > n_traffic:
            self.notes.append(f"server_config.max_cars = {max_cars} leaves room for {high} "
                              f"traffic cars but `traffic` lists {n_traffic}; using at most "
                              f"{n_traffic}")
            high = n_traffic
        low = min(min_traffic, high) if randomize else high
        if randomize and min_traffic > max_cars - n_agents:
            fail("server_config.min_traffic_cars", f"exceeds max_cars - learning agents "
                 f"({max_cars - n_agents})", min_traffic)
        self.put(out, "traffic_count", [low, high], "server", "server_config.max_cars")
        if "max_steps" in raw:
            self.put(out, "max_steps", raw["max_steps"] or None, "server", "max_steps")
        for ours, theirs in (("track_limits", "track_limits"), ("init_wait", "init_wait"),
                             ("observation_noise", "noisy_observations")):
            if theirs in raw:
                self.put(out, ours, raw[theirs], "server", theirs)
        return out, cars

    def agent(self, src: Mapping, sp: str, op: str, name: str, car: str | None) -> dict:
        if sp:
            self.check_keys(src, _MADRAS_AGENT, sp)
        out: dict[str, Any] = {"name": name}
        if sp:
            self.origin[op] = sp
        if car is not None:
            self.put(out, "car", car, op, "server_config.learning_car")
        action: dict[str, Any] = {}
        for k, v in src.items():
            s = join_key(sp, k)
            if k == "pid_assist":
                self.put(action, "space", "TS" if self.flag(v, s) else "SAB", f"{op}.action", s)
            elif k == "normalize_actions":
                self.put(action, "normalised", v, f"{op}.action", s)
            elif k == "target_speed":
                self.put(out, "target_speed", v, op, s)
            elif k == "gear_change":
                self.put(out, "gear", "manual" if self.flag(v, s) else "auto", op, s)
            elif k == "vision" and self.flag(v, s):
                fail(s, "vision input is not supported by madsim", v)
            elif k == "throttle" and not self.flag(v, s):
                fail(s, "throttle control cannot be turned off (MADRaS requires true too)", v)
            elif k == "pid_settings":
                self.put(out, "pid", self.renamed(v, s, _MADRAS_PID, f"{op}.pid"), op, s)
            elif k == "observations":
                self.put(out, "observation", self.observations(v, s, f"{op}.observation", out),
                         op, s)
            elif k in ("rewards", "dones"):
                self.put(out, k, v, op, s)
            elif k in _MADRAS_IGNORED and sp:
                self.ignored.append(s)
        if action:
            out["action"] = action
        add = self.flag(src.get("add_noise_to_actions", False), join_key(sp, "add_noise_to_actions"))
        std = src.get("action_noise_std", 0.001)         # MADRaS's default sigma
        self.put(out, "action_noise_std", std if add else 0.0, op,
                 join_key(sp, "action_noise_std" if "action_noise_std" in src else "add_noise_to_actions"))
        return out

    def renamed(self, value, src: str, table: Mapping[str, str], ours: str) -> dict:
        value = self.mapping(value, src)
        self.check_keys(value, [*table, *(k for k in _MADRAS_IGNORED if k in value)], src)
        out = {}
        for k, v in value.items():
            if k in table:
                self.put(out, table[k], v, ours, join_key(src, k))
            else:
                self.ignored.append(join_key(src, k))
        return out

    def observations(self, value, src: str, ours: str, agent: dict) -> dict:
        value = self.mapping(value, src)
        extra = {k: v for k, v in value.items() if k in ("buff_size", "multi_flag")}
        out = self.renamed({k: v for k, v in value.items() if k not in extra}, src, _MADRAS_OBS, ours)
        if "multi_flag" in extra:
            self.ignored.append(join_key(src, "multi_flag"))
        if "buff_size" in extra:
            agent["_buff_size"] = (extra["buff_size"], join_key(src, "buff_size"))
        return out

    def traffic(self, entry, src: str) -> dict:
        if not isinstance(entry, Mapping) or len(entry) != 1:
            fail(src, "expected one `<TrafficClass>: {settings}` entry", entry)
        (cls_name, settings), = entry.items()
        src = f"{src}.{cls_name}"
        if cls_name not in _MADRAS_TRAFFIC:
            raise unknown_name("traffic class", cls_name, _MADRAS_TRAFFIC, src)
        behaviour = _MADRAS_TRAFFIC[cls_name]
        ours = src.split(".")[0]
        out: dict[str, Any] = {"behaviour": behaviour}
        self.origin[ours] = src
        settings = self.mapping(settings, src)
        allowed = [*_MADRAS_TRAFFIC_KEYS, "pid_settings", *_MADRAS_TRAFFIC_IGNORED]
        self.check_keys(settings, allowed, src)
        for k, v in settings.items():
            s = join_key(src, k)
            if k in _MADRAS_TRAFFIC_IGNORED:
                self.ignored.append(s)
            elif k == "pid_settings":
                self.put(out, "pid", self.renamed(v, s, _MADRAS_PID, f"{ours}.pid"), ours, s)
            else:
                name, factor = _MADRAS_TRAFFIC_KEYS[k]
                self.put(out, name, v if factor is None else as_number(v, s) * factor, ours, s)
        if behaviour == "SinusoidalSpeed" and "speed_amplitude" in out:
            # MADRaS oscillated around 0 km/h (spec 11, item 18); madsim around a mean speed,
            # here the amplitude, so the car varies between standstill and twice the amplitude.
            self.put(out, "mean_speed", out["speed_amplitude"], ours, join_key(src, "speed_amplitude"))
        return out

    def communications(self, comms: Mapping, agents: list[dict]) -> None:
        names = [a["name"] for a in agents]
        by_name = {a["name"]: a for a in agents}
        for receiver, entry in comms.items():
            entry = self.mapping(entry, str(receiver))
            self.check_keys(entry, ("buff_size", "vars", "comms"), str(receiver))
            if receiver not in by_name:
                self.notes.append(f"communications: receiver {receiver!r} is not an agent of this "
                                  f"scenario ({', '.join(names)}); entry ignored")
                continue
            senders = entry.get("comms") or []
            variables = entry.get("vars") or []
            for key, value in (("comms", senders), ("vars", variables)):
                if not isinstance(value, list):
                    fail(f"{receiver}.{key}", "expected a list", value)
            for i, var in enumerate(variables):
                if var not in COMM_VARIABLES:
                    raise unknown_name("variable", var, COMM_VARIABLES, f"{receiver}.vars[{i}]")
            kept = [s for s in senders if s in by_name]
            if len(kept) != len(senders):
                self.notes.append(f"communications: {receiver} hears unknown agent(s) "
                                  f"{[s for s in senders if s not in by_name]}; dropped")
            agent = by_name[receiver]
            length = entry.get("buff_size", 1)
            if isinstance(length, bool) or not isinstance(length, int) or length < 1:
                fail(f"{receiver}.buff_size", "expected a whole number >= 1", length)
            if "_buff_size" in agent:
                obs_length = agent["_buff_size"][0]
                if "buff_size" in entry and obs_length != length:
                    self.notes.append(f"communications: {receiver} buff_size {length} differs from "
                                      f"its observations.buff_size {obs_length}; MADRaS uses the "
                                      "latter, so does madsim")
                length = obs_length
            if kept and variables:
                agent["communication"] = {"senders": kept, "variables": variables,
                                          "buffer_length": length}
                ours = f"agents[{names.index(receiver)}].communication"
                self.origin[ours] = str(receiver)
                self.comm_keys.append(ours)


