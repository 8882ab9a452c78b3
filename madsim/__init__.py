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
