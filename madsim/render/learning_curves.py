"""Learning curves of a training run folder (`madsim plot DIR`).

Reads DIR/eval.csv (written by `madsim train` at every evaluation) and, when present,
DIR/progress.csv (stable-baselines3's log: `time/total_timesteps`, `rollout/ep_rew_mean`),
and draws four panels against env steps: episode return (training episodes and the
deterministic evaluation), fraction of the lap covered, average speed (km/h) and lap
completion rate. matplotlib's Agg backend: no display needed.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

__all__ = ["plot_learning_curves", "read_csv_columns"]


def read_csv_columns(path: Path) -> dict[str, list[float]]:
    """A CSV of numbers as columns of floats (empty cells: NaN)."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        return {}
    cols: dict[str, list[float]] = {k: [] for k in rows[0]}
    for row in rows:
        for k, column in cols.items():
            v = row.get(k)
            try:
                column.append(float(v) if v not in (None, "") else math.nan)
            except ValueError:
                column.append(math.nan)
    return cols


def _pairs(xs: list[float], ys: list[float]) -> tuple[list[float], list[float]]:
    keep = [(x, y) for x, y in zip(xs, ys) if not (math.isnan(x) or math.isnan(y))]
    return [x for x, _ in keep], [y for _, y in keep]


def plot_learning_curves(run_dir, out_png=None) -> Path:
    """Draw the learning curves of run folder `run_dir` into `out_png` (default
    run_dir/learning_curves.png); returns the path written. FileNotFoundError when the
    folder has no eval.csv, ValueError when it holds no evaluation row."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    run = Path(run_dir)
    eval_csv = run / "eval.csv"
    if not eval_csv.is_file():
        raise FileNotFoundError(f"{run}: no eval.csv (is this a `madsim train` run folder?)")
    ev = read_csv_columns(eval_csv)
    if not ev or not ev.get("timesteps"):
        raise ValueError(f"{eval_csv}: no evaluation rows yet")
    out = Path(out_png) if out_png is not None else run / "learning_curves.png"
    progress = read_csv_columns(run / "progress.csv") if (run / "progress.csv").is_file() else {}

    fig, axes = plt.subplots(2, 2, figsize=(10, 7), sharex=True)
    steps = ev["timesteps"]
    ax = axes[0, 0]
    if "rollout/ep_rew_mean" in progress and "time/total_timesteps" in progress:
        x, y = _pairs(progress["time/total_timesteps"], progress["rollout/ep_rew_mean"])
        ax.plot(x, y, color="0.6", label="training episodes (mean of last 100)")
    ax.plot(steps, ev["mean_return"], "o-", color="C0", label="evaluation (deterministic)")
    ax.set_ylabel("episode return")
    ax.legend(fontsize=8)
    panels = [(axes[0, 1], "lap_fraction", "fraction of lap covered", (0, 1.05)),
              (axes[1, 0], "avg_speed_kmh", "average speed (km/h)", None),
              (axes[1, 1], "completion_rate", "lap completion rate", (0, 1.05))]
    for ax, key, label, ylim in panels:
        ax.plot(steps, ev[key], "o-", color="C1")
        ax.set_ylabel(label)
        if ylim:
            ax.set_ylim(*ylim)
    for ax in axes.flat:
        ax.grid(alpha=0.3)
    from matplotlib.ticker import FuncFormatter

    steps_fmt = FuncFormatter(lambda v, _: f"{v / 1e6:g}M" if abs(v) >= 1e6 else f"{v / 1e3:g}k"
                              if abs(v) >= 1e3 else f"{v:g}")
    for ax in axes[1]:
        ax.set_xlabel("env steps")
        ax.xaxis.set_major_formatter(steps_fmt)
    fig.suptitle(_title(run), fontsize=10)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def _title(run: Path) -> str:
    meta = run / "run.json"
    if not meta.is_file():
        return f"{run.name} (run in progress)"
    try:
        rec = json.loads(meta.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return run.name
    s = rec.get("settings", {})
    return (f"{run.name}: {rec.get('algo', '?').upper()}, {rec.get('timesteps', '?')} steps, "
            f"{s.get('num_envs', '?')} env(s), seed {s.get('seed', '?')}, "
            f"{rec.get('wall_s', '?')} s wall")
