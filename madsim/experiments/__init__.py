"""The MADRaS paper's six experiments on madsim: scenario YAML (package data in
`madsim/experiments/scenarios/`), the runner (train, evaluate as the paper does, write a
result folder), and the report (the paper's tables with madsim's numbers beside them).

    madsim experiment list
    madsim experiment run exp1 --budget smoke|short|full [--out DIR] [--seed S] [--address ADDR]
    madsim experiment report DIR

Training needs the `train` extra (exp1-exp5) and the `rllib` extra (exp6); nothing heavy is
imported here. See docs/paper-results.md.
"""

__all__ = ["BUDGETS", "EXPERIMENTS", "experiment", "run_experiment", "write_report"]

_WHERE = {"BUDGETS": "madsim.experiments.registry", "EXPERIMENTS": "madsim.experiments.registry",
          "experiment": "madsim.experiments.registry", "run_experiment": "madsim.experiments.runner",
          "write_report": "madsim.experiments.report"}


def __getattr__(name: str):
    if name in _WHERE:
        import importlib

        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module 'madsim.experiments' has no attribute {name!r}")
