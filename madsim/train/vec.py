"""The vector env training runs on, and its adapter to stable-baselines3's VecEnv interface.

`make_gym_vector_env(config, num_envs)` returns a `gymnasium.vector.VectorEnv` of `num_envs`
independent episodes: madsim's native batched env (`madsim.make_vec`) when it is installed,
else gymnasium's `SyncVectorEnv` of `MadrasEnv`s (same-step autoreset). Choosing between the
two happens in that one function. `make_training_env` wraps the result for stable-baselines3
(`GymnasiumToSB3`), which converts gymnasium's vector API (dict-of-arrays infos, either
autoreset mode) into SB3's (list of info dicts, `terminal_observation`,
`TimeLimit.truncated`), exactly as SB3's `DummyVecEnv` reports a list of single envs.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from typing import Any

import numpy as np

__all__ = ["GymnasiumToSB3", "make_gym_vector_env", "make_training_env", "native_make_vec"]


def native_make_vec():
    """madsim's batched vector env factory `make_vec(config, num_envs=...)`, or None when this
    madsim has none yet. A fault inside an existing module is raised, not hidden."""
    import madsim

    make_vec = getattr(madsim, "make_vec", None)
    if make_vec is not None:
        return make_vec
    try:
        module = importlib.import_module("madsim.envs.vector")
    except ModuleNotFoundError as exc:
        if exc.name != "madsim.envs.vector":
            raise
        return None
    return getattr(module, "make_vec", None)


def make_gym_vector_env(config, num_envs: int, *, native: bool | None = None):
    """A gymnasium VectorEnv of `num_envs` episodes of the (single-learner) scenario `config`
    (path, mapping or ScenarioConfig). native None: madsim.make_vec if installed, else a
    SyncVectorEnv of MadrasEnv; True/False forces the choice (True raises if unavailable)."""
    from gymnasium.vector import AutoresetMode, SyncVectorEnv

    from madsim.envs.config import ScenarioConfig, load_config
    from madsim.envs.madras_env import MadrasEnv

    if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
        raise ValueError(f"num_envs must be an int >= 1, got {num_envs!r}")
    cfg = config if isinstance(config, ScenarioConfig) else load_config(config)
    make_vec = native_make_vec() if native is not False else None
    if native and make_vec is None:
        raise ValueError("madsim.make_vec (the batched vector env) is not installed in this madsim")
    if make_vec is not None:       # same-step autoreset: what SB3 expects, no extra reset call
        return make_vec(cfg, num_envs=int(num_envs), autoreset_mode=AutoresetMode.SAME_STEP)
    return SyncVectorEnv([lambda: MadrasEnv(cfg) for _ in range(int(num_envs))],
                         autoreset_mode=AutoresetMode.SAME_STEP)


def make_training_env(config, num_envs: int = 1, *, seed: int | None = 0,
                      native: bool | None = None):
    """An SB3 VecEnv (VecMonitor over `GymnasiumToSB3`) of `num_envs` episodes of `config`;
    env i is first reset with seed `seed + i` (None: unseeded)."""
    from stable_baselines3.common.vec_env import VecMonitor

    venv = GymnasiumToSB3(make_gym_vector_env(config, num_envs, native=native))
    if seed is not None:
        venv.seed(int(seed))
    return VecMonitor(venv)


def _unbatch(infos: Mapping, i: int) -> dict:
    """Env i's info dict from gymnasium's batched info (values per env, '_key' masks)."""
    out = {}
    for key, value in infos.items():
        if key.startswith("_"):
            continue
        mask = infos.get("_" + key)
        if mask is not None and not mask[i]:
            continue
        if isinstance(value, Mapping):
            out[key] = _unbatch(value, i)
        else:
            item = value[i]
            out[key] = item.item() if isinstance(item, np.generic) else item
    return out


def _base():
    from stable_baselines3.common.vec_env.base_vec_env import VecEnv

    return VecEnv


class GymnasiumToSB3(_base()):
    """A gymnasium `VectorEnv` seen as a stable-baselines3 `VecEnv`.

    Observations (num_envs, *obs_shape), rewards (num_envs,) float32, dones (num_envs,) bool,
    infos a list of dicts. When env i ends, its returned observation is already the first of
    the next episode and `infos[i]` holds the last step's info plus `terminal_observation` and
    `TimeLimit.truncated`. Works with either gymnasium autoreset mode: same-step (final values
    in `final_obs`/`final_info`) or next-step (the ended envs are reset at once through
    `reset(options={"reset_mask": ...})`).
    """

    def __init__(self, venv):
        from gymnasium.vector import AutoresetMode

        self.venv = venv
        mode = venv.metadata.get("autoreset_mode", AutoresetMode.NEXT_STEP)
        if isinstance(mode, str):
            mode = AutoresetMode(mode)
        if mode not in (AutoresetMode.SAME_STEP, AutoresetMode.NEXT_STEP):
            raise ValueError(f"GymnasiumToSB3 needs a vector env that resets ended episodes "
                             f"itself (same-step or next-step autoreset), got {mode}")
        self.same_step = mode == AutoresetMode.SAME_STEP
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self._actions = None

    def reset(self):
        seeds = None if all(s is None for s in self._seeds) else list(self._seeds)
        options = self._options[0] if self._options and self._options[0] else None
        obs, infos = self.venv.reset(seed=seeds, options=options)
        self.reset_infos = [_unbatch(infos, i) for i in range(self.num_envs)]
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        obs, rewards, terminated, truncated, infos = self.venv.step(self._actions)
        dones = np.logical_or(terminated, truncated)
        out = []
        if self.same_step:
            final_obs, final_info = infos.get("final_obs"), infos.get("final_info", {})
            for i in range(self.num_envs):
                if dones[i]:
                    info = _unbatch(final_info, i)
                    info["terminal_observation"] = final_obs[i]
                    self.reset_infos[i] = _unbatch(infos, i)
                    for key in ("final_obs", "final_info"):
                        self.reset_infos[i].pop(key, None)
                else:
                    info = _unbatch(infos, i)
                out.append(info)
        else:
            out = [_unbatch(infos, i) for i in range(self.num_envs)]
            if dones.any():
                obs = np.array(obs, copy=True)
                for i in np.flatnonzero(dones):
                    out[i]["terminal_observation"] = obs[i].copy()
                new_obs, new_infos = self.venv.reset(options={"reset_mask": dones.copy()})
                obs[dones] = new_obs[dones]
                for i in np.flatnonzero(dones):
                    self.reset_infos[i] = _unbatch(new_infos, i)
        for i in range(self.num_envs):
            out[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
        return obs, np.asarray(rewards, dtype=np.float32), dones, out

    def close(self) -> None:
        self.venv.close()

    # attribute access is per sub-env in SB3 and only exists on gymnasium's Sync/Async envs

    def _indices(self, indices) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        if isinstance(indices, int):
            return [indices]
        return list(indices)

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        if attr_name == "render_mode":       # SB3 asks at construction; vector envs hold one
            return [getattr(self.venv, "render_mode", None)] * len(self._indices(indices))
        values = self.venv.get_attr(attr_name)
        return [values[i] for i in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        idx = self._indices(indices)
        if len(idx) == self.num_envs:
            self.venv.set_attr(attr_name, value)
            return
        current = list(self.venv.get_attr(attr_name))
        for i in idx:
            current[i] = value
        self.venv.set_attr(attr_name, current)

    def env_method(self, method_name: str, *args, indices=None, **kwargs) -> list[Any]:
        results = self.venv.call(method_name, *args, **kwargs)
        return [results[i] for i in self._indices(indices)]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        envs = getattr(self.venv, "envs", None)
        if envs is None:
            return [False] * len(self._indices(indices))
        from stable_baselines3.common.env_util import is_wrapped

        return [is_wrapped(envs[i], wrapper_class) for i in self._indices(indices)]
