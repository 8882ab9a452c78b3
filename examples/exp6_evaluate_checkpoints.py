"""Evaluate the policies an Experiment 6 run kept along the way (checkpoint-NNNN/, budget
`medium`) and at its end (checkpoint/), as the experiment evaluates its final pair
(madsim.experiments.evaluate.evaluate_pair at the evaluated curriculum stage: 100 episodes,
seeds 1,000,000 + k, joint passage 5 m beyond the farthest parking spot with no collision
before it). Prints per checkpoint: the joint passage rate, each learner's pass rate, how the
episodes ended and the median step of the collisions.

    PYTHONPATH=. python examples/exp6_evaluate_checkpoints.py runs/exp6-medium-seed0
    PYTHONPATH=. python examples/exp6_evaluate_checkpoints.py OUT --stochastic 0  # sampled actions

`--stochastic SEED` draws each action from the policy's Gaussian (numpy Generator seeded
SEED) instead of taking its mean, as MADRaS evaluated (`rllib rollout`, whose compute_action
explores by default) and as the experiment's table does (seeded with the run's seed).
"""

from __future__ import annotations

import argparse
import collections
import statistics
import time
from pathlib import Path

import numpy as np
from madsim.experiments.evaluate import evaluate_pair
from madsim.experiments.registry import experiment
from madsim.experiments.runner import load_scenario, rllib_policies


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", type=Path, help="the run's result folder (madsim experiment run --out)")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--stochastic", type=int, default=None, metavar="SEED",
                        help="sample actions with this seed (default: the Gaussian's mean)")
    parser.add_argument("--only", nargs="+", default=None, metavar="FOLDER",
                        help="these checkpoint folders only (e.g. checkpoint-0050 checkpoint)")
    args = parser.parse_args()
    exp = experiment("exp6")
    sub = exp.subruns[0]
    condition = exp.conditions[0]
    run_dir = args.out / sub.name
    folders = args.only or sorted(p.name for p in run_dir.glob("checkpoint-*")) + ["checkpoint"]
    cfg = load_scenario(sub)
    ecfg = load_scenario(sub, condition.overrides)
    names = [a["name"] for a in cfg["agents"]]
    mode = "mean action" if args.stochastic is None else f"sampled actions (seed {args.stochastic})"
    print(f"{args.out}: {condition.name}, {args.episodes} episodes, {mode}")
    for folder in folders:
        if not (run_dir / folder).is_dir():
            continue
        rng = None if args.stochastic is None else np.random.default_rng(args.stochastic)
        t0 = time.time()
        policies = rllib_policies(run_dir, cfg, folder, rng=rng)
        summary, per = evaluate_pair(policies, ecfg, episodes=args.episodes)
        ends = collections.Counter("+".join(sorted({d for a in names for d in e[f"{a}_dones"]}))
                                   for e in per)
        crash_steps = [max(e[f"{a}_steps"] for a in names) for e in per
                       if any("Collision" in e[f"{a}_dones"] for a in names)]
        passes = ", ".join(f"{a} passes {100 * summary[f'{a}_pass_rate']:.0f} %" for a in names)
        median = f"{statistics.median(crash_steps):.0f}" if crash_steps else "-"
        print(f"{folder:16s} joint {100 * summary['joint_success_rate']:5.1f} %; {passes}; "
              f"collision step median {median}; ends {dict(ends)} ({time.time() - t0:.0f} s)")


if __name__ == "__main__":
    main()
