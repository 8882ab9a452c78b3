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


STILL_M = 5.0   # a run that covers less distance than this is drawn as a marker (a parked car)


def plot_runs(track: Track, runs: list[Run], out_path: str | os.PathLike, *, title: str | None = None,
              dpi: int = 120) -> None:
    """Write the figure: the map with the trajectories (left), speed and trackPos against
    distance (right). One run: its trajectory is coloured by speed (with a colour bar); several:
    each run has its own colour in all three panels, so whose speed is whose can be read on the
    right. A run that barely moves (a parked car) is drawn as a square marker."""
    if not runs:
        raise ValueError("no runs to plot")
    plt = _figure()
    from matplotlib.collections import LineCollection
    from matplotlib.colors import Normalize

    fig = plt.figure(figsize=(15, 7.5))
    grid = fig.add_gridspec(2, 2, width_ratios=(1.0, 1.15), hspace=0.28, wspace=0.22)
    ax_map = fig.add_subplot(grid[:, 0])
    ax_v = fig.add_subplot(grid[0, 1])
    ax_n = fig.add_subplot(grid[1, 1], sharex=ax_v)
    draw_track(ax_map, track, marks_every_m=500.0)
    colours = plt.get_cmap("tab10").colors
    by_speed = len(runs) == 1
    xmin, xmax = ax_map.get_xlim()
    line = None
    for i, r in enumerate(runs):
        if r.x.size == 0:
            continue
        c = colours[i % len(colours)]
        still = r.dist_m.size < 2 or float(np.ptp(r.dist_m)) < STILL_M
        if still:
            ax_map.plot(r.x[0], r.y[0], "s", ms=7, mfc=c, mec="black", zorder=7)
        elif by_speed:
            pts = np.stack([r.x, r.y], axis=1)
            segs = np.stack([pts[:-1], pts[1:]], axis=1)
            norm = Normalize(vmin=0.0, vmax=max(float(np.max(r.speed_kmh)), 1.0))
            line = LineCollection(segs, cmap=SPEED_CMAP, norm=norm, linewidths=2.2, zorder=6)
            line.set_array((r.speed_kmh[:-1] + r.speed_kmh[1:]) / 2)
            ax_map.add_collection(line)
        else:
            ax_map.plot(r.x, r.y, color=c, lw=1.6, alpha=0.9, zorder=6)
        if not still:
            ax_map.plot(r.x[0], r.y[0], "o", ms=6, mfc=c, mec="black", zorder=7)
        # labels point into the map (away from the nearer side edge), clipped to the axes
        inward = r.x[0] > (xmin + xmax) / 2
        ax_map.annotate(r.label, (r.x[0], r.y[0]), xytext=(-8 if inward else 8, -12 - 11 * (i % 3)),
                        textcoords="offset points", ha="right" if inward else "left", fontsize=8, color=c,
                        zorder=8, annotation_clip=True,
                        bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": c, "alpha": 0.85})
        style = {"color": c, "label": r.label}
        if still:
            ax_v.plot(r.dist_m[:1], r.speed_kmh[:1], "s", ms=6, mec="black", **style)
            ax_n.plot(r.dist_m[:1], r.track_pos[:1], "s", ms=6, mec="black", **style)
        else:
            ax_v.plot(r.dist_m, r.speed_kmh, lw=1.2, **style)
            ax_n.plot(r.dist_m, r.track_pos, lw=1.2, **style)
    if line is not None:
        fig.colorbar(line, ax=ax_map, shrink=0.6, pad=0.08, location="bottom", label="speed (km/h)")
    ax_map.set_title(title or f"{track.name}: {len(runs)} car{'s' if len(runs) != 1 else ''}")
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
