"""`madsim experiment report DIR`: the paper's table with madsim's numbers beside the paper's
(table.md) and one picture (NAME.png: learning curves and the table) from a result folder.

Every cell reads "madsim (paper)"; rows and columns carry the paper's labels in its order.
Averages rows are the mean of madsim's own rows, as the paper's are of its rows. Rates the
paper prints in percent are printed in percent on both sides.
"""

from __future__ import annotations

import csv
import json
import math
import textwrap
from pathlib import Path

from madsim.experiments.registry import PaperTable, experiment

__all__ = ["doc_section", "madsim_table", "markdown_table", "read_results", "write_report"]


def read_results(out: Path) -> dict:
    """(subrun, condition) -> {metric: float} from OUT/results.csv."""
    table = {}
    with open(Path(out) / "results.csv", newline="", encoding="utf-8") as f:
        for row in csv.DictReader(f):
            key = (row.pop("subrun"), row.pop("condition"))
            table[key] = {k: float(v) for k, v in row.items() if v not in ("", None)}
    return table


def madsim_table(table: PaperTable, results: dict) -> dict:
    """(row, column) -> madsim's number (NaN where the run has no figure), averages filled."""
    cells = {}
    for (row, col), (sub, cond, metric) in table.cells.items():
        value = results.get((sub, cond), {}).get(metric, math.nan)
        cells[(row, col)] = value * 100.0 if col in table.percent else value
    for row in table.average_rows:
        for col in table.columns:
            vals = [cells[(r, col)] for r in table.average_of]
            cells[(row, col)] = math.nan if any(math.isnan(v) for v in vals) else sum(vals) / len(vals)
    return cells


def _fmt(value) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    v = float(value)
    if v != 0 and abs(v) < 0.01:
        return f"{v:.4f}"
    return f"{v:.2f}" if abs(v) < 10 else f"{v:.1f}"


def _rows(table: PaperTable, cells: dict) -> list[list[str]]:
    rows = []
    for row in table.rows:
        paper = table.paper.get(row)
        line = [row]
        for j, col in enumerate(table.columns):
            theirs = None if paper is None else paper[j]
            line.append(f"{_fmt(cells[(row, col)])} ({_fmt(theirs)})")
        rows.append(line)
    return rows


def markdown_table(table: PaperTable, cells: dict) -> str:
    """The table in markdown: header = corner + the paper's columns; one line per paper row."""
    head = [table.corner, *table.columns]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(r) + " |" for r in _rows(table, cells)]
    return "\n".join(lines)


def _curves(ax, out: Path, record: dict) -> None:
    from madsim.render.learning_curves import read_csv_columns

    for name in record.get("subruns", {}):
        progress, rllib = out / name / "progress.csv", out / name / "rllib.csv"
        if progress.is_file():
            cols = read_csv_columns(progress)
            x, y = cols.get("time/total_timesteps", []), cols.get("rollout/ep_rew_mean", [])
        elif rllib.is_file():
            cols = read_csv_columns(rllib)
            x, y = cols.get("env_steps", []), cols.get("episode_return_mean", [])
        else:
            continue
        keep = [(a, b) for a, b in zip(x, y) if not (math.isnan(a) or math.isnan(b))]
        if keep:
            ax.plot([a for a, _ in keep], [b for _, b in keep], ".-", label=name)
    from matplotlib.ticker import FuncFormatter

    ax.xaxis.set_major_formatter(FuncFormatter(lambda x, _: f"{x / 1000:g}k"))
    ax.set_xlabel("env steps (of this sub-run)")
    ax.set_ylabel("mean training episode return")
    ax.set_title("learning curves")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    ax.grid(alpha=0.3)


def _picture(path: Path, exp, table: PaperTable, cells: dict, record: dict, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = _rows(table, cells)
    height = max(4.0, 0.28 * len(rows) + 2.0)
    width_table = min(16.0, 2.0 + 1.6 * len(table.columns) + 0.06 * max(len(r[0]) for r in rows))
    fig, (ax_c, ax_t) = plt.subplots(1, 2, figsize=(5 + width_table, height),
                                     gridspec_kw={"width_ratios": [5, width_table]})
    _curves(ax_c, out, record)
    ax_t.axis("off")
    wrapped = [c if len(c) < 22 else c.replace(" ", "\n", 2) for c in table.columns]
    label_w = max(len(r[0]) for r in rows) + 2
    widths = [label_w] + [max(12, max(len(r[j]) for r in rows)) for j in range(1, len(rows[0]))]
    total = float(sum(widths))
    t = ax_t.table(cellText=rows, colLabels=[table.corner, *wrapped], loc="center",
                   cellLoc="center", colWidths=[w / total for w in widths])
    t.auto_set_font_size(False)
    t.set_fontsize(7)
    t.scale(1.0, 1.35)
    for (i, _), cell in t.get_celld().items():
        if i == 0:
            cell.set_height(cell.get_height() * 2.2)
    ax_t.set_title(textwrap.fill(f"madsim (paper): {table.caption}", 90), fontsize=9)
    b = record.get("budget", {})
    fig.suptitle(f"{exp.name}: {exp.title} - budget {b.get('name')}, seed {record.get('seed')}",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_report(out) -> str:
    """Write OUT/table.md and OUT/NAME.png from a result folder; returns the markdown."""
    out = Path(out)
    record_path = out / "experiment.json"
    if not record_path.is_file():
        raise FileNotFoundError(f"{out}: no experiment.json (not a `madsim experiment run` folder)")
    record = json.loads(record_path.read_text(encoding="utf-8"))
    exp = experiment(record["experiment"])
    table = exp.table
    cells = madsim_table(table, read_results(out))
    text = "\n".join([
        f"# {exp.name}: {exp.title}", "",
        f"{table.caption}. Each cell: madsim (paper). Budget `{record['budget']['name']}`, "
        f"seed {record['seed']}, {record['evaluation']['episodes']} evaluation episodes per "
        f"cell" + (f" cut at {record['evaluation']['max_ticks']} ticks"
                   if record["evaluation"].get("max_ticks") else "") + ".", "",
        markdown_table(table, cells), "",
        *[f"- {n}" for n in record.get("notes", [])],
        f"- Reproduce: `{record['command']}`", ""])
    (out / "table.md").write_text(text, encoding="utf-8")
    _picture(out / f"{exp.name}.png", exp, table, cells, record, out)
    return text


def doc_section(out, image: str) -> str:
    """A docs/paper-results.md section for result folder `out`: heading, command, wall time,
    the table and the picture (`image`: its path relative to the doc)."""
    out = Path(out)
    record = json.loads((out / "experiment.json").read_text(encoding="utf-8"))
    exp = experiment(record["experiment"])
    cells = madsim_table(exp.table, read_results(out))
    subs = record["subruns"]
    speed = ", ".join(f"{n} {s['steps_per_s']:.0f}" for n, s in subs.items() if s.get("steps_per_s"))
    return "\n".join([
        f"### {exp.name}: {exp.title}", "",
        f"`{record['command']}` - {record['wall_s'] / 60:.1f} min wall; training env-steps/s: {speed}.",
        "", f"{exp.table.caption}. Each cell: madsim (paper).", "",
        markdown_table(exp.table, cells), "", f"![{exp.name}]({image})", ""])
