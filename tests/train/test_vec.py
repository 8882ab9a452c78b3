"""The SB3 adapter over gymnasium vector envs (madsim.train.vec) against SB3's own DummyVecEnv."""

import numpy as np
import pytest

pytest.importorskip("stable_baselines3", reason="stable-baselines3 not installed: pip install 'madsim[train]'")

from gymnasium.vector import AutoresetMode, SyncVectorEnv
from stable_baselines3.common.vec_env import DummyVecEnv

from madsim.envs import MadrasEnv
from madsim.train.vec import (
    GymnasiumToSB3,
    make_gym_vector_env,
    make_training_env,
    native_make_vec,
)

# Episodes of 30 ticks (S-A-B: one tick per step) so a run of 75 steps crosses two autoresets;
# the drawn track order makes consecutive episodes differ.
SHORT = {
    "server": {"tracks": ["madsim-road", "madsim-oval"], "cars": ["madsim-sedan"], "max_steps": 30},
    "agents": [{"name": "driver", "action": {"space": "SAB", "normalised": True},
                "observation": {"mode": "SingleAgentSimpleLapObs"},
                "rewards": {"Progress2": {"scale": 1.0}},
                "dones": ["TimeOut", "OutOfTrack"]}],
}


def _run(venv, actions):
    venv.seed(11)
    out = [(venv.reset(), None, None, None)]
    for a in actions:
        venv.step_async(a)
        out.append(venv.step_wait())
    venv.close()
    return out


def _sync(mode):
    return SyncVectorEnv([lambda: MadrasEnv(SHORT)] * 2, autoreset_mode=mode)


def _native(mode):
    make_vec = native_make_vec()
    if make_vec is None:
        pytest.skip("madsim.make_vec (the batched vector env) is not in this madsim")
    return make_vec(SHORT, num_envs=2, autoreset_mode=mode)


@pytest.mark.parametrize("make", [_sync, _native], ids=["SyncVectorEnv", "make_vec"])
@pytest.mark.parametrize("mode", [AutoresetMode.SAME_STEP, AutoresetMode.NEXT_STEP])
def test_adapter_matches_dummy_vec_env(make, mode):
    """Same seeds, same actions: observations, rewards, dones, terminal observations and the
    truncation flag equal those of SB3's DummyVecEnv of MadrasEnvs, bit for bit, with either
    gymnasium autoreset mode underneath, over gymnasium's SyncVectorEnv and madsim's make_vec."""
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(75, 2, 3)).astype(np.float32)
    actions[:, :, 1] = 1.0                                   # full throttle: the car moves
    ours = _run(GymnasiumToSB3(make(mode)), actions)
    ref = _run(DummyVecEnv([lambda: MadrasEnv(SHORT)] * 2), actions)
    ends = 0
    for (o1, r1, d1, i1), (o2, r2, d2, i2) in zip(ours, ref):
        np.testing.assert_array_equal(o1, o2)
        if r1 is None:
            continue
        np.testing.assert_array_equal(r1, r2)
        np.testing.assert_array_equal(d1, d2)
        for a, b, done in zip(i1, i2, d1):
            assert a["TimeLimit.truncated"] == b["TimeLimit.truncated"]
            assert a["dones"] == b["dones"]
            if done:
                ends += 1
                np.testing.assert_array_equal(a["terminal_observation"], b["terminal_observation"])
    assert ends == 4                                         # 2 envs x steps 30 and 60


def test_reset_infos_follow_the_new_episode():
    venv = GymnasiumToSB3(SyncVectorEnv([lambda: MadrasEnv(SHORT)] * 2,
                                        autoreset_mode=AutoresetMode.SAME_STEP))
    venv.seed(5)
    venv.reset()
    assert [i["track"] for i in venv.reset_infos] == ["madsim-road", "madsim-road"]
    for _ in range(30):                                      # the first episodes end at step 30
        venv.step(np.tile([0.0, 1.0, -1.0], (2, 1)).astype(np.float32))
    assert [i["track"] for i in venv.reset_infos] == ["madsim-oval", "madsim-oval"]
    venv.close()


def test_training_env_counts_episodes_and_attributes():
    venv = make_training_env(SHORT, 3, seed=0, native=False)
    assert venv.num_envs == 3
    venv.reset()
    assert venv.get_attr("curriculum_progress") == [0, 0, 0]
    venv.set_attr("curriculum_progress", 7, indices=[1])
    assert venv.get_attr("curriculum_progress") == [0, 7, 0]
    for _ in range(30):
        _, _, dones, infos = venv.step(np.zeros((3, 3), dtype=np.float32))
    assert dones.all()
    assert all(i["episode"]["l"] == 30 for i in infos)        # VecMonitor's episode record
    venv.close()


def test_bad_num_envs_is_refused():
    with pytest.raises(ValueError, match="num_envs"):
        make_gym_vector_env(SHORT, 0, native=False)
