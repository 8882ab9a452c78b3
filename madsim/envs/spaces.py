"""Gymnasium spaces derived from the scenario schema: an agent's action Box and the length of
its observation vector."""

from __future__ import annotations

import gymnasium
import numpy as np

from madsim.agents.comms import ACTION_VARIABLES
from madsim.agents.observations import FIELD_WIDTH, ObservationBuilder
from madsim.envs.schema import AgentConfig, ScenarioConfig

__all__ = ["MANUAL_GEARS", "action_space", "observation_size"]


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

