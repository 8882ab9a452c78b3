"""Scenario config, the gymnasium and PettingZoo envs and their backends.

`MadrasEnv`, `MadrasParallelEnv`, `LocalBackend`, `ScrBackend` are importable from here; they
load on first use, so `madsim.envs.config` stays light.
"""

__all__ = ["LocalBackend", "MadrasEnv", "MadrasParallelEnv", "ScrBackend", "register_envs"]

_WHERE = {"MadrasEnv": "madsim.envs.madras_env", "MadrasParallelEnv": "madsim.envs.parallel_env",
          "LocalBackend": "madsim.envs.backends", "ScrBackend": "madsim.envs.backends",
          "register_envs": "madsim.envs.registration"}


def __getattr__(name: str):
    if name in _WHERE:
        import importlib

        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module 'madsim.envs' has no attribute {name!r}")
