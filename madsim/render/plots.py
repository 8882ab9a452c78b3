"""Run plots (matplotlib, files only): trajectories over the track map coloured by speed, and
speed and trackPos against distance, with any number of runs overlaid.

A `Run` is one car's drive as plain arrays, so `madsim run`, an episode log or a serve trace
(`runs_from_trace`) all plot the same way; `plot_traces` does the whole job for trace files.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from madsim.render.trace import check_track, read_trace
from madsim.render.trackmap import _figure, draw_track
from madsim.tracks import Track

SPEED_CMAP = "plasma"


@dataclass(frozen=True)
class Run:
    """One car's drive: x, y (m), speed_kmh, dist_m (distance from the start line along the
    track, growing over laps; negative before the first crossing), track_pos (SCR trackPos:
    +-1 at the road edges, left positive); all (T,)."""

    label: str
    x: np.ndarray
    y: np.ndarray
    speed_kmh: np.ndarray
    dist_m: np.ndarray
    track_pos: np.ndarray


def unwrap_distance(dist_from_start: np.ndarray, track_length: float) -> np.ndarray:
    """distFromStart (wrapping at the track length) as a distance growing over laps, m; a
    start behind the line (first value beyond half a lap) starts negative."""
    d = np.unwrap(np.asarray(dist_from_start, dtype=np.float64), period=track_length)
    if d.size and d[0] > track_length / 2:
        d = d - track_length
    return d


def runs_from_trace(trace, track_length: float, cars=None, prefix: str = "") -> list[Run]:
    """One Run per car (or per listed car row) of a serve Trace."""
    rows = range(trace.n_cars) if cars is None else cars
    runs = []
    for k in rows:
        if not 0 <= k < trace.n_cars:
            raise ValueError(f"{trace.path}: no car {k} (cars 0..{trace.n_cars - 1})")
        runs.append(Run(f"{prefix}car {k}", trace["x"][:, k], trace["y"][:, k], trace["speedX"][:, k],
                        unwrap_distance(trace["distFromStart"][:, k], track_length),
                        trace["trackPos"][:, k]))
    return runs


def plot_runs(track: Track, runs: list[Run], out_path: str | os.PathLike, *, title: str | None = None,
              dpi: int = 120) -> None:
    """Write the figure: map with speed-coloured trajectories (left), speed and trackPos
    against distance (right), one colour per run."""
    if not runs:
        raise ValueError("no runs to plot")
    plt = _figure()
    from matplotlib.collections import LineCollection
    from matplotlib.colors import Normalize

    fig = plt.figure(figsize=(15, 7.5))
    grid = fig.add_gridspec(2, 2, width_ratios=(1.0, 1.15), hspace=0.28, wspace=0.18)
    ax_map = fig.add_subplot(grid[:, 0])
    ax_v = fig.add_subplot(grid[0, 1])
    ax_n = fig.add_subplot(grid[1, 1], sharex=ax_v)
    draw_track(ax_map, track, marks_every_m=500.0)
    vmax = max([float(np.max(r.speed_kmh)) for r in runs if r.speed_kmh.size] + [1.0])
    norm = Normalize(vmin=0.0, vmax=vmax)
    colours = plt.get_cmap("tab10").colors
    line = None
    for i, r in enumerate(runs):
        if r.x.size < 2:
            continue
        pts = np.stack([r.x, r.y], axis=1)
        segs = np.stack([pts[:-1], pts[1:]], axis=1)
        line = LineCollection(segs, cmap=SPEED_CMAP, norm=norm, linewidths=2.2, zorder=6)
        line.set_array((r.speed_kmh[:-1] + r.speed_kmh[1:]) / 2)
        ax_map.add_collection(line)
        c = colours[i % len(colours)]
        ax_map.plot(r.x[0], r.y[0], "o", ms=6, mfc=c, mec="black", zorder=7)
        ax_map.annotate(r.label, (r.x[0], r.y[0]), xytext=(6, -12 - 11 * i), textcoords="offset points",
                        fontsize=8, color=c, zorder=8,
                        bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": c, "alpha": 0.85})
        ax_v.plot(r.dist_m, r.speed_kmh, color=c, lw=1.2, label=r.label)
        ax_n.plot(r.dist_m, r.track_pos, color=c, lw=1.2, label=r.label)
    if line is not None:
        fig.colorbar(line, ax=ax_map, shrink=0.7, pad=0.02, label="speed (km/h)")
    ax_map.set_title(title or f"{track.name}: {len(runs)} run(s)")
    far = max([float(np.max(r.dist_m)) for r in runs if r.dist_m.size] + [0.0])
    for d in np.arange(0.0, far + 1.0, track.length):
        for ax in (ax_v, ax_n):
            ax.axvline(d, color="0.6", lw=0.8, ls=":")
    ax_v.set_ylabel("speed (km/h)")
    ax_v.set_title("speed and track position against distance (dotted: start line)")
    ax_v.grid(alpha=0.3)
    ax_v.legend(fontsize=8, loc="lower right")
    for edge in (-1.0, 1.0):
        ax_n.axhline(edge, color="#30343b", lw=1.0)
    ax_n.axhline(0.0, color="0.6", lw=0.8, ls="--")
    ax_n.set_ylabel("trackPos (+1 left edge, -1 right)")
    ax_n.set_xlabel("distance from the start line (m)")
    ax_n.grid(alpha=0.3)
    fig.savefig(out_path, dpi=dpi, bbox_inches="tight")
    plt.close(fig)


def plot_traces(paths, out_png: str | os.PathLike, *, track: str = "madsim-road", cars=None,
                labels=None, title: str | None = None, dpi: int = 120) -> int:
    """Plot serve traces (one or several files, overlaid) into `out_png`; cars: rows to show
    (default all); labels: one name per file (default the file stems). Returns the run count."""
    from pathlib import Path

    from madsim.tracks import load_track

    paths = [paths] if isinstance(paths, (str, os.PathLike)) else list(paths)
    if labels is not None and len(labels) != len(paths):
        raise ValueError(f"{len(labels)} labels for {len(paths)} trace files")
    tr = load_track(track)
    runs: list[Run] = []
    for i, p in enumerate(paths):
        trace = read_trace(p)
        check_track(trace, tr)
        name = labels[i] if labels is not None else Path(p).stem
        runs += runs_from_trace(trace, tr.length, cars, prefix=f"{name}: " if len(paths) > 1 or labels else "")
    plot_runs(tr, runs, out_png, title=title, dpi=dpi)
    return len(runs)
