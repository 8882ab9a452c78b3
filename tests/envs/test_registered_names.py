"""Issue 14 item 8: a registered id is what its name says from the first episode."""

import gymnasium
import pytest

import madsim  # noqa: F401  (registers the ids)
from madsim.envs.registration import ENV_IDS

TRAFFIC_IDS = [i for i in ENV_IDS if "Traffic" in i and "Curriculum" not in i]


@pytest.mark.parametrize("env_id", TRAFFIC_IDS)
def test_traffic_ids_have_traffic_in_their_first_episode(env_id):
    env = gymnasium.make(env_id)
    for seed in range(3):
        _, info = env.reset(seed=seed)
        assert info["traffic_count"] >= 1, (env_id, seed, info["traffic_count"])
    env.close()


def test_the_curriculum_variant_starts_on_an_empty_road_and_adds_traffic():
    env = gymnasium.make("madsim/MixedTrafficCurriculum-v0")
    _, info = env.reset(seed=0)
    assert info["traffic_count"] == 0
    env.unwrapped.curriculum_progress = 1499
    _, info = env.reset(seed=0)
    assert info["traffic_count"] >= 2
    env.close()
