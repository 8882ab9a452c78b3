"""madsim: a pure-Python, TORCS-like driving simulator for reinforcement learning."""

__version__ = "0.1.0"

from madsim.kernel_cache import install as _install_kernel_cache

_install_kernel_cache()   # before any kernel module: numba picks cache locators at decoration

from madsim.envs.registration import register_envs as _register_envs

_register_envs()


def make_vec(config=None, num_envs: int = 1, **kwargs):
    """N episodes of a one-learner scenario as ONE batched gymnasium VectorEnv (one batched
    World; cars of different episodes never interact); see madsim.envs.vector.make_vec."""
    from madsim.envs.vector import make_vec as _make_vec

    return _make_vec(config, num_envs, **kwargs)


def to_sb3(venv):
    """A gymnasium VectorEnv (e.g. `make_vec(...)`) as a stable-baselines3 VecEnv, ready for
    `PPO("MlpPolicy", to_sb3(make_vec(config, num_envs=8)))` (extra `train`); the adapter is
    madsim.train.vec.GymnasiumToSB3 (list infos, `terminal_observation`, either autoreset mode)."""
    try:
        from madsim.train.vec import GymnasiumToSB3
    except ModuleNotFoundError as exc:
        raise ModuleNotFoundError(f"madsim.to_sb3 needs the train extra ({exc.name} missing): "
                                  "pip install 'madsim[train]'", name=exc.name) from None
    return GymnasiumToSB3(venv)
