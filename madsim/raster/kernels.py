"""Compiled pixel kernels of the rasteriser: quad filling, egocentric sampling, car boxes.

Rasters are label images (H, W) uint8 whose values index a palette (P, 3) uint8; RGB images
are (H, W, 3) uint8. A raster maps world metres to pixels by `x0, y_top, ppm`: pixel (row r,
column c) has its centre at world (x0 + (c + 0.5) / ppm, y_top - (r + 0.5) / ppm) (x east,
y north, rows downwards). Each kernel assumes its arrays are C-contiguous and does no
allocation, so it can run once per frame.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True)
def fill_quads(raster, quads, labels, x0, y_top, ppm):
    """Paint convex quads (Q, 4, 2) world metres into `raster` (H, W) with `labels` (Q,),
    in order (later quads cover earlier ones); a pixel is painted when its centre lies inside
    or on the quad (either winding)."""
    h, w = raster.shape
    for q in range(quads.shape[0]):
        px = np.empty(4)
        py = np.empty(4)
        for k in range(4):
            px[k] = (quads[q, k, 0] - x0) * ppm
            py[k] = (y_top - quads[q, k, 1]) * ppm
        c0 = max(0, int(math.floor(min(px[0], px[1], px[2], px[3]))))
        c1 = min(w - 1, int(math.ceil(max(px[0], px[1], px[2], px[3]))))
        r0 = max(0, int(math.floor(min(py[0], py[1], py[2], py[3]))))
        r1 = min(h - 1, int(math.ceil(max(py[0], py[1], py[2], py[3]))))
        lab = labels[q]
        for r in range(r0, r1 + 1):
            cy = r + 0.5
            for c in range(c0, c1 + 1):
                cx = c + 0.5
                pos = 0
                neg = 0
                for k in range(4):
                    k2 = (k + 1) % 4
                    cr = (px[k2] - px[k]) * (cy - py[k]) - (py[k2] - py[k]) * (cx - px[k])
                    if cr > 1e-12:
                        pos += 1
                    elif cr < -1e-12:
                        neg += 1
                if pos == 0 or neg == 0:
                    raster[r, c] = lab


@numba.njit(cache=True)
def downsample_rgb(raster, palette, factor, out):
    """out (H, W, 3) = box-filtered colours of the label `raster` (H*factor, W*factor)."""
    h, w = out.shape[0], out.shape[1]
    inv = 1.0 / (factor * factor)
    for r in range(h):
        for c in range(w):
            a0 = 0.0
            a1 = 0.0
            a2 = 0.0
            for i in range(factor):
                for j in range(factor):
                    lab = raster[r * factor + i, c * factor + j]
                    a0 += palette[lab, 0]
                    a1 += palette[lab, 1]
                    a2 += palette[lab, 2]
            out[r, c, 0] = np.uint8(a0 * inv + 0.5)
            out[r, c, 1] = np.uint8(a1 * inv + 0.5)
            out[r, c, 2] = np.uint8(a2 * inv + 0.5)


@numba.njit(cache=True)
def egocentric_frame(out, raster, palette, x0, y_top, ppm, outside, cx, cy, yaw, m_per_px,
                     row0, col0, ss, xs, ys, yaws, half_len, half_wid, ego, ego_rgb, other_rgb):
    """One egocentric image `out` (H, W, 3): the car at world (cx, cy) heading `yaw` sits at
    pixel (row0, col0) pointing up (image up = car forward, image left = car left), `m_per_px`
    metres per pixel, `ss` x `ss` samples per pixel from the label raster (palette colours,
    `outside` label beyond the raster). Then every car (xs, ys, yaws, half_len, half_wid: (N,))
    is drawn as a box, car `ego` in `ego_rgb`, the others in `other_rgb` (3,), blended by the
    share of its samples inside the box."""
    h, w = out.shape[0], out.shape[1]
    ch = math.cos(yaw)
    sh = math.sin(yaw)
    hr, wr = raster.shape
    inv = 1.0 / (ss * ss)
    step = 1.0 / ss
    for i in range(h):
        for j in range(w):
            a0 = 0.0
            a1 = 0.0
            a2 = 0.0
            for a in range(ss):
                fwd = (row0 - (i + (a + 0.5) * step)) * m_per_px
                for b in range(ss):
                    lft = (col0 - (j + (b + 0.5) * step)) * m_per_px
                    wx = cx + fwd * ch - lft * sh
                    wy = cy + fwd * sh + lft * ch
                    c = int(math.floor((wx - x0) * ppm))
                    r = int(math.floor((y_top - wy) * ppm))
                    lab = outside
                    if 0 <= r < hr and 0 <= c < wr:
                        lab = raster[r, c]
                    a0 += palette[lab, 0]
                    a1 += palette[lab, 1]
                    a2 += palette[lab, 2]
            out[i, j, 0] = np.uint8(a0 * inv + 0.5)
            out[i, j, 1] = np.uint8(a1 * inv + 0.5)
            out[i, j, 2] = np.uint8(a2 * inv + 0.5)
    reach = (h + w) * m_per_px   # farther than this from the ego car: not in the image
    for k in range(xs.shape[0]):
        dx = xs[k] - cx
        dy = ys[k] - cy
        if abs(dx) > reach + half_len[k] or abs(dy) > reach + half_len[k]:
            continue
        # car centre and axes in image coordinates (column right, row down)
        fwd = dx * ch + dy * sh
        lft = -dx * sh + dy * ch
        pc = col0 - lft / m_per_px
        pr = row0 - fwd / m_per_px
        rel = yaws[k] - yaw
        ux = -math.sin(rel)          # car forward, image columns
        uy = -math.cos(rel)          # car forward, image rows
        hl = half_len[k] / m_per_px
        hw = half_wid[k] / m_per_px
        ext = hl + hw
        rgb = ego_rgb if k == ego else other_rgb
        for i in range(max(0, int(pr - ext)), min(h, int(pr + ext) + 2)):
            for j in range(max(0, int(pc - ext)), min(w, int(pc + ext) + 2)):
                inside = 0
                for a in range(ss):
                    py = i + (a + 0.5) * step - pr
                    for b in range(ss):
                        px = j + (b + 0.5) * step - pc
                        along = px * ux + py * uy
                        across = -px * uy + py * ux
                        if abs(along) <= hl and abs(across) <= hw:
                            inside += 1
                if inside:
                    f = inside * inv
                    for ch3 in range(3):
                        out[i, j, ch3] = np.uint8(out[i, j, ch3] * (1.0 - f) + rgb[ch3] * f + 0.5)


@numba.njit(cache=True)
def rotate_into(out, src, u0, v0, cos_t, sin_t, ax, ay, bg):
    """out (H, W, 3) = `src` (h, w, 3) turned counter-clockwise on screen by angle t about
    the source point (u0, v0) (pixel units, x right, y down), which lands on out's (ax, ay);
    bilinear interpolation, `bg` (3,) where the source has no pixel."""
    h, w = out.shape[0], out.shape[1]
    hs, ws = src.shape[0], src.shape[1]
    for i in range(h):
        dy = i + 0.5 - ay
        # source position of column 0's centre, then a step of (cos, sin) per column
        ub = u0 + (0.5 - ax) * cos_t - dy * sin_t - 0.5
        vb = v0 + (0.5 - ax) * sin_t + dy * cos_t - 0.5
        for j in range(w):
            u = ub + j * cos_t
            v = vb + j * sin_t
            c = int(math.floor(u))
            r = int(math.floor(v))
            if c < 0 or r < 0 or c + 1 >= ws or r + 1 >= hs:
                out[i, j, 0] = bg[0]
                out[i, j, 1] = bg[1]
                out[i, j, 2] = bg[2]
                continue
            fu = u - c
            fv = v - r
            w00 = (1.0 - fu) * (1.0 - fv)
            w01 = fu * (1.0 - fv)
            w10 = (1.0 - fu) * fv
            w11 = fu * fv
            p00 = src[r, c]
            p01 = src[r, c + 1]
            p10 = src[r + 1, c]
            p11 = src[r + 1, c + 1]
            for k in range(3):
                out[i, j, k] = np.uint8(p00[k] * w00 + p01[k] * w01 + p10[k] * w10 + p11[k] * w11 + 0.5)


@numba.njit(cache=True)
def track_poses(geo, length, s, n, out_x, out_y, out_h):
    """World x, y (m) and centre-line heading (rad) of track points (s, n), (N,) each, from the
    piece table `geo` (tracks.kernels.GEO_COLUMNS: kind 0 straight / 1 left / 2 right, s0,
    length, radius, arc, x0, y0, a0, cx, cy); the same formulas as `Track.pose`."""
    p_count = geo.shape[0]
    for k in range(s.shape[0]):
        sk = s[k] % length
        lo, hi = 0, p_count - 1          # last piece with s0 <= sk
        while lo < hi:
            mid = (lo + hi + 1) // 2
            if geo[mid, 1] <= sk:
                lo = mid
            else:
                hi = mid - 1
        g = geo[lo]
        q = sk - g[1]
        kind = g[0]
        a0 = g[7]
        if kind == 0.0:
            a = a0
            x = g[5] + q * math.cos(a0)
            y = g[6] + q * math.sin(a0)
        elif kind == 1.0:
            a = a0 + q / g[3]
            x = g[8] + g[3] * math.sin(a)
            y = g[9] - g[3] * math.cos(a)
        else:
            a = a0 - q / g[3]
            x = g[8] - g[3] * math.sin(a)
            y = g[9] + g[3] * math.cos(a)
        out_x[k] = x - n[k] * math.sin(a)
        out_y[k] = y + n[k] * math.cos(a)
        out_h[k] = a
