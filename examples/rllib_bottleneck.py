"""Two learners through a bottleneck (the MADRaS paper's Experiment 6 set-up) with PPO on Ray RLlib.

Each car ("first", "second") has its own policy by default (`--policies shared` trains one
network for both). Rollout workers are Ray actors; without `--address` a local Ray instance
is started on this machine, with `--address` the script joins a running Ray cluster (see
docs/training.md: `ray start --head` on one machine, `ray start --address=HEAD:6379` on the
others, then run this script on the head with `--address auto`).

    pip install 'madsim[train,rllib]'
    python examples/rllib_bottleneck.py --iterations 50 --num-env-runners 2 --out runs/bottleneck

Writes OUT/rllib.csv (one row per iteration: env steps, wall time, mean return per agent),
OUT/config.yml, OUT/run.json and OUT/checkpoint (RLlib's `Algorithm.save`).
"""

import argparse
import sys

from madsim.envs.registration import CONFIG_DIR


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--config", default=str(CONFIG_DIR / "bottleneck_two_learners.yml"),
                   help="multi-agent scenario YAML (default: the bundled bottleneck scenario)")
    p.add_argument("--iterations", type=int, default=50)
    p.add_argument("--num-env-runners", type=int, default=2, help="rollout worker processes")
    p.add_argument("--address", default=None,
                   help="Ray cluster to join ('auto' on a cluster node, or ray://HOST:10001); "
                        "default: start a local Ray instance")
    p.add_argument("--policies", choices=["per_agent", "shared"], default="per_agent")
    p.add_argument("--train-batch-size", type=int, default=4000)
    p.add_argument("--minibatch-size", type=int, default=500)
    p.add_argument("--num-epochs", type=int, default=10)
    p.add_argument("--gamma", type=float, default=0.995)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="runs/rllib_bottleneck")
    args = p.parse_args(argv)

    try:
        from madsim.train.rllib import train_rllib
    except ModuleNotFoundError as exc:   # one line, naming the extra to install
        print(f"{p.prog}: error: {exc}", file=sys.stderr)
        return 2

    rows = train_rllib(args.config, args.out, iterations=args.iterations, address=args.address,
                       policies=args.policies, num_env_runners=args.num_env_runners,
                       train_batch_size=args.train_batch_size, minibatch_size=args.minibatch_size,
                       num_epochs=args.num_epochs, gamma=args.gamma, seed=args.seed)
    last = rows[-1]
    print(f"done: {last['env_steps']} env steps in {last['wall_s']:.0f} s; results in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
