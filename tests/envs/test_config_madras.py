"""MADRaS's own config files load unchanged (master madras_config.yml, devel sim_options*.yml
with communications.yml); read from ../shared/madras-configs, never copied here."""

import math
import shutil
from pathlib import Path

import pytest

from madsim.envs.config import ConfigError, ConfigWarning, config_to_dict, load_config, observation_size

MADRAS = Path(__file__).resolve().parents[3] / "shared" / "madras-configs"


@pytest.fixture(scope="module")
def madras_dir():
    if not (MADRAS / "madras_config.yml").is_file():
        pytest.skip(f"MADRaS reference configs not found in {MADRAS}")
    return MADRAS


def load_warned(path, **kw):
    with pytest.warns(ConfigWarning) as record:
        cfg = load_config(path, **kw)
    return cfg, [str(w.message) for w in record]


def test_master_config_maps_every_key(madras_dir):
    cfg, messages = load_warned(madras_dir / "madras_config.yml")
    s = cfg.server
    assert s.tracks == ("forza", "aalborg", "alpine-1", "alpine-2") and s.order == "random"
    assert s.cars == ("car1-stock1", "car1-stock2") and s.traffic_car == "p406"
    assert s.traffic_count == (1, 9)                 # min_traffic_cars .. max_cars - 1 learner
    assert s.observation_noise is True and s.max_steps == 1000 and s.distance_to_start == 25
    (a,) = cfg.agents
    assert a.name == "MadrasAgent_0" and a.target_speed == 13.89
    assert a.action.space == "TS" and a.action.normalised is True and a.gear == "auto"
    assert a.action_noise_std == 0.01
    assert a.pid.accel_gains == (10.5, 0.05, 2.8) and a.pid.steer_gains == (5.1, 0.001, 1e-6)
    assert a.pid.latency == 10 and a.pid.steer_scale == 0.1
    assert a.observation.mode == "SingleAgentInTrafficObs" and not a.observation.normalised
    assert dict(a.observation.obs_max) == {"angle": 3.142, "track": 200.0, "trackPos": 1.0}
    assert [(t.name, t.scale) for t in a.rewards] == [
        ("Progress2", 1.0), ("AvgSpeed", 1.0), ("SuccessfulOvertake", 10.0), ("Collision", 10.0),
        ("TurnBackward", 10.0), ("AngularAcceleration", 2.0)]
    assert dict(a.rewards[-1].params) == {"max_ang_accl": 2.0}
    assert a.dones == ("RaceOver", "TimeOut", "Collision", "TurnBackward", "OutOfTrack", "Rank1")
    assert len(cfg.traffic) == 9 and {t.behaviour for t in cfg.traffic} == {"DriveAndPark"}
    t = cfg.traffic[0]
    assert t.params["target_speed"] == pytest.approx(50 / 3.6)        # km/h -> m/s
    assert t.params["parking_lane"] == (-0.8, 0.0) and t.params["parking_distance"] == (185, 200)
    assert t.collision_time_window == 1.2 and t.pid.accel_gains == (10.5, 0.05, 2.8)
    assert load_config(config_to_dict(cfg)) == cfg           # same scenario in madsim's format
    (msg,) = messages
    for key in ("torcs_server_port", "visualise", "no_of_visualisations", "client_max_steps",
                "server_config.torcs_server_config_dir", "server_config.scr_server_config_dir"):
        assert key in msg


def test_devel_config_with_its_communications_file(madras_dir):
    cfg, messages = load_warned(madras_dir / "sim_options_v2.yml")   # sibling file read
    (a,) = cfg.agents
    assert a.name == "MadrasAgent_0" and a.car == "car1-stock1"      # not randomised: first car
    assert cfg.server.tracks == ("forza",) and cfg.server.order == "fixed"
    assert cfg.server.traffic_count == (0, 0) and cfg.traffic == ()
    assert a.target_speed == 27.78 and a.action.space == "TS" and a.action_noise_std == 0.0
    assert a.rewards[0].name == "Progress3"
    link = a.communication
    assert link.senders == ("MadrasAgent_0",)            # MadrasAgent_1 does not exist here
    assert link.variables == ("action", "speedX", "speedY", "track")
    assert link.buffer_length == 1                       # observations.buff_size, as MADRaS
    assert observation_size(cfg, "MadrasAgent_0") == 24 + (2 + 1 + 1 + 19)
    text = " ".join(messages)
    assert "MadrasAgent_1" in text and "agents[0].MadrasAgent.observations.multi_flag" in text
    assert load_config(config_to_dict(cfg)) == cfg
    explicit, _ = load_warned(madras_dir / "sim_options_v2.yml",
                              communications=madras_dir / "communications.yml")
    assert explicit == cfg


def test_devel_config_without_communications(madras_dir, tmp_path):
    shutil.copy(madras_dir / "sim_options_v2.yml", tmp_path / "sim_options_v2.yml")
    cfg, _ = load_warned(tmp_path / "sim_options_v2.yml")
    assert cfg.agents[0].communication is None


