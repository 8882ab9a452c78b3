"""Backends (World in process, SCR over UDP) and the per-episode draws they are given."""

import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from madsim.envs import config as config_module
from madsim.envs.backends import LocalBackend, ScrBackend
from madsim.envs.config import ConfigError, load_config
from madsim.envs.episode import AssetCache, draw_plan, placements
from madsim.envs.madras_env import MadrasEnv

CONFIGS = Path(config_module.__file__).parent / "configs"


def scenario(**server):
    return load_config({"server": server,
                        "agents": [{"name": "x"}, {"name": "y", "car": "madsim-buggy"}],
                        "traffic": [{"behaviour": "ConstVel", "initial_distance": [100, 200],
                                     "initial_trackpos": [-0.5, 0.25]}, {"behaviour": "Parked"},
                                    {"behaviour": "Parked"}]})


# --- the draws (paper, Appendix C) ------------------------------------------------------------


def test_random_draws_are_categorical_and_discrete_uniform_over_seeds():
    cfg = scenario(tracks=["madsim-road", "madsim-oval", "madsim-street"],
                   cars=["madsim-sedan", "madsim-gt"], traffic_count=[1, 3], order="random")
    plans = [draw_plan(cfg, 0, s, np.random.default_rng(s)) for s in range(3000)]
    tracks = np.unique([p.track for p in plans], return_counts=True)[1]
    cars_x = np.unique([p.agent_cars[0] for p in plans], return_counts=True)[1]
    counts = np.bincount([p.n_traffic for p in plans])[1:]
    # expected 1000 / 1500 / 1000 per value; binomial sd <= 27.4, bands are 4 sd
    assert tracks.size == 3 and np.all(np.abs(tracks - 1000) < 110), tracks
    assert cars_x.size == 2 and np.all(np.abs(cars_x - 1500) < 110), cars_x
    assert counts.size == 3 and np.all(np.abs(counts - 1000) < 110), counts
    assert {p.agent_cars[1] for p in plans} == {"madsim-buggy"}      # a fixed car stays fixed
    assert all(p.traffic == cfg.traffic[:p.n_traffic] for p in plans)


def test_fixed_order_walks_the_lists_with_the_episode_index():
    cfg = scenario(tracks=["madsim-road", "madsim-oval"], cars=["madsim-sedan", "madsim-gt"],
                   traffic_count=[0, 2])
    plans = [draw_plan(cfg, k, 0, np.random.default_rng(0)) for k in range(4)]
    assert [p.track for p in plans] == ["madsim-road", "madsim-oval"] * 2
    assert [p.agent_cars[0] for p in plans] == ["madsim-sedan", "madsim-gt"] * 2
    assert [p.n_traffic for p in plans] == [0, 1, 2, 0]


def test_placements_are_continuous_uniform_within_the_ranges_and_grid_otherwise():
    cfg = scenario(traffic_count=[3, 3], distance_to_start=40.0)
    track = AssetCache().track("madsim-road")
    plan = draw_plan(cfg, 0, 0, np.random.default_rng(0))
    assert plan.cars == ("madsim-sedan",) * 3 + ("madsim-sedan", "madsim-buggy")
    draws = np.array([placements(cfg, plan, track, np.random.default_rng(s)) for s in range(2000)])
    s, n = draws[:, 0, 0], draws[:, 0, 1] / (track.width / 2)
    assert s.min() >= 100 and s.max() <= 200 and n.min() >= -0.5 and n.max() <= 0.25
    # uniform: mean within 4 standard errors (sd of U(a, b) = (b - a) / sqrt 12)
    assert abs(s.mean() - 150) < 4 * (100 / 12**0.5) / 2000**0.5
    assert abs(n.mean() + 0.125) < 4 * (0.75 / 12**0.5) / 2000**0.5
    grid = draws[0, 1:]                                   # slots 1..4, all at rest
    assert np.all(draws[:, 1:] == grid) and np.all(grid[:, 2] == 0.0)
    # quick-race grid: distance_to_start (40 m here), 20 m per row of two, 10 m within a row
    expected_s = track.length - np.array([40 + 10, 40 + 20, 40 + 30, 40 + 40])
    assert grid[:, 0] == pytest.approx(expected_s, abs=1e-9)


