"""`madsim train`: the handler (its options: madsim.cli_parsers); torch and stable-baselines3
are imported only when it runs. `madsim plot RUN_DIR` draws a run's learning curves."""

from __future__ import annotations

import sys

__all__ = ["cmd_train"]


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
