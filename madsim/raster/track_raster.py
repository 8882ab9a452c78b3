"""The static track as coloured quads and label rasters, shared by the view and image observations.

`track_quads(track)` cuts the track into convex quads between consecutive centre-line samples
(1 m apart): per interval, the right side, right border, left side, left border, the road, and
the chequered start line, each with a palette label chosen from its TORCS surface name
(`surface_colour`). `TrackRaster` paints them once into a label image (uint8 per pixel) over
the track's bounding box; the pygame view paints windows (tiles) of the same quads.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from madsim.raster import kernels
from madsim.tracks import Track
from madsim.tracks.build import COL

# fixed labels; surface colours follow from FIRST_SURFACE_LABEL on
BACKGROUND, START_WHITE, START_BLACK, KERB_WHITE = 0, 1, 2, 3
FIRST_SURFACE_LABEL = 4
FIXED_COLOURS = ((52, 74, 56), (245, 245, 245), (20, 20, 20), (236, 236, 236))

# first keyword found in the (lower-case) surface name decides the colour
_KEYWORD_COLOURS = (
    (("kerb", "curb"), (200, 52, 44)),
    (("grass",), (92, 142, 72)),
    (("sand", "gravel"), (205, 188, 132)),
    (("dirt", "mud", "earth"), (150, 113, 78)),
    (("snow", "ice"), (232, 238, 244)),
    (("sidewalk", "pavement", "concrete", "apron"), (176, 176, 170)),
    (("wall", "armco", "barrier", "fence", "tyre", "tire", "building"), (88, 88, 94)),
    (("asphalt", "tarmac", "road", "pit", "street"), (100, 103, 109)),
)
UNKNOWN_SURFACE = (128, 124, 112)
START_LINE_DEPTH_M = 1.0
START_SQUARE_M = 1.0


def surface_colour(name: str) -> tuple[int, int, int]:
    """RGB of a TORCS surface by its name (kerb red, grass green, sand, dirt, asphalt grey...)."""
    low = name.lower()
    for words, rgb in _KEYWORD_COLOURS:
        if any(w in low for w in words):
            return rgb
    return UNKNOWN_SURFACE


def _is_kerb(name: str) -> bool:
    low = name.lower()
    return "kerb" in low or "curb" in low


def palette(track: Track) -> np.ndarray:
    """(FIRST_SURFACE_LABEL + len(track.surfaces), 3) uint8 colours of every label."""
    if FIRST_SURFACE_LABEL + len(track.surfaces) > 256:
        raise ValueError(f"track {track.name!r} has {len(track.surfaces)} surfaces; the renderer "
                         f"draws at most {256 - FIRST_SURFACE_LABEL}")
    rows = list(FIXED_COLOURS) + [surface_colour(s.name) for s in track.surfaces]
    return np.array(rows, dtype=np.uint8)


def _band_quads(x, y, h, n_in, n_out):
    """(K, 4, 2) quads between lateral offsets n_in and n_out over sample intervals k -> k+1
    (arrays of length K + 1: the last sample repeats the first to close the loop)."""
    nx, ny = -np.sin(h), np.cos(h)
    ax, ay = x + n_in * nx, y + n_in * ny
    bx, by = x + n_out * nx, y + n_out * ny
    q = np.empty((x.shape[0] - 1, 4, 2))
    q[:, 0, 0], q[:, 0, 1] = ax[:-1], ay[:-1]
    q[:, 1, 0], q[:, 1, 1] = bx[:-1], by[:-1]
    q[:, 2, 0], q[:, 2, 1] = bx[1:], by[1:]
    q[:, 3, 0], q[:, 3, 1] = ax[1:], ay[1:]
    return q


@dataclass(frozen=True)
class TrackQuads:
    """The track as convex quads: `quads` (Q, 4, 2) world m, `labels` (Q,) uint8 palette
    labels, in painting order; `bbox` (Q, 4) per quad (xmin, ymin, xmax, ymax), m."""

    quads: np.ndarray
    labels: np.ndarray
    bbox: np.ndarray

    def window(self, xmin: float, ymin: float, xmax: float, ymax: float) -> TrackQuads:
        """The quads whose bounding box meets the rectangle (order kept)."""
        b = self.bbox
        keep = (b[:, 2] >= xmin) & (b[:, 0] <= xmax) & (b[:, 3] >= ymin) & (b[:, 1] <= ymax)
        return TrackQuads(self.quads[keep], self.labels[keep], b[keep])


def track_quads(track: Track) -> TrackQuads:
    """Sides, borders, road and start line of `track` as quads (see the module docstring)."""
    x = np.append(track.x, track.x[0])
    y = np.append(track.y, track.y[0])
    h = np.append(track.heading, track.heading[0])
    s = np.append(track.s, track.length)
    piece = np.append(track.piece, track.piece[0])
    half = track.width / 2
    br, sr, bl, sl = track.side_widths_at(np.minimum(s, np.nextafter(track.length, 0)))
    p = track.pieces[piece[:-1]]
    stripe = (np.arange(len(s) - 1) // 2) % 2          # kerb stripes of two samples (~2 m)
    bands = []   # (n_in, n_out, labels) in painting order
    for sign, b, sd, sfx in ((-1.0, br, sr, "r"), (1.0, bl, sl, "l")):
        side_lab = p[:, COL[f"side_surf_{sfx}"]].astype(np.int64) + FIRST_SURFACE_LABEL
        bands.append((sign * (half + b), sign * (half + b + sd), side_lab, sd))
    for sign, b, sfx in ((-1.0, br, "r"), (1.0, bl, "l")):
        surf = p[:, COL[f"border_surf_{sfx}"]].astype(np.int64)
        lab = surf + FIRST_SURFACE_LABEL
        is_kerb = np.array([_is_kerb(track.surfaces[i].name) for i in surf], dtype=bool)
        lab = np.where(is_kerb & (stripe == 1), KERB_WHITE, lab)
        bands.append((sign * half, sign * (half + b), lab, b))
    road = track.surface_id.astype(np.int64) + FIRST_SURFACE_LABEL
    bands.append((-half, half, road, np.full_like(s, track.width)))
    quads, labels = [], []
    for n_in, n_out, lab, width in bands:
        n_in = np.broadcast_to(n_in, s.shape)
        n_out = np.broadcast_to(n_out, s.shape)
        q = _band_quads(x, y, h, n_in, n_out)
        keep = (np.asarray(width)[:-1] > 1e-6) | (np.asarray(width)[1:] > 1e-6)
        quads.append(q[keep])
        labels.append(np.asarray(lab)[keep])
    start_quads, start_labels = _start_line(track)
    quads.append(start_quads)
    labels.append(start_labels)
    q = np.ascontiguousarray(np.concatenate(quads))
    lab = np.concatenate(labels).astype(np.uint8)
    bbox = np.concatenate([q.min(axis=1), q.max(axis=1)], axis=1)
    return TrackQuads(q, lab, bbox)


def _start_line(track: Track) -> tuple[np.ndarray, np.ndarray]:
    """Chequered squares across the road at s = 0: (quads (M, 4, 2), labels (M,))."""
    x0, y0, _, h0 = (float(v) for v in track.pose(0.0, 0.0))
    tx, ty = math.cos(h0), math.sin(h0)
    nx, ny = -ty, tx
    cols = max(2, round(track.width / START_SQUARE_M))
    step = track.width / cols
    rows = 2
    depth = START_LINE_DEPTH_M / rows
    quads, labels = [], []
    for r in range(rows):
        for c in range(cols):
            n0 = -track.width / 2 + c * step
            a0 = -START_LINE_DEPTH_M / 2 + r * depth
            corners = ((a0, n0), (a0 + depth, n0), (a0 + depth, n0 + step), (a0, n0 + step))
            quads.append([(x0 + a * tx + n * nx, y0 + a * ty + n * ny) for a, n in corners])
            labels.append(START_WHITE if (r + c) % 2 == 0 else START_BLACK)
    return np.array(quads, dtype=np.float64), np.array(labels)


class TrackRaster:
    """The whole track painted once into a label image at `ppm` pixels per metre.

    `labels` (H, W) uint8, `palette` (P, 3) uint8, `x0`, `y_top` (world metres of the left and
    top raster edges) and `ppm`; see `madsim.raster.kernels` for the pixel convention. The
    resolution is lowered if the image would exceed `max_pixels` (big TORCS tracks).
    """

    def __init__(self, track: Track, ppm: float = 4.0, *, margin_m: float = 60.0,
                 max_pixels: int = 24_000_000, quads: TrackQuads | None = None):
        if not ppm > 0:
            raise ValueError(f"ppm must be > 0, got {ppm}")
        xmin, ymin, xmax, ymax = track.bounding_box
        xmin, ymin, xmax, ymax = xmin - margin_m, ymin - margin_m, xmax + margin_m, ymax + margin_m
        area = (xmax - xmin) * (ymax - ymin)
        ppm = min(float(ppm), math.sqrt(max_pixels / area))
        self.ppm = ppm
        self.x0, self.y_top = xmin, ymax
        w = math.ceil((xmax - xmin) * ppm)
        h = math.ceil((ymax - ymin) * ppm)
        self.palette = palette(track)
        self.labels = np.zeros((h, w), dtype=np.uint8)
        q = quads if quads is not None else track_quads(track)
        kernels.fill_quads(self.labels, q.quads, q.labels, self.x0, self.y_top, ppm)

    def label_at(self, x, y) -> np.ndarray:
        """Labels under world points (BACKGROUND outside the raster)."""
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        c = np.floor((x - self.x0) * self.ppm).astype(np.int64)
        r = np.floor((self.y_top - y) * self.ppm).astype(np.int64)
        h, w = self.labels.shape
        ok = (r >= 0) & (r < h) & (c >= 0) & (c < w)
        out = np.full(x.shape, BACKGROUND, dtype=np.uint8)
        out[ok] = self.labels[r[ok], c[ok]]
        return out

    def rgb(self) -> np.ndarray:
        """(H, W, 3) uint8 colour image of the whole raster."""
        return self.palette[self.labels]
