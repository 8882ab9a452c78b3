"""Compiled track queries: point -> (s, n) on the piece geometry.

Pieces are passed as a (P, N_GEO) float64 array `geo` with columns GEO_* below (or any table
that starts with them: the physics kernels' piece table, `physics.layout.PIECE_COLUMNS`, so the
car kernel, the contact kernels and the track's own queries share one piece walk, `locate`).
All kernels are plain loops compiled with numba (cache=True) and also run as ordinary Python
for debugging.
"""

from __future__ import annotations

import math

import numba
import numpy as np

GEO_COLUMNS = ("kind", "s0", "length", "radius", "arc", "x0", "y0", "a0", "cx", "cy", "cos_a0", "sin_a0")
"""kind 0 straight / 1 left / 2 right; s0 (m from the start line), length (m, along the centre
line), radius (m) and arc (rad) of a curve; x0, y0 (m) and heading a0 (rad) at the piece start;
cx, cy (m) the curve's centre; cos a0 and sin a0 (numpy's, computed once)."""
(GEO_KIND, GEO_S0, GEO_LEN, GEO_R, GEO_ARC, GEO_X0, GEO_Y0, GEO_A0, GEO_CX, GEO_CY, GEO_CA0,
 GEO_SA0) = range(len(GEO_COLUMNS))
N_GEO = len(GEO_COLUMNS)

_JIT = {"cache": True, "error_model": "numpy"}


@numba.njit(inline="always", **_JIT)
def wrap_angle(a):
    """Radians wrapped into [-pi, pi) (np.floor: a float, no round trip through an integer)."""
    return a - 2.0 * math.pi * np.floor((a + math.pi) / (2.0 * math.pi))


@numba.njit(inline="always", **_JIT)
def piece_at(geo, length, s):
    """The piece holding distance s (m, any real): the last piece whose start GEO_S0 is at most
    s wrapped into [0, L), clipped to the table (a NaN s gives the last piece); numpy's
    searchsorted(side="right") - 1, as one binary search. The one piece lookup of the track
    (`Track.piece_at`), the rays and the focus sensor."""
    s = s % length
    npieces = geo.shape[0]
    if s != s:
        return npieces - 1
    lo, hi = 0, npieces               # the first piece starting after s
    while lo < hi:
        mid = (lo + hi) // 2
        if geo[mid, GEO_S0] <= s:
            lo = mid + 1
        else:
            hi = mid
    return min(max(lo - 1, 0), npieces - 1)


@numba.njit(**_JIT)
def pieces_at(geo, length, s, out):
    """out[k] = piece_at(geo, length, s[k]) for s (K,) float64, out (K,) int64."""
    for k in range(s.shape[0]):
        out[k] = piece_at(geo, length, s[k])


@numba.njit(inline="always", **_JIT)
def piece_local(geo, p, x, y):
    """(q, n, cos h, sin h) of point (x, y) in piece p: centre-line distance from the piece start
    (m), lateral offset (m, left +) and the tangent direction at the projection."""
    kind = geo[p, GEO_KIND]
    if kind == 0.0:
        ca, sa = geo[p, GEO_CA0], geo[p, GEO_SA0]
        dx, dy = x - geo[p, GEO_X0], y - geo[p, GEO_Y0]
        return dx * ca + dy * sa, dy * ca - dx * sa, ca, sa
    r, d, a0 = geo[p, GEO_R], geo[p, GEO_ARC], geo[p, GEO_A0]
    dx, dy = x - geo[p, GEO_CX], y - geo[p, GEO_CY]
    dist = math.sqrt(dx * dx + dy * dy)
    inv = 1.0 / dist if dist > 0.0 else 0.0
    phi = math.atan2(dy, dx)
    if kind == 1.0:
        q = 0.5 * d + wrap_angle(phi - (a0 - 0.5 * math.pi) - 0.5 * d)
        return q * r, r - dist, -dy * inv, dx * inv
    q = 0.5 * d + wrap_angle((a0 + 0.5 * math.pi) - 0.5 * d - phi)
    return q * r, dist - r, dy * inv, -dx * inv


