"""`madsim train` and `madsim plot`: argument parsers and handlers for madsim's CLI.

`madsim/cli.py` calls `add_parsers(sub)` with its subparsers object; nothing heavy is imported
until a command runs. `python -m madsim.train.commands train ...` runs them directly too.
"""

from __future__ import annotations

import argparse
import sys

__all__ = ["add_parsers", "cmd_plot", "cmd_train", "main"]


def cmd_train(args) -> int:
    from madsim.interrupts import StopRequest, exit_now
    from madsim.train.evaluate import format_table
    from madsim.train.sb3 import TrainSettings, train

    settings = TrainSettings(algo=args.algo, steps=args.steps, num_envs=args.num_envs,
                             seed=args.seed, eval_every=args.eval_every,
                             eval_episodes=args.eval_episodes, n_steps=args.n_steps,
                             gamma=args.gamma, ent_coef=args.ent_coef,
                             progress=not args.no_progress,
                             native_vec={"auto": None, "native": True, "sync": False}[args.vec])
    with StopRequest(grace_s=0.5) as stop:   # a step held up (e.g. compiling) is interrupted after 0.5 s
        record = train(args.config, args.out, settings, overwrite=args.overwrite, stop=stop)
    if stop:
        print(f"madsim train: interrupted by {stop.signal_name} after {record['timesteps']} steps; "
              f"saved {args.out}/policy.zip", file=sys.stderr, flush=True)
        exit_now(stop.exit_status)      # every file is closed: skip torch's slow teardown
        return stop.exit_status
    print(f"madsim train: {record['timesteps']} steps in {record['wall_s']} s "
          f"({record['steps_per_s']} steps/s); policy: {args.out}/policy.zip")
    print(format_table([record["final_eval"]]))
    return 0


def cmd_plot(args) -> int:
    from madsim.render.learning_curves import plot_learning_curves

    out = plot_learning_curves(args.run_dir, args.output)
    print(f"wrote {out}")
    return 0


def add_parsers(sub, *, with_plot: bool = True) -> None:
    """Add the `train` (and, unless the caller has its own, `plot`) subcommands to an argparse
    subparsers object; the madsim CLI's `plot` (madsim.render.commands) handles run folders."""
    t = sub.add_parser("train", help="train a policy with PPO (extra [train]: torch, stable-baselines3)")
    t.add_argument("config", help="scenario YAML with one learning agent (e.g. examples/ts_single_lap.yml)")
    t.add_argument("--algo", choices=["ppo"], default="ppo")
    t.add_argument("--steps", type=int, required=True, help="env steps to train, over all envs")
    t.add_argument("--out", required=True, help="run folder: policy.zip, CSV logs, checkpoints, config")
    t.add_argument("--num-envs", type=int, default=1, help="episodes stepped side by side")
    t.add_argument("--seed", type=int, default=0)
    t.add_argument("--eval-every", type=int, default=None,
                   help="env steps between evaluations (default: steps / 10)")
    t.add_argument("--eval-episodes", type=int, default=3)
    t.add_argument("--n-steps", type=int, default=None,
                   help="PPO rollout length per env (default 2048 / num-envs)")
    t.add_argument("--gamma", type=float, default=0.99, help="discount per env step")
    t.add_argument("--ent-coef", type=float, default=0.0, help="PPO entropy bonus")
    t.add_argument("--vec", choices=["auto", "native", "sync"], default="auto",
                   help="vector env: madsim's batched make_vec (native), gymnasium's SyncVectorEnv "
                        "of MadrasEnv (sync), or native when installed (auto)")
    t.add_argument("--overwrite", action="store_true", help="reuse an --out folder holding a run")
    t.add_argument("--no-progress", action="store_true", help="no progress bar")
    t.add_argument("--import", dest="imports", action="append", default=[], metavar="MODULE",
                   help="import this module or .py file first (registers your rewards, dones, "
                        "traffic behaviours); repeatable; or list them under `plugins:` in the YAML")
    t.set_defaults(func=cmd_train)

    if not with_plot:
        return
    p = sub.add_parser("plot", help="draw the learning curves of a `madsim train` run folder")
    p.add_argument("run_dir")
    p.add_argument("-o", "--output", default=None, help="PNG file (default RUN_DIR/learning_curves.png)")
    p.set_defaults(func=cmd_plot)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m madsim.train.commands")
    add_parsers(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    try:
        if getattr(args, "imports", None):
            from madsim.plugins import import_plugins

            import_plugins(args.imports)
        return int(args.func(args) or 0)
    except (ValueError, OSError) as exc:
        print(f"madsim: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
