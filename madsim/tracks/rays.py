"""Exact rangefinder rays to the road edges (the SCR `track` and `focus` sensors).

The ray is walked through *runs* of the centre line: consecutive pieces with the same geometry
(one straight line, or one circle arc of the same radius and centre) merged, so a 200 m straight
is one step however finely TORCS cut it. Inside a run the road edges are a pair of lines or
concentric circles, so every intersection is closed form; no sampling, no distance field.
Only the main road edges count (sides, barriers, cars and elevation are ignored, as in SCR).

Runs are a (R, RUN_COLS) float64 array; `piece_run` maps piece index -> run index.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from madsim.tracks.build import COL, STRAIGHT
from madsim.tracks.kernels import piece_at

RUN_KIND, RUN_X0, RUN_Y0, RUN_A0, RUN_LEN, RUN_R, RUN_CX, RUN_CY, RUN_ARC = range(9)
RUN_C0, RUN_S0, RUN_C1, RUN_S1 = range(9, 13)
"""Directions precomputed once per run (numpy's cos/sin; a ray crosses several runs, 19 rays
per car per tick): a straight's (cos a0, sin a0) in C0, S0; an arc's radial unit vectors at its
start (theta0 of `_arc_frame`) in C0, S0 and at its end (theta0 + sense arc) in C1, S1."""
RUN_COLS = 13
_SAME_TOL = 1e-6


def build_runs(pieces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge consecutive pieces of identical geometry into runs; returns (runs, piece_run)."""
    runs: list[list[float]] = []
    piece_run = np.empty(len(pieces), dtype=np.int64)
    for i, p in enumerate(pieces):
        kind = p[COL["kind"]]
        if runs:
            r = runs[-1]
            same = r[RUN_KIND] == kind and (
                (kind == STRAIGHT and abs(_wrap(p[COL["a0"]] - r[RUN_A0])) < _SAME_TOL) or
                (kind != STRAIGHT and abs(p[COL["radius"]] - r[RUN_R]) < _SAME_TOL * max(1.0, r[RUN_R])
                 and math.hypot(p[COL["cx"]] - r[RUN_CX], p[COL["cy"]] - r[RUN_CY]) < 1e-4
                 and r[RUN_ARC] + p[COL["arc"]] < math.pi))
            if same:
                r[RUN_LEN] += p[COL["length"]]
                r[RUN_ARC] += p[COL["arc"]]
                piece_run[i] = len(runs) - 1
                continue
        runs.append([kind, p[COL["x0"]], p[COL["y0"]], p[COL["a0"]], p[COL["length"]], p[COL["radius"]],
                     p[COL["cx"]], p[COL["cy"]], p[COL["arc"]]])
        piece_run[i] = len(runs) - 1
    table = np.zeros((len(runs), RUN_COLS))
    table[:, :RUN_C0] = np.array(runs, dtype=np.float64).reshape(len(runs), RUN_C0)
    kind, a0 = table[:, RUN_KIND], table[:, RUN_A0]
    left = kind == 1.0
    theta0 = np.where(left, a0 - math.pi / 2.0, a0 + math.pi / 2.0)    # as _arc_frame
    theta1 = theta0 + np.where(left, 1.0, -1.0) * table[:, RUN_ARC]
    start = np.where(kind == STRAIGHT, a0, theta0)
    table[:, RUN_C0], table[:, RUN_S0] = np.cos(start), np.sin(start)
    table[:, RUN_C1], table[:, RUN_S1] = np.cos(theta1), np.sin(theta1)
    return table, piece_run


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


@numba.njit(cache=True, inline="always")
def _wrapn(a):
    return a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))


@numba.njit(cache=True)
def _arc_frame(runs, j):
    """(theta0, sense): radial angle of the run start and +1 (left) / -1 (right) turn sense."""
    if runs[j, RUN_KIND] == 1.0:
        return runs[j, RUN_A0] - math.pi / 2.0, 1.0
    return runs[j, RUN_A0] + math.pi / 2.0, -1.0


@numba.njit(cache=True)
def _arc_q(runs, j, x, y):
    """Angular position of (x, y) along arc run j, 0 at its start, in (-pi, pi] around the span."""
    theta0, sense = _arc_frame(runs, j)
    d = runs[j, RUN_ARC]
    phi = math.atan2(y - runs[j, RUN_CY], x - runs[j, RUN_CX])
    return d / 2.0 + _wrapn(sense * (phi - theta0) - d / 2.0)


ON_ARC_MARGIN = 1e-9
"""rad: `_on_arc` decides without atan2 only this far from the arc's ends (atan2 and the
cross products err by ~1e-15 rad; `_arc_q`'s own tolerance is 1e-12)."""


@numba.njit(cache=True, inline="always")
def _on_arc(runs, j, px, py, radius, sense, d):
    """Whether the point (px, py) from the centre of arc run j (on the circle of `radius`) lies
    within its span, as `-1e-12 <= _arc_q <= d + 1e-12` decides: 1 or 0 from two cross
    products with the radial unit vectors at its ends when the point is over ON_ARC_MARGIN
    from both, else -1 (ask `_arc_q`; also for arcs of 3 rad or more, where the half-plane
    test would not be enough)."""
    if d >= 3.0:
        return -1
    margin = ON_ARC_MARGIN * radius
    after_start = sense * (runs[j, RUN_C0] * py - runs[j, RUN_S0] * px)    # |P| sin(angle from start)
    before_end = sense * (px * runs[j, RUN_S1] - py * runs[j, RUN_C1])     # |P| sin(angle to end)
    if after_start > margin and before_end > margin:
        return 1
    if after_start < -margin or before_end < -margin:
        return 0
    return -1