@numba.njit(inline="always", **_JIT)
def locate(geo, p, x, y):
    """TORCS's walk from piece p to the piece holding the projection of (x, y) (track spec
    10.1: once it moves in one direction it never turns back). Returns (p, q, n, cos h, sin h)
    as `piece_local`. Inlined into its callers (the car kernel's sub-step loop)."""
    npieces = geo.shape[0]
    q, n, ch, sh = piece_local(geo, p, x, y)
    direction = 0
    for _ in range(npieces):
        if q < 0.0 and direction <= 0:
            direction = -1
            p = p - 1 if p > 0 else npieces - 1
        elif q > geo[p, GEO_LEN] and direction >= 0:
            direction = 1
            p = p + 1 if p < npieces - 1 else 0
        else:
            break
        q, n, ch, sh = piece_local(geo, p, x, y)
    return p, q, n, ch, sh


@numba.njit(**_JIT)
def locate_from(geo, i, px, py):
    """`locate` as a call: (piece, q, n) of (px, py), walking from piece i."""
    p, q, n, _, _ = locate(geo, i, px, py)
    return p, q, n


@numba.njit(cache=True)
def nearest_sample(px, py, sx, sy, gx0, gy0, cell, nx, ny, cell_start, cell_items):
    """Index of the sample nearest to (px, py) using a uniform grid (CSR cell lists)."""
    ix = int(math.floor((px - gx0) / cell))
    iy = int(math.floor((py - gy0) / cell))
    ix = min(max(ix, 0), nx - 1)
    iy = min(max(iy, 0), ny - 1)
    best = -1
    best_d2 = np.inf
    rmax = max(nx, ny)
    for r in range(rmax + 1):
        for cx in range(ix - r, ix + r + 1):
            if cx < 0 or cx >= nx:
                continue
            for cy in range(iy - r, iy + r + 1):
                if cy < 0 or cy >= ny:
                    continue
                if max(abs(cx - ix), abs(cy - iy)) != r:
                    continue
                c = cx * ny + cy
                for k in range(cell_start[c], cell_start[c + 1]):
                    j = cell_items[k]
                    dx = sx[j] - px
                    dy = sy[j] - py
                    d2 = dx * dx + dy * dy
                    if d2 < best_d2:
                        best_d2 = d2
                        best = j
        if best >= 0 and best_d2 <= (r * cell) ** 2:
            break
    return best


@numba.njit(cache=True)
def locate_point(geo, length, piece, px, py):
    """(s, n, piece) of one point, walking from `piece`; s wrapped into [0, L)."""
    i, q, n = locate_from(geo, piece, px, py)
    s = geo[i, GEO_S0] + q
    if s >= length:
        s -= length
    elif s < 0.0:
        s += length
    return s, n, i


@numba.njit(cache=True)
def locate_many(px, py, geo, length, sx, sy, spiece, gx0, gy0, cell, nx, ny, cell_start, cell_items,
                out_s, out_n, out_piece):
    """Vectorised locate: distance from start s in [0, L) and lateral offset n for every point,
    walking from the piece of the nearest centre-line sample."""
    for k in range(px.shape[0]):
        j = nearest_sample(px[k], py[k], sx, sy, gx0, gy0, cell, nx, ny, cell_start, cell_items)
        out_s[k], out_n[k], out_piece[k] = locate_point(geo, length, spiece[j], px[k], py[k])


@numba.njit(cache=True)
def locate_many_hinted(px, py, geo, length, hint_piece, out_s, out_n, out_piece):
    """Locate each point by walking from a known piece (e.g. the car's previous piece), as TORCS
    does every step; unambiguous where the track crosses itself (bridges)."""
    for k in range(px.shape[0]):
        out_s[k], out_n[k], out_piece[k] = locate_point(geo, length, hint_piece[k], px[k], py[k])
