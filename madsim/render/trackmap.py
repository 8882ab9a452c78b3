"""Track map pictures (matplotlib, files only, no window)."""

from __future__ import annotations

import os

import numpy as np

from madsim.tracks import Track


def _figure():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def draw_track(ax, track: Track, *, marks_every_m: float = 500.0, label: bool = True) -> None:
    """Draw road surface, edges, barriers, pit walls, start line, direction and distance marks on
    `ax`."""
    left, right = track.edge_polyline("left"), track.edge_polyline("right")
    bl, br = track.barrier_polyline("left"), track.barrier_polyline("right")
    road = np.concatenate([left, right[::-1]])
    ax.fill(road[:, 0], road[:, 1], color="#b9bcc2", lw=0, zorder=1)
    for edge in (left, right):
        closed = np.vstack([edge, edge[:1]])
        ax.plot(closed[:, 0], closed[:, 1], color="#30343b", lw=0.8, zorder=2)
    for barrier in (bl, br):
        closed = np.vstack([barrier, barrier[:1]])
        ax.plot(closed[:, 0], closed[:, 1], color="#c0392b", lw=0.6, alpha=0.7, zorder=2)
    walls = track.pit_wall_quads()[0]          # solid pit walls, as the contact solver sees them
    if walls.shape[0]:
        from matplotlib.collections import PolyCollection

        ax.add_collection(PolyCollection(walls, facecolors="#c0392b", edgecolors="#c0392b",
                                         linewidths=0.3, zorder=3))
    # start line across the road, and an arrow along the driving direction
    x0, y0, _, h0 = (float(v) for v in track.pose(0.0, 0.0))
    half = track.width / 2
    nx, ny = -np.sin(h0), np.cos(h0)
    ax.plot([x0 - half * nx, x0 + half * nx], [y0 - half * ny, y0 + half * ny], color="black", lw=2.5, zorder=4)
    span = max(np.ptp(track.x), np.ptp(track.y))
    ax.annotate("", xy=(x0 + 0.06 * span * np.cos(h0), y0 + 0.06 * span * np.sin(h0)), xytext=(x0, y0),
                arrowprops=dict(arrowstyle="-|>", color="#1f6feb", lw=2), zorder=5)
    if label:
        ax.text(x0, y0, "  start", fontsize=8, ha="left", va="bottom", zorder=5)
    if marks_every_m > 0:
        for d in np.arange(marks_every_m, track.length - 0.1 * marks_every_m, marks_every_m):
            x, y, _, h = (float(v) for v in track.pose(d, 0.0))
            off = track.width * 3.0
            ax.plot([x], [y], marker="o", ms=2.5, color="#1f6feb", zorder=9)
            # above anything drawn over the road (trajectories), on a white patch: always legible
            ax.text(x - off * np.sin(h), y + off * np.cos(h), f"{d:.0f} m", fontsize=7, ha="center",
                    va="center", color="#1f4f9b", zorder=9,
                    bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.8})
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")


def save_track_map(track: Track, path: str | os.PathLike, *, marks_every_m: float = 500.0,
                   dpi: int = 150) -> None:
    """Write a PNG (or any matplotlib format) map of `track` to `path`."""
    plt = _figure()
    fig, ax = plt.subplots(figsize=(8, 8))
    draw_track(ax, track, marks_every_m=marks_every_m)
    label = track.name if track.title in ("", track.name) else f"{track.title} [{track.name}]"
    ax.set_title(f"{label} ({track.category}) - {track.length:.2f} m, width {track.width:g} m")
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