def test_devel_single_agent_config(madras_dir):
    cfg, _ = load_warned(madras_dir / "sim_options.yml")
    assert cfg.agents[0].observation.mode == "SingleAgentSimpleLapObs"
    assert cfg.server.traffic_count == (9, 9)            # max_cars default 10, not randomised
    assert cfg.traffic[0].params["parking_distance"] == (185, 200)


def test_madras_errors_name_the_key_as_written():
    base = {"torcs_server_port": 60934}
    cases = [
        ({"pid_settings": {"accel_pid": [1, 2, "x"]}}, "pid_settings.accel_pid[2]", None),
        ({"pid_settings": {"accel_pd": [1, 2, 3]}}, "pid_settings.accel_pd", "accel_pid"),
        ({"randomise_env": True}, "randomise_env", "randomize_env"),
        ({"traffic": [{"ParkedAgnt": {}}]}, "traffic[0].ParkedAgnt", "ParkedAgent"),
        ({"traffic": [{"ParkedAgent": {"parking_lane_pos": {"low": 1, "high": 0}}}]},
         "traffic[0].ParkedAgent.parking_lane_pos", None),
        ({"traffic": [{"ConstVelTrafficAgent": {"parking_lane_pos": {"low": 0, "high": 1}}}]},
         "traffic[0].ConstVelTrafficAgent.parking_lane_pos", "target_lane_pos"),
        ({"rewards": {"ProgressRewrd2": {"scale": 1.0}}}, "rewards.ProgressRewrd2", "ProgressReward2"),
        ({"dones": ["TimeOut", "Rank2"]}, "dones[1]", "Rank1"),
        ({"observations": {"mode": "SingleAgentInTrafficOb"}}, "observations.mode",
         "SingleAgentInTrafficObs"),
        ({"target_speed": -1}, "target_speed", None),
        ({"vision": True}, "vision", None),
        ({"throttle": False}, "throttle", None),
        ({"server_config": {"max_cars": 0}}, "server_config.max_cars", None),
        ({"randomize_env": False, "server_config": {"learning_car": []}},
         "server_config.learning_car", None),
    ]
    for extra, key, hint in cases:
        with pytest.raises(ConfigError) as info:
            load_config({**base, **extra})
        assert (info.value.key, info.value.hint) == (key, hint), extra
    with pytest.raises(ConfigError) as info:
        load_config({"agents": [{"MadrasAgent": {"rewards": {"CollisionPenalty": {"scale": -1}}}}]})
    assert info.value.key == "agents[0].MadrasAgent.rewards.CollisionPenalty.scale"


def test_madras_unit_conversions_of_traffic():
    cfg = load_config({"traffic": [
        {"SinusoidalSpeedAgent": {"speed_amplitude": 36, "speed_time_period": 1000,
                                  "target_lane_pos": -0.25}},
        {"RandomStoppingAgent": {"target_speed": 72, "max_stop_duration": 5}},
        {"RandomLaneSwitchAgent": {"target_speed": 100, "lane_change_interval": 5}}],
        "server_config": {"max_cars": 4}})
    sin, stop, switch = (t.params for t in cfg.traffic)
    assert sin["speed_amplitude"] == pytest.approx(10.0) and sin["mean_speed"] == pytest.approx(10.0)
    assert sin["speed_period"] == pytest.approx(2 * math.pi * 1000 * 0.02)   # sin(t/1000), t in ticks
    assert sin["lane"] == -0.25
    assert stop["target_speed"] == pytest.approx(20.0) and stop["max_stop_duration"] == pytest.approx(0.1)
    assert switch["lane_change_interval"] == pytest.approx(0.1)


def test_fewer_traffic_entries_than_max_cars_allows_is_a_warning():
    with pytest.warns(ConfigWarning, match="max_cars = 10"):
        cfg = load_config({"randomize_env": True, "traffic": [{"ParkedAgent": {}}]})
    assert cfg.server.traffic_count == (0, 1)


def test_errors_name_the_file_they_are_in(madras_dir, tmp_path):
    main = tmp_path / "sim_options_v2.yml"
    main.write_text((madras_dir / "sim_options_v2.yml").read_text().replace(
        "target_speed: 27.78", "target_sped: 27.78"))
    comms = tmp_path / "communications.yml"
    comms.write_text((madras_dir / "communications.yml").read_text())
    with pytest.raises(ConfigError) as info:
        load_config(main)
    assert info.value.file == str(main) and info.value.key == "agents[0].MadrasAgent.target_sped"
    main.write_text((madras_dir / "sim_options_v2.yml").read_text())
    comms.write_text("MadrasAgent_0:\n  vars: [speedx]\n  comms: [MadrasAgent_0]\n")
    with pytest.raises(ConfigError) as info:
        load_config(main)
    assert (info.value.file, info.value.key, info.value.hint) == (str(comms), "MadrasAgent_0.vars[0]",
                                                                  "speedX")
    comms.write_text("MadrasAgent_0:\n  vars: [speedX]\n  comms: [MadrasAgent_0]\n  buff_size: 2\n")
    main.write_text((madras_dir / "sim_options_v2.yml").read_text().replace("buff_size: 1", ""))
    cfg, _ = load_warned(main)
    assert cfg.agents[0].communication.buffer_length == 2      # the file's own buff_size
