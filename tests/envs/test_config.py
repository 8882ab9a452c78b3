"""Scenario config: schema defaults, strict errors, round trip and the shipped examples."""

import warnings
from pathlib import Path

import pytest
import yaml

from madsim.agents.observations import ObservationBuilder
from madsim.envs import config
from madsim.envs.config import (
    AgentConfig,
    ConfigError,
    ScenarioConfig,
    action_space,
    check_config,
    config_to_dict,
    generated_track_args,
    load_config,
    observation_size,
    show_config,
)

EXAMPLES = Path(config.__file__).parent / "configs"
EXAMPLE_FILES = sorted(EXAMPLES.glob("*.yml"))


def test_defaults_are_the_dataclass_defaults():
    cfg = load_config(None)
    assert cfg == ScenarioConfig() == load_config({})
    a = cfg.agents[0]
    assert a.name == "agent_0" and cfg.server.tracks == ("madsim-road",)
    assert cfg.server.cars == ("madsim-sedan",)
    assert a.pid.accel_gains == (10.5, 0.05, 2.8) and a.pid.steer_gains == (5.1, 0.001, 1e-6)
    assert a.pid.steer_scale == 0.1 and a.pid.accel_scale == 1.0
    assert [t.name for t in a.rewards] == ["Progress2", "AvgSpeed", "Collision", "TurnBackward",
                                           "AngularAcceleration"]


def test_configs_are_frozen():
    cfg = load_config(None)
    with pytest.raises(AttributeError):
        cfg.server.laps = 3
    with pytest.raises(TypeError):
        cfg.agents[0].observation.obs_min["angle"] = 1.0


def test_shorthand_forms():
    cfg = load_config({"server": {"tracks": "madsim-street", "track_limits": {"low": -0.5, "high": 0.5}},
                       "agents": [{"action": {"space": "T-S"},
                                   "rewards": {"Progress2": 2.0, "RankOne": None}}]})
    assert cfg.server.tracks == ("madsim-street",) and cfg.server.track_limits == (-0.5, 0.5)
    a = cfg.agents[0]
    assert a.action.space == "TS" and [(t.name, t.scale) for t in a.rewards] == [
        ("Progress2", 2.0), ("RankOne", 1.0)]


ERRORS = [  # (config, dotted key, hint or None, text in the message)
    ({"server": {"trakcs": ["a"]}}, "server.trakcs", "tracks", "unknown key"),
    ({"agent": []}, "agent", "agents", "unknown section"),
    ({"agents": [{"rewards": {"ProgresReward2": {}}}]}, "agents[0].rewards.ProgresReward2",
     "ProgressReward2", "unknown reward"),
    ({"agents": [{"rewards": {"AngAcclPenalty": {"max_ang_acl": 2}}}]},
     "agents[0].rewards.AngAcclPenalty.max_ang_acl", "max_ang_accl", "unknown parameter"),
    ({"agents": [{"rewards": {"Progress2": 1, "ProgressReward2": 1}}]},
     "agents[0].rewards.ProgressReward2", None, "same reward"),
    ({"agents": [{"dones": ["Colision"]}]}, "agents[0].dones[0]", "Collision", "unknown done"),
    ({"agents": [{"target_speed": -3}]}, "agents[0].target_speed", None, "must be > 0"),
    ({"agents": [{"target_speed": "fast"}]}, "agents[0].target_speed", None, "expected a number"),
    ({"agents": [{"gear": "automatic"}]}, "agents[0].gear", "auto", "unknown gear"),
    ({"agents": [{"observation": {"mode": "SingleAgentSimpleLap"}}]}, "agents[0].observation.mode",
     "SingleAgentSimpleLapObs", "unknown mode"),
    ({"agents": [{"observation": {"mode": "Fields", "fields": ["trackpos"]}}]},
     "agents[0].observation.fields[0]", "trackPos", "unknown SCR field"),
    ({"agents": [{"communication": {"senders": ["agent_1"]}}]},
     "agents[0].communication.senders[0]", "agent_0", "unknown agent"),
    ({"agents": [{"communication": {"variables": ["peerActions"]}}]}, "agents[0].communication",
     None, "missing required key 'senders'"),
    ({"agents": [{"name": "x"}, {"name": "x"}]}, "agents[1].name", None, "two agents"),
    ({"traffic": [{"behaviour": "ConstVelocity"}]}, "traffic[0].behaviour", "ConstVel",
     "unknown traffic behaviour"),
    ({"traffic": [{"behaviour": "ConstVel", "target_sped": 3}]}, "traffic[0].target_sped",
     "target_speed", "unknown parameter of ConstVel"),
    ({"traffic": [{"behaviour": "DriveAndPark", "parking_lane": [0.5, -0.5]}]},
     "traffic[0].parking_lane", None, "low must not exceed high"),
    ({"traffic": [{"car": "madsim-gt"}]}, "traffic[0]", None, "missing required key 'behaviour'"),
    ({"server": {"traffic_count": [0, 3]}}, "server.traffic_count", None, "exceeds the 0 traffic"),
    ({"server": {"tracks": ["generated:x"]}}, "server.tracks[0]", None, "generated:<seed>"),
    ({"server": {"laps": 1.5}}, "server.laps", None, "whole number"),
    ({"server": {"observation_noise": "yes"}}, "server.observation_noise", None, "true or false"),
    ({"curriculum": {"stages": [{"start": 5}]}}, "curriculum.stages[0].start", None, "start at 0"),
    ({"curriculum": {"stages": [{"start": 0}, {"start": 10, "agents": 3}]}},
     "curriculum.stages[1].agents", None, "1 agents"),
    ({"curriculum": {"stages": [{"start": 0, "targt_speed": 3}]}},
     "curriculum.stages[0].targt_speed", "target_speed", "unknown key"),
]


