"""Compiled track queries: point -> (s, n) on the piece geometry.

Pieces are passed as a (P, 10) float64 array `geo` with columns GEO_* below. All kernels are
plain loops compiled with numba (cache=True) and also run as ordinary Python for debugging.
"""

from __future__ import annotations

import math

import numba
import numpy as np

GEO_KIND, GEO_S0, GEO_LEN, GEO_R, GEO_ARC, GEO_X0, GEO_Y0, GEO_A0, GEO_CX, GEO_CY = range(10)
GEO_COLUMNS = ("kind", "s0", "length", "radius", "arc", "x0", "y0", "a0", "cx", "cy")


@numba.njit(cache=True, inline="always")
def _wrap(a):
    return a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))


@numba.njit(cache=True)
def piece_local(geo, i, px, py):
    """(q, n) of point (px, py) in piece i: q = centre-line distance from the piece start (m),
    n = signed lateral offset from the centre line (m, left positive)."""
    kind = geo[i, GEO_KIND]
    a0 = geo[i, GEO_A0]
    if kind == 0.0:
        dx = px - geo[i, GEO_X0]
        dy = py - geo[i, GEO_Y0]
        c, s = math.cos(a0), math.sin(a0)
        return dx * c + dy * s, -dx * s + dy * c
    r = geo[i, GEO_R]
    d = geo[i, GEO_ARC]
    dx = px - geo[i, GEO_CX]
    dy = py - geo[i, GEO_CY]
    phi = math.atan2(dy, dx)
    dist = math.sqrt(dx * dx + dy * dy)
    if kind == 1.0:
        q = d / 2.0 + _wrap(phi - (a0 - math.pi / 2.0) - d / 2.0)
        return q * r, r - dist
    q = d / 2.0 + _wrap((a0 + math.pi / 2.0) - d / 2.0 - phi)
    return q * r, dist - r


@numba.njit(cache=True)
def locate_from(geo, i, px, py):
    """Walk from piece i to the piece containing the projection of (px, py), as TORCS does
    (once the walk moves in one direction it never turns back). Returns (piece, q, n)."""
    npieces = geo.shape[0]
    q, n = piece_local(geo, i, px, py)
    direction = 0
    for _ in range(npieces):
        if q < 0.0 and direction <= 0:
            direction = -1
            j = i - 1 if i > 0 else npieces - 1
        elif q > geo[i, GEO_LEN] and direction >= 0:
            direction = 1
            j = i + 1 if i < npieces - 1 else 0
        else:
            break
        q2, n2 = piece_local(geo, j, px, py)
        i, q, n = j, q2, n2
    return i, q, n


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
