"""madsim: a pure-Python, TORCS-like driving simulator for reinforcement learning."""

__version__ = "0.1.0"

from madsim.envs.registration import register_envs as _register_envs

_register_envs()
