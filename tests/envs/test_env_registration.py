"""Registered ids: gymnasium and PettingZoo, idempotent, spawn-safe, one per shipped config."""

import subprocess
import sys
import warnings
from pathlib import Path

import gymnasium
import numpy as np
import pytest

import madsim
from madsim.envs import config as config_module
from madsim.envs.config import load_config
from madsim.envs.registration import CONFIGS, ENV_IDS, PARALLEL_ENV_IDS, register_envs

SHIPPED = {p.name for p in (Path(config_module.__file__).parent / "configs").glob("*.yml")}


def test_every_shipped_config_has_an_id_and_single_agent_ones_a_gymnasium_id():
    assert {f for f, _ in CONFIGS.values() if f} == SHIPPED
    for env_id, (file, single) in CONFIGS.items():
        cfg = load_config(None if file is None else Path(config_module.__file__).parent / "configs" / file)
        assert single == (len(cfg.agents) == 1), env_id
        assert (env_id in ENV_IDS) == single and env_id in PARALLEL_ENV_IDS


def test_registration_is_idempotent_and_silent():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        register_envs()
        register_envs()
    assert {i for i in gymnasium.registry if i.startswith("madsim/")} == set(ENV_IDS)


def test_gymnasium_make_with_and_without_a_config_argument():
    env = gymnasium.make("madsim/SingleLap-v0")
    assert env.unwrapped.config.server.max_steps == 15000
    obs, info = env.reset(seed=0)
    assert obs.shape == (24,) and info["track"] == "madsim-road"
    other = gymnasium.make("madsim/Madras-v0", config={"server": {"tracks": ["madsim-oval"]}})
    assert other.reset(seed=0)[1]["track"] == "madsim-oval"


def test_pettingzoo_registry_when_pettingzoo_has_one():
    pettingzoo = pytest.importorskip("pettingzoo")
    if not hasattr(pettingzoo, "register"):
        pytest.skip("this PettingZoo has no registry (pettingzoo.register needs >= 1.27)")
    assert set(PARALLEL_ENV_IDS) <= set(pettingzoo.parallel_registry)
    env = pettingzoo.make("parallel", "madsim/SingleLap-v0")
    obs, _ = env.reset(seed=0)
    assert env.possible_agents == ["driver"] and obs["driver"].shape == (24,)


def test_a_fresh_process_can_make_an_env_by_module_prefixed_id():
    """What a spawned vector-env worker does: nothing imported yet but gymnasium."""
    code = ("import gymnasium; env = gymnasium.make('madsim:madsim/SingleLap-v0'); "
            "obs, info = env.reset(seed=1); print(obs.shape, info['seed'])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, check=False)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "(24,) 1"


def test_madsim_keeps_its_version():
    assert madsim.__version__ == "0.1.0"


def test_gymnasium_vector_env_over_registered_ids_is_deterministic():
    def make():
        return gymnasium.make_vec("madsim/LapWithNoise-v0", num_envs=2, vectorization_mode="sync")
    runs = []
    for _ in range(2):
        vec = make()
        obs, _ = vec.reset(seed=[3, 4])
        out = [obs]
        for _ in range(20):
            out.append(vec.step(np.tile([0.0, 1.0, -1.0], (2, 1)))[0])
        runs.append(np.array(out))
        vec.close()
    assert np.array_equal(runs[0], runs[1]) and not np.array_equal(runs[0][:, 0], runs[0][:, 1])
