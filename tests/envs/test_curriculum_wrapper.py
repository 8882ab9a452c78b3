"""CurriculumWrapper: training code moves a MadrasEnv through its curriculum stages."""

import pytest

from madsim.envs import MadrasEnv
from madsim.envs.wrappers import CurriculumWrapper

CONFIG = {
    "server": {"max_steps": 50},
    "agents": [{"name": "a", "target_speed": 10.0}],
    "curriculum": {"unit": "steps", "stages": [{"start": 0}, {"start": 1000, "target_speed": 25.0}]},
}


def test_stage_follows_the_progress_set_by_a_callback():
    env = CurriculumWrapper(MadrasEnv(CONFIG))
    _, info = env.reset(seed=1)
    assert info["curriculum_stage"] == 0 and env.stage == 0
    env.set_progress(999)
    _, info = env.reset()
    assert info["curriculum_stage"] == 0
    env.advance(1)                      # 1000: the second stage
    _, info = env.reset()
    assert info["curriculum_stage"] == 1 and info["curriculum_progress"] == 1000
    assert env.unwrapped.core.stage.cfg.agents[0].target_speed == pytest.approx(25.0)
    _, _, _, _, info = env.step(env.action_space.sample())
    assert info["curriculum_stage"] == 1
    env.close()


def test_bad_progress_and_wrong_env_are_refused():
    env = CurriculumWrapper(MadrasEnv(CONFIG))
    with pytest.raises(ValueError, match="progress"):
        env.set_progress(-1)
    import gymnasium
    with pytest.raises(TypeError, match="madsim env"):
        CurriculumWrapper(gymnasium.make("CartPole-v1"))
