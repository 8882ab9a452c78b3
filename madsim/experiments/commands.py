"""`madsim experiment list | run NAME | report DIR`: parser and handlers for madsim's CLI."""

from __future__ import annotations

__all__ = ["add_parser"]


def cmd_list(args) -> int:
    from madsim.experiments.registry import BUDGETS, EXPERIMENTS

    for exp in EXPERIMENTS.values():
        subs = ", ".join(s.name for s in exp.subruns)
        print(f"{exp.name:5s} {exp.title}")
        print(f"      sub-runs: {subs}; {len(exp.conditions)} evaluation condition(s); "
              f"trainer {exp.trainer}")
    print("budgets: " + ", ".join(BUDGETS) + "  (sub-run selection: e.g. exp1-sab, exp3-alpine-1)")
    return 0


def cmd_run(args) -> int:
    from madsim.experiments.runner import run_experiment

    out = args.out or f"runs/{args.name}-{args.budget}-seed{args.seed}"
    record = run_experiment(args.name, budget=args.budget, out=out, seed=args.seed,
                            address=args.address)
    print((__import__("pathlib").Path(out) / "table.md").read_text(encoding="utf-8"))
    print(f"madsim experiment: {args.name} at {args.budget} in {record['wall_s']} s; results in {out}")
    return 0


def cmd_report(args) -> int:
    from madsim.experiments.report import write_report

    print(write_report(args.dir))
    return 0


def add_parser(sub) -> None:
    """Add `experiment` (list, run, report) to an argparse subparsers object."""
    e = sub.add_parser("experiment", help="the MADRaS paper's six experiments: list, run, report")
    esub = e.add_subparsers(dest="experiment_command", required=True)
    esub.add_parser("list", help="the experiments, their sub-runs and the budgets").set_defaults(func=cmd_list)
    r = esub.add_parser("run", help="train, evaluate over 100 episodes, write a result folder")
    r.add_argument("name", help="exp1..exp6, or a sub-run such as exp1-sab, exp1-ts, exp2-random")
    r.add_argument("--budget", choices=["smoke", "short", "full"], default="smoke")
    r.add_argument("--out", default=None, help="result folder (default runs/NAME-BUDGET-seedS)")
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--address", default=None,
                   help="Ray cluster for exp6's RLlib training ('auto' or ray://HOST:10001)")
    r.set_defaults(func=cmd_run)
    p = esub.add_parser("report", help="rewrite table.md and the picture of a result folder")
    p.add_argument("dir")
    p.set_defaults(func=cmd_report)
