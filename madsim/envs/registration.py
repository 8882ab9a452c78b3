"""Environment ids in gymnasium's (and PettingZoo's) registry; `register_envs` is idempotent.

`madsim/__init__.py` calls `register_envs()`, so `gymnasium.make("madsim/SingleLap-v0")`
works after `import madsim`, and `gymnasium.make("madsim:madsim/SingleLap-v0")` works in a
fresh (e.g. spawned) process. Ids, each with its shipped config (`madsim/envs/configs`) as the
default `config` argument (`gymnasium.make(id, config=...)` replaces it):

| id                                 | config                        | gymnasium | PettingZoo |
|------------------------------------|-------------------------------|-----------|------------|
| madsim/Madras-v0                   | defaults (one S-A-B car)      | yes       | yes        |
| madsim/SingleLap-v0                | single_lap.yml                | yes       | yes        |
| madsim/LapWithNoise-v0             | lap_with_noise.yml            | yes       | yes        |
| madsim/TrafficOvertaking-v0        | traffic_overtaking.yml        | yes       | yes        |
| madsim/MixedTraffic-v0             | mixed_traffic.yml             | yes       | yes        |
| madsim/MixedTrafficCurriculum-v0   | mixed_traffic_curriculum.yml  | yes       | yes        |
| madsim/BottleneckTwoLearners-v0    | bottleneck_two_learners.yml   | no (2 cars)| yes       |
| madsim/RunDefault-v0               | run_default.yml (`madsim run`)| yes       | yes        |

PettingZoo ids (`pettingzoo.make("parallel", id)`) are registered only when the installed
PettingZoo has a registry (`pettingzoo.register`, PettingZoo >= 1.27); otherwise they are
skipped without a word and `MadrasParallelEnv(config)` is the way in.
Nothing here imports the envs themselves (entry points are strings), so importing madsim stays
cheap apart from gymnasium and PettingZoo themselves.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["CONFIGS", "ENV_IDS", "PARALLEL_ENV_IDS", "register_envs"]

CONFIG_DIR = Path(__file__).resolve().parent / "configs"
# id -> (config file or None, one learning agent?)
CONFIGS: dict[str, tuple[str | None, bool]] = {
    "madsim/Madras-v0": (None, True),
    "madsim/SingleLap-v0": ("single_lap.yml", True),
    "madsim/LapWithNoise-v0": ("lap_with_noise.yml", True),
    "madsim/TrafficOvertaking-v0": ("traffic_overtaking.yml", True),
    "madsim/MixedTraffic-v0": ("mixed_traffic.yml", True),
    "madsim/MixedTrafficCurriculum-v0": ("mixed_traffic_curriculum.yml", True),
    "madsim/BottleneckTwoLearners-v0": ("bottleneck_two_learners.yml", False),
    "madsim/RunDefault-v0": ("run_default.yml", True),
}
ENV_IDS = tuple(i for i, (_, single) in CONFIGS.items() if single)
PARALLEL_ENV_IDS = tuple(CONFIGS)
_ENTRY = "madsim.envs.madras_env:MadrasEnv"
_VECTOR_ENTRY = "madsim.envs.vector:MadrasVectorEnv"   # gymnasium.make_vec(id, vectorization_mode="vector_entry_point")
_PARALLEL_ENTRY = "madsim.envs.parallel_env:MadrasParallelEnv"


def _kwargs(file: str | None) -> dict:
    return {"config": None if file is None else str(CONFIG_DIR / file)}


def register_envs() -> None:
    """Register every id that is not registered yet (safe to call any number of times)."""
    import gymnasium

    for env_id in ENV_IDS:
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=_ENTRY, kwargs=_kwargs(CONFIGS[env_id][0]),
                               nondeterministic=False, vector_entry_point=_VECTOR_ENTRY)
    try:
        import pettingzoo
    except ImportError:
        return
    register = getattr(pettingzoo, "register", None)
    registry = getattr(pettingzoo, "parallel_registry", None)
    if register is None or registry is None:
        return
    for env_id in PARALLEL_ENV_IDS:
        if env_id not in registry:
            register("parallel", env_id, _PARALLEL_ENTRY, kwargs=_kwargs(CONFIGS[env_id][0]))
