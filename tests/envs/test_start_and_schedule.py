"""The race start and the tick schedule as env options (issue 12): `server.grid` puts the cars
where `madsim serve --grid` does, `server.tick_schedule: torcs` steps the World on TORCS's own
driver-call schedule (madsim.physics.schedule.TorcsClock), tick for tick from every reset."""

import numpy as np
import pytest

from madsim.cli import make_world_factory, parse_grid
from madsim.envs.backends import ScrBackend
from madsim.envs.config import ConfigError, config_to_dict, load_config
from madsim.envs.madras_env import MadrasEnv
from madsim.envs.parallel_env import MadrasParallelEnv
from madsim.physics import layout as L
from madsim.physics.schedule import TorcsClock
from madsim.facts import SUBSTEP_S

TRACES_START = {"rows": 1, "distance_to_start": 100.0}     # the real-TORCS traces' race file


def scenario(server=None, traffic=()):
    return {"server": {"tracks": ["madsim-oval"], "max_steps": 1000, **(server or {})},
            "agents": [{"name": "learner"}], "traffic": list(traffic)}


def substeps_done(world) -> int:
    """Sub-steps since reset, from the World's clock (a sum of 0.002 s; exact to well under one)."""
    return round(world.time / SUBSTEP_S)


def test_torcs_schedule_env_ticks_are_torcs_clock_calls_from_every_reset():
    env = MadrasEnv(scenario({"tick_schedule": "torcs"}))
    action = np.array([0.0, 0.5, -1.0], dtype=np.float32)
    for seed in (3, 4):                               # the clock starts over at each reset
        env.reset(seed=seed)
        clock = TorcsClock()
        expected = 0
        for _ in range(30):
            env.step(action)
            expected += clock.substeps()
            assert substeps_done(env.core.backend.world) == expected
    # 30 ticks hold TORCS's two late (0.022 s) calls, at ticks 12 and 24 after the green light
    assert expected == 30 * 10 + 2


def test_fixed_schedule_stays_the_default_at_exactly_ten_substeps_per_tick():
    env = MadrasEnv(scenario())
    env.reset(seed=0)
    for _ in range(30):
        env.step(np.array([0.0, 0.5, -1.0], dtype=np.float32))
    assert substeps_done(env.core.backend.world) == 300
    assert load_config(scenario()).server.tick_schedule == "fixed"


def test_parallel_env_runs_the_schedule_too():
    env = MadrasParallelEnv(scenario({"tick_schedule": "torcs"}))
    env.reset(seed=1)
    for _ in range(25):
        env.step({"learner": np.array([0.0, 0.5, -1.0], dtype=np.float32)})
    assert substeps_done(env.core.backend.world) == 25 * 10 + 2


def test_grid_start_places_cars_where_madsim_serve_grid_does():
    cfg = scenario({"grid": TRACES_START},
                   traffic=[{"behaviour": "ConstVel"}, {"behaviour": "Parked"}])
    env = MadrasEnv(cfg)
    env.reset(seed=0)
    got = env.core.backend.world
    served = make_world_factory("madsim-oval", ["madsim-sedan"], 3,
                                grid=parse_grid("rows=1,distance_to_start=100"))(0)
    cols = [L.S_X, L.S_Y, L.S_YAW, L.S_DIST]
    assert np.array_equal(got.state[:, cols], served.state[:, cols])
    # TORCS's grid, one row: car k 100 + 20 k m before the line, on the centre line
    length = got.track.length
    s, n = got.track.locate(got.state[:, L.S_X], got.state[:, L.S_Y])
    np.testing.assert_allclose(s, length - 100.0 - 20.0 * np.arange(3), atol=1e-6)
    np.testing.assert_allclose(n, 0.0, atol=1e-6)


def test_grid_values_left_out_keep_quickrace_and_distance_to_start():
    cfg = load_config(scenario({"grid": {"rows": 3}, "distance_to_start": 40.0}))
    assert cfg.server.grid.race_grid(cfg.server.distance_to_start) == {
        "distance to start": 40.0, "rows": 3.0}
    assert load_config(config_to_dict(cfg)) == cfg


@pytest.mark.parametrize("server, key, words", [
    ({"tick_schedule": "exact"}, "server.tick_schedule", "unknown tick_schedule value"),
    ({"grid": {"rows": 0}}, "server.grid.rows", "must be > 0"),
    ({"grid": {"row": 1}}, "server.grid.row", "did you mean 'rows'"),
    ({"grid": {"distance_to_start": 100}, "distance_to_start": 50},
     "server.grid.distance_to_start", "give one"),
])
def test_bad_start_and_schedule_values_name_the_key(server, key, words):
    with pytest.raises(ConfigError) as err:
        load_config(scenario(server))
    assert err.value.key == key and words in str(err.value)


def test_scr_backend_leaves_grid_and_schedule_to_the_server():
    for server, key in (({"grid": TRACES_START}, "server.grid"),
                        ({"tick_schedule": "torcs"}, "server.tick_schedule")):
        with pytest.raises(ConfigError, match="server") as err:
            ScrBackend().check(load_config(scenario(server)))
        assert err.value.key == key
