"""Curriculum stages move a scenario along the paper's eight axes (pure functions)."""

import pytest

from madsim.agents.curriculum import apply_stage, stage_at, stage_index
from madsim.envs.config import ConfigError, StageConfig, TrafficConfig, load_config

BASE = {
    "server": {"tracks": ["madsim-road"], "cars": ["madsim-sedan"], "traffic_count": [0, 2]},
    "agents": [
        {"name": "a", "communication": {"senders": ["b"]}},
        {"name": "b", "communication": {"senders": ["a"], "variables": ["peerActions", "speedX"]}},
    ],
    "traffic": [
        {"behaviour": "Parked", "initial_distance": [30, 40], "initial_trackpos": [-0.7, -0.6]},
        {"behaviour": "ConstVel", "target_speed": 10.0, "lane": 0.5},
    ],
    "curriculum": {"unit": "episodes", "stages": [{"start": 0}, {"start": 100, "agents": 1},
                                                   {"start": 500, "target_speed": 20.0}]},
}


@pytest.fixture(scope="module")
def cfg():
    return load_config(BASE)


def test_stage_in_force(cfg):
    c = cfg.curriculum
    assert [stage_index(c, p) for p in (0, 99, 100, 499, 500, 10**6)] == [0, 0, 1, 1, 2, 2]
    assert stage_at(c, 150).agents == 1


def test_an_empty_stage_keeps_the_scenario(cfg):
    out = apply_stage(cfg, StageConfig(start=0))
    assert out.server == cfg.server and out.agents == cfg.agents and out.traffic == cfg.traffic
    assert out.curriculum is None


def test_number_of_agents_drops_links_to_removed_agents(cfg):
    out = apply_stage(cfg, StageConfig(agents=1))
    assert [a.name for a in out.agents] == ["a"] and out.agents[0].communication is None
    assert len(cfg.agents) == 2                       # the base is untouched


def test_server_axes(cfg):
    out = apply_stage(cfg, StageConfig(cars=("madsim-gt", "madsim-buggy"),
                                       tracks=("madsim-street", "generated:4"),
                                       traffic_count=(1, 1), observation_noise=True))
    s = out.server
    assert s.cars == ("madsim-gt", "madsim-buggy") and s.tracks == ("madsim-street", "generated:4")
    assert s.traffic_count == (1, 1) and s.observation_noise is True
    assert s.max_steps == cfg.server.max_steps


def test_agent_axes_apply_to_every_agent(cfg):
    out = apply_stage(cfg, StageConfig(target_speed=12.5, action_noise_std=0.2))
    assert [(a.target_speed, a.action_noise_std) for a in out.agents] == [(12.5, 0.2)] * 2
    assert out.agents[1].communication == cfg.agents[1].communication


def test_traffic_obstruction_by_replacement_and_overrides(cfg):
    new = (TrafficConfig(behaviour="RandomStopping"),)
    out = apply_stage(cfg, StageConfig(traffic=new, traffic_count=(0, 1)))
    assert out.traffic == new
    out = apply_stage(cfg, StageConfig(traffic_set={"*": {"initial_distance": [30, 35]},
                                                    "ConstVel": {"target_speed": 15.0},
                                                    "0": {"initial_trackpos": [-0.8, -0.7]}}))
    t0, t1 = out.traffic
    assert t0.initial_distance == (30.0, 35.0) and t0.initial_trackpos == (-0.8, -0.7)
    assert t1.initial_distance == (30.0, 35.0) and t1.params["target_speed"] == 15.0
    assert t1.params["lane"] == 0.5                   # untouched parameters stay


def test_a_stage_that_breaks_the_scenario_fails_at_load():
    bad = dict(BASE, curriculum={"stages": [{"start": 0}, {"start": 5, "traffic_count": [0, 3]}]})
    with pytest.raises(ConfigError) as info:
        load_config(bad)
    assert info.value.key == "curriculum.stages[1]" and "traffic_count" in str(info.value)
    bad = dict(BASE, curriculum={"stages": [{"start": 0}, {"start": 5, "traffic_set": {
        "1": {"lane": "left"}}}]})
    with pytest.raises(ConfigError, match="traffic\\[1\\].lane"):
        load_config(bad)
    with pytest.raises(ConfigError, match="increasing"):
        load_config(dict(BASE, curriculum={"stages": [{"start": 0}, {"start": 0}]}))
