"""Curriculum: move a scenario along the paper's eight axes of difficulty, stage by stage.

The axes (paper, "Curriculum Design for Driving Agents") and the stage keys that set them:
1 number of learning agents `agents` (the first n of the scenario's agents), 2 cars offered
`cars`, 3 tracks offered `tracks`, 4 number of traffic cars `traffic_count` (min, max),
5 obstructiveness of traffic `traffic` (a new list of behaviours) and `traffic_set`
(parameter overrides for entries selected by index, behaviour name or "*"), 6 target speed
`target_speed` (m/s, every agent), 7 action noise `action_noise_std` (every agent),
8 observation noise `observation_noise`.

Everything here is a pure function of configs: a stage is applied to the *base* scenario (not
to the previous stage's result), so stages are absolute settings and can be revisited in any
order. Configs are the frozen dataclasses of `madsim.envs.config`; their own checks run again
on the result, so a stage that makes the scenario inconsistent raises the config's error.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

__all__ = ["TRAFFIC_FIELDS", "apply_stage", "stage_at", "stage_index"]

# TrafficConfig fields a `traffic_set` override may name besides behaviour parameters
TRAFFIC_FIELDS = ("car", "pid", "collision_time_window", "min_safe_dist", "initial_distance",
                  "initial_trackpos")


def stage_index(curriculum, progress: int) -> int:
    """Index of the stage in force after `progress` episodes or steps (the curriculum's
    unit): the last stage whose `start` <= progress."""
    index = 0
    for i, stage in enumerate(curriculum.stages):
        if stage.start <= progress:
            index = i
    return index


def stage_at(curriculum, progress: int):
    """The stage in force after `progress` episodes or steps."""
    return curriculum.stages[stage_index(curriculum, progress)]


def _selected(selector: str, index: int, entry) -> bool:
    return selector == "*" or selector == str(index) or selector == entry.behaviour


def _override(entry, index: int, traffic_set: Mapping[str, Mapping[str, Any]]):
    fields: dict[str, Any] = {}
    params: dict[str, Any] = {}
    for selector, changes in traffic_set.items():
        if not _selected(selector, index, entry):
            continue
        for key, value in changes.items():
            (fields if key in TRAFFIC_FIELDS else params)[key] = value
    if not fields and not params:
        return entry
    if params:
        fields["params"] = {**entry.params, **params}
    try:
        return dataclasses.replace(entry, **fields)
    except ValueError as exc:              # the config's error: say which traffic entry
        if hasattr(exc, "under"):
            raise exc.under(f"traffic[{index}]") from None
        raise


def apply_stage(cfg, stage):
    """The scenario `cfg` with the settings of `stage` (keys left None keep cfg's values);
    the result has no curriculum of its own (keep the base scenario to apply later stages).
    Truncating the agents drops links to senders that are gone."""
    server_changes = {k: getattr(stage, k) for k in
                      ("tracks", "cars", "traffic_count", "observation_noise")
                      if getattr(stage, k) is not None}
    traffic = cfg.traffic if stage.traffic is None else stage.traffic
    if stage.traffic_set:
        traffic = tuple(_override(t, i, stage.traffic_set) for i, t in enumerate(traffic))
    agents = cfg.agents if stage.agents is None else cfg.agents[:stage.agents]
    kept = {a.name for a in agents}
    agent_changes = {k: getattr(stage, k) for k in ("target_speed", "action_noise_std")
                     if getattr(stage, k) is not None}
    new_agents = []
    for agent in agents:
        changes = dict(agent_changes)
        link = agent.communication
        if link is not None and any(s not in kept for s in link.senders):
            senders = tuple(s for s in link.senders if s in kept)
            changes["communication"] = (dataclasses.replace(link, senders=senders)
                                        if senders else None)
        new_agents.append(dataclasses.replace(agent, **changes) if changes else agent)
    server = dataclasses.replace(cfg.server, **server_changes) if server_changes else cfg.server
    return dataclasses.replace(cfg, server=server, agents=tuple(new_agents), traffic=traffic,
                               curriculum=None)
