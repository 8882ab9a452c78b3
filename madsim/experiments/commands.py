"""`madsim experiment list | run NAME | report DIR`: the handlers (options: madsim.cli_parsers)."""

from __future__ import annotations

__all__ = ["cmd_list", "cmd_report", "cmd_run"]


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
