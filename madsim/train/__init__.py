"""Training drivers for madsim: PPO with stable-baselines3 (`madsim train`), multi-agent PPO on
Ray RLlib, evaluation with MADRaS's figures, learning-curve plots.

Nothing heavy is imported here: torch and stable-baselines3 (extra `train`) load in
`madsim.train.sb3` and `madsim.train.vec`, Ray (extra `rllib`) in `madsim.train.rllib`.
"""

__all__ = ["TrainSettings", "evaluate_policy", "load_policy", "plot_learning_curves", "train"]

_WHERE = {"TrainSettings": "madsim.train.sb3", "load_policy": "madsim.train.sb3",
          "train": "madsim.train.sb3", "evaluate_policy": "madsim.train.evaluate",
          "plot_learning_curves": "madsim.render.learning_curves"}


def __getattr__(name: str):
    if name in _WHERE:
        import importlib

        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module 'madsim.train' has no attribute {name!r}")