# --- LocalBackend ------------------------------------------------------------------------------


def test_worlds_are_reused_for_the_same_track_and_cars_and_drive_identically():
    cfg = {"server": {"tracks": ["madsim-road", "madsim-oval"], "order": "fixed"}}
    actions = [np.array([0.2 * np.sin(i / 9), 1.0, -1.0]) for i in range(120)]

    def drive(env, seed, episode):
        out = [env.reset(seed=seed, options={"episode": episode})[0]]
        out += [env.step(a)[0] for a in actions]
        return np.array(out)

    fresh = drive(MadrasEnv(cfg), 3, 0)
    env = MadrasEnv(cfg)
    drive(env, 8, 0)
    drive(env, 8, 1)                                       # the oval
    reused = drive(env, 3, 0)
    assert env.core.backend.worlds_built == 2
    assert np.array_equal(fresh, reused)


def test_world_cache_is_bounded():
    backend = LocalBackend(max_worlds=1)
    env = MadrasEnv({"server": {"tracks": ["madsim-road", "madsim-oval"], "order": "fixed"}},
                    backend=backend)
    for k in (0, 1, 0):
        env.reset(seed=0, options={"episode": k})
    assert backend.worlds_built == 3 and len(backend._worlds) == 1


# --- ScrBackend -------------------------------------------------------------------------------


def test_scr_backend_refuses_what_only_the_server_decides():
    with pytest.raises(ConfigError, match="server.tracks"):
        ScrBackend().check(load_config({"server": {"tracks": ["madsim-road", "madsim-oval"]}}))
    with pytest.raises(ConfigError, match=r"agents\[0\].initial_distance"):
        ScrBackend().check(load_config({"agents": [{"initial_distance": [0, 10]}]}))
    with pytest.raises(ConfigError, match="traffic_count"):
        ScrBackend().check(scenario(traffic_count=[1, 2]))
    ScrBackend().check(load_config(CONFIGS / "single_lap.yml"))


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_scr_backend_against_madsim_serve_sees_what_the_local_backend_sees():
    """Same config, same seed, same S-A-B actions: the observations through `madsim serve`
    equal the in-process ones up to the wire's precision (%g: 6 significant digits, so a
    relative error <= 5e-6, plus float32 rounding). The actions are multiples of 1/16 so that
    they cross the wire exactly; the server runs without fuel use, as the LocalBackend does.
    Two episodes: the second one goes through the server's restart."""
    port = _free_udp_port()
    server = subprocess.Popen([sys.executable, "-m", "madsim.cli", "serve", "--port", str(port),
                               "--countdown", "0", "--nofuel", "--track", "madsim-road",
                               "--cars", "madsim-sedan", "--start-timeout", "30"],
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        remote = MadrasEnv(CONFIGS / "single_lap.yml",
                           backend=ScrBackend(port=port, timeout_s=0.5, tries=60))
        local = MadrasEnv(CONFIGS / "single_lap.yml")
        actions = [np.array([((i % 5) - 2) / 16, 0.5, -1.0]) for i in range(60)]
        for _ in range(2):
            got = [remote.reset(seed=5)[0]] + [remote.step(a)[0] for a in actions]
            want = [local.reset(seed=5)[0]] + [local.step(a)[0] for a in actions]
            np.testing.assert_allclose(np.array(got), np.array(want), rtol=2e-5, atol=2e-6)
        assert np.array(want)[-1, 21] > 0.1                 # speedX: the car did drive
        remote.close()
    finally:
        server.terminate()
        try:
            out = server.communicate(timeout=10)[0]
        except subprocess.TimeoutExpired:
            server.kill()
            out = server.communicate()[0]
    assert "restart requested" in out


def test_sensor_rows_read_like_the_frames_own_rows():
    from madsim.envs.core import SensorRow

    env = MadrasEnv(CONFIGS / "single_lap.yml")
    env.reset(seed=0)
    for _ in range(30):
        env.step(np.array([0.1, 1.0, -1.0]))
    frame = env.core.frame
    row = SensorRow(frame.flat[0].tolist())
    assert dict(row) == frame.row(0)
    assert type(row["damage"]) is int and type(row["track"]) is list