@pytest.mark.parametrize("raw, key, hint, text", ERRORS, ids=[e[1] for e in ERRORS])
def test_errors_name_key_value_and_nearest(raw, key, hint, text):
    with pytest.raises(ConfigError) as info:
        load_config(raw)
    err = info.value
    assert isinstance(err, ValueError)
    assert err.key == key and err.hint == hint and text in str(err)
    assert str(err).startswith(key + ":")


def test_error_names_the_file_and_yaml_errors_the_line(tmp_path):
    f = tmp_path / "bad.yml"
    f.write_text("agents:\n  - target_speed: -2\n")
    with pytest.raises(ConfigError, match=r"bad\.yml: agents\[0\]\.target_speed: must be > 0 \(got -2\.0\)"):
        load_config(f)
    f.write_text("server:\n  tracks: [a\n  laps: 2\n")
    with pytest.raises(ConfigError, match=r"bad\.yml: line \d+, column \d+: not valid YAML"):
        load_config(f)
    with pytest.raises(ConfigError, match="cannot read"):
        load_config(tmp_path / "missing.yml")
    f.write_text("- just\n- a list\n")
    with pytest.raises(ConfigError, match="mapping of sections"):
        load_config(f)


def test_relative_track_and_car_paths_are_relative_to_the_file(tmp_path):
    f = tmp_path / "sub" / "scenario.yml"
    f.parent.mkdir()
    f.write_text("server:\n  tracks: [madsim-road, ../tracks/my.xml]\n  cars: [cars/c.xml]\n")
    s = load_config(f).server
    assert s.tracks == ("madsim-road", str((tmp_path / "tracks" / "my.xml").resolve()))
    assert s.cars == (str((tmp_path / "sub" / "cars" / "c.xml").resolve()),)


def test_generated_track_entries():
    assert generated_track_args("madsim-road") is None
    assert generated_track_args("generated:7") == {"seed": 7}
    assert generated_track_args("generated:7:2000:8") == {"seed": 7, "length_m": 2000.0, "width_m": 8.0}
    for bad in ("generated:", "generated:-1", "generated:1:0", "generated:1:2:3:4"):
        with pytest.raises(ValueError):
            generated_track_args(bad)


def test_action_spaces():
    def box(**action):
        return action_space(AgentConfig(action=config.ActionConfig(**action)))
    assert box(space="SAB").low.tolist() == [-1, -1, -1]
    assert box(space="SAB", normalised=False).low.tolist() == [-1, 0, 0]
    assert box(space="TS").shape == (2,)
    ts = action_space(AgentConfig(action=config.ActionConfig(space="TS", normalised=False)), (-0.5, 0.5))
    assert ts.low.tolist() == [-0.5, -140] and ts.high.tolist() == [0.5, 140]
    manual = action_space(AgentConfig(gear="manual", action=config.ActionConfig(normalised=False)))
    assert manual.low.tolist() == [-1, 0, 0, -1] and manual.high.tolist() == [1, 1, 1, 6]