@numba.njit(cache=True, _nrt=False)   # allocates nothing: no reference counts (kernel.NO_REFCOUNT)
def cast_ray(runs, half_width, j, px, py, dx, dy, max_range):
    """Distance along unit direction (dx, dy) from (px, py), inside run j, to the first road
    edge crossing, walking from run to run; max_range if none closer."""
    nruns = runs.shape[0]
    t = 0.0
    entered = 0  # 0: start point, +1: entered through the run's start line, -1: through its end
    for _ in range(4 * nruns + 8):
        best = max_range
        event = 0  # 0 edge hit / none, +1 leave through the end, -1 leave through the start
        ox = px + t * dx
        oy = py + t * dy
        if runs[j, RUN_KIND] == 0.0:
            c, s = runs[j, RUN_C0], runs[j, RUN_S0]
            rx, ry = ox - runs[j, RUN_X0], oy - runs[j, RUN_Y0]
            q0 = rx * c + ry * s
            n0 = -rx * s + ry * c
            dq = dx * c + dy * s
            dn = -dx * s + dy * c
            length = runs[j, RUN_LEN]
            if dn != 0.0:
                for side in (-1.0, 1.0):
                    tau = (side * half_width - n0) / dn
                    if 1e-12 < tau < best - t:
                        q = q0 + tau * dq
                        if -1e-9 <= q <= length + 1e-9:
                            best = t + tau
                            event = 0
            if dq > 0.0 and entered != -1:
                tau = (length - q0) / dq
                if -1e-9 <= tau and t + tau < best:
                    best = t + tau
                    event = 1
            elif dq < 0.0 and entered != 1:
                tau = -q0 / dq
                if -1e-9 <= tau and t + tau < best:
                    best = t + tau
                    event = -1
        else:
            cx, cy, r = runs[j, RUN_CX], runs[j, RUN_CY], runs[j, RUN_R]
            d = runs[j, RUN_ARC]
            sense = _arc_frame(runs, j)[1]
            rx, ry = ox - cx, oy - cy
            b = dx * rx + dy * ry
            cc = rx * rx + ry * ry
            for radius in (r - half_width, r + half_width):
                if radius <= 0.0:
                    continue
                disc = b * b - (cc - radius * radius)
                if disc < 0.0:
                    continue
                sq = math.sqrt(disc)
                for tau in (-b - sq, -b + sq):
                    if 1e-12 < tau < best - t:
                        hx, hy = ox + tau * dx, oy + tau * dy
                        on = _on_arc(runs, j, hx - cx, hy - cy, radius, sense, d)
                        if on < 0:
                            q = _arc_q(runs, j, hx, hy)
                            on = 1 if -1e-12 <= q <= d + 1e-12 else 0
                        if on == 1:
                            best = t + tau
                            event = 0
            # radial boundary lines: start (angle theta0) and end (theta0 + sense * d)
            for which in (1, -1):
                if (which == 1 and entered == -1) or (which == -1 and entered == 1):
                    continue
                if which == 1:      # the end line (angle theta0 + sense d)
                    ux, uy = runs[j, RUN_C1], runs[j, RUN_S1]
                else:
                    ux, uy = runs[j, RUN_C0], runs[j, RUN_S0]
                den = dx * uy - dy * ux
                if den == 0.0:
                    continue
                tau = -(rx * uy - ry * ux) / den
                if tau < -1e-9 or t + tau >= best:
                    continue
                hx, hy = rx + tau * dx, ry + tau * dy
                along = hx * ux + hy * uy  # must be on the ray from the centre, inside the band
                if r - half_width - 1e-9 <= along <= r + half_width + 1e-9:
                    # crossing counts only when moving across the line in its own direction
                    moving = (dx * -uy + dy * ux) * sense  # velocity along the turning direction
                    if (which == 1 and moving > 0.0) or (which == -1 and moving < 0.0):
                        best = t + tau
                        event = which
        if event == 0 or best >= max_range:
            return min(best, max_range)
        t = best
        if event == 1:
            j = j + 1 if j < nruns - 1 else 0
            entered = 1
        else:
            j = j - 1 if j > 0 else nruns - 1
            entered = -1
    return max_range


@numba.njit(cache=True)
def rangefinders(geo, length, runs, piece_run, half_width, s, px, py, yaw, angles_rad, max_range, out):
    """Rays for many cars: out[k, a] = distance from car k at (px, py), located at s[k] (m), along
    yaw - angles[a] (SCR angles, positive clockwise) to the road edge, walked from the run of
    the piece at s[k] (`kernels.piece_at`, as the focus sensor); caller handles the
    |trackPos| > 1 sentinel."""
    for k in range(px.shape[0]):
        run = piece_run[piece_at(geo, length, s[k])]
        for a in range(angles_rad.shape[0]):
            h = yaw[k] - angles_rad[a]
            out[k, a] = cast_ray(runs, half_width, run, px[k], py[k], math.cos(h), math.sin(h), max_range)
