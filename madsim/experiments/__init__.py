"""The MADRaS paper's six experiments on madsim: scenario YAML (package data in
`madsim/experiments/scenarios/`), the runner (train, evaluate as the paper does, write a
result folder), and the report (the paper's tables with madsim's numbers beside them).

    madsim experiment list
    madsim experiment run exp1 --budget smoke|short|medium|full [--out DIR] [--seed S] [--address ADDR]
    madsim experiment report DIR

Training needs the `train` extra (exp1-exp5) and the `rllib` extra (exp6); nothing heavy is
imported by this package. See docs/paper-results.md.
"""

from madsim.experiments.registry import BUDGETS, EXPERIMENTS, experiment
from madsim.experiments.report import write_report
from madsim.experiments.runner import run_experiment

__all__ = ["BUDGETS", "EXPERIMENTS", "experiment", "run_experiment", "write_report"]