def test_observation_size_includes_the_communication_buffer():
    cfg = load_config({"agents": [
        {"name": "a", "observation": {"mode": "SingleAgentInTrafficObs"},
         "communication": {"senders": ["b"], "variables": ["peerActions", "track"], "buffer_length": 3}},
        {"name": "b", "action": {"space": "TS"}}]})
    assert observation_size(cfg, "a") == 60 + 3 * (2 + 19)
    assert observation_size(cfg, "b") == ObservationBuilder("SingleAgentSimpleLapObs").size == 24


def test_round_trip_through_plain_data():
    cfg = load_config({"agents": [{"rewards": {"Task": {"scale": 2.0, "bonus": 50.0}}}],
                       "traffic": [{"behaviour": "RandomLaneSwitch", "lanes": [0.5, -0.5]}]})
    assert load_config(config_to_dict(cfg)) == cfg
    assert cfg.traffic[0].params["lanes"] == (0.5, -0.5)         # a pair, not a range


def test_traffic_registry_is_used_when_the_traffic_layer_exists(monkeypatch):
    import sys
    import types
    fake = types.ModuleType("madsim.agents.traffic")
    fake.BEHAVIOURS = {"ConstVel": object, "Platoon": object}
    monkeypatch.setitem(sys.modules, "madsim.agents.traffic", fake)
    cfg = load_config({"traffic": [{"behaviour": "Platoon", "gap": 5}]})
    assert dict(cfg.traffic[0].params) == {"gap": 5}            # its params are its layer's job
    with pytest.raises(ConfigError, match="Parked"):
        load_config({"traffic": [{"behaviour": "Parked"}]})


# --- the shipped examples ------------------------------------------------------------------


def test_the_examples_are_shipped():
    assert {f.stem for f in EXAMPLE_FILES} >= {"single_lap", "lap_with_noise", "traffic_overtaking",
                                               "bottleneck_two_learners", "mixed_traffic"}


@pytest.mark.parametrize("path", EXAMPLE_FILES, ids=[f.stem for f in EXAMPLE_FILES])
def test_examples_load_without_warnings_check_and_round_trip(path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cfg = load_config(path)
    assert check_config(path).startswith(f"OK {path}")
    assert load_config(yaml.safe_load(show_config(path))) == cfg


def test_traffic_overtaking_example_is_the_papers_experiment_5():
    cfg = load_config(EXAMPLES / "traffic_overtaking.yml")
    a = cfg.agents[0]
    assert cfg.server.tracks == ("madsim-street",) and cfg.server.traffic_count == (4, 5)
    assert a.action.space == "TS" and a.pid.latency == 5 and "Rank1" in a.dones
    assert {t.name: t.scale for t in a.rewards}["RankOne"] == 100.0
    assert all(t.behaviour == "DriveAndPark" for t in cfg.traffic)
    assert observation_size(cfg, "driver") == 60


def test_bottleneck_example_has_two_learners_hearing_each_other():
    cfg = load_config(EXAMPLES / "bottleneck_two_learners.yml")
    first, second = cfg.agents
    assert first.communication.senders == ("second",) and second.communication.senders == ("first",)
    assert observation_size(cfg, "first") == 60 + 2
    assert len(cfg.curriculum.stages) == 2


def test_check_config_fails_for_a_track_that_cannot_be_found():
    with pytest.raises(ConfigError, match="no-such-track"):
        check_config({"server": {"tracks": ["no-such-track"]}})



def test_components_build_from_the_config():
    from madsim.agents.dones import DoneSet
    from madsim.agents.pid import PIDController
    from madsim.agents.rewards import RewardSet
    cfg = load_config(EXAMPLES / "lap_with_noise.yml")
    a = cfg.agents[0]
    obs = ObservationBuilder.from_config(a.observation)
    assert obs.size == 24 and not obs.normalise
    rewards = RewardSet.from_terms(a.rewards, target_speed=a.target_speed)
    assert [(n, w) for n, w, _ in rewards.components] == [
        ("Progress2", 1.0), ("AvgSpeed", 1.0), ("Collision", -10.0), ("TurnBackward", -10.0),
        ("AngularAcceleration", -8.0)]
    dones = DoneSet.from_names(a.dones, max_steps=cfg.server.max_steps, laps=cfg.server.laps,
                               track_limits=cfg.server.track_limits, target_speed=a.target_speed)
    assert [n for n, _ in dones.components] == list(a.dones)
    pid = PIDController.from_config(a.pid)
    assert pid.accel_pid.kp == 10.5 and pid.steer_scale == 0.1 and not pid.compat
