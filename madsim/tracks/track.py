"""The immutable, sampled `Track` and its vectorised queries (ARCHITECTURE.md, tracks/).

Frame: x east, y north, z up; headings counter-clockwise from +x. Track coordinates are
(s, n): s = distance from the start line along the centre line in [0, L), n = signed lateral
offset from the centre line, left positive (TORCS `toMiddle`). The exact piece geometry is kept
(`pieces`) and the centre line is also sampled at most `SAMPLE_SPACING_M` apart.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from madsim.tracks import kernels, rays
from madsim.tracks.build import COL, LEFT, RIGHT, STRAIGHT, STYLE_WALL, BuildResult, Surface

SAMPLE_SPACING_M = 1.0
GRID_CELL_M = 10.0


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


@dataclass(frozen=True, eq=False)
class Track:
    """A track: TORCS pieces plus a sampled centre line; all queries take arrays.

    Sample arrays (length K, s ascending from 0): `s, x, y, z, heading` (unwrapped, rad),
    `curvature` (1/m, left positive), `banking` (rad, left edge higher positive),
    `width_left, width_right` (road half widths, m), `barrier_left, barrier_right` (lateral
    distance from the centre line to the barrier line = outer edge of the side, m),
    `surface_id` (road material index into `surfaces`), `piece` (piece index).
    """

    name: str            # the id users type: the file's stem (e.g. "g-track-1")
    title: str           # the Header name (e.g. "CG Speedway number 1")
    category: str
    version: int
    author: str
    description: str
    source: str
    width: float
    length: float
    pieces: np.ndarray
    piece_names: tuple[str, ...]
    surfaces: tuple[Surface, ...]
    side_bank_tangent: tuple[bool, bool]
    grid: dict
    pits: dict
    closure_gap: float
    closure_heading_gap: float
    offset: tuple[float, float, float]
    s: np.ndarray = field(repr=False)
    x: np.ndarray = field(repr=False)
    y: np.ndarray = field(repr=False)
    z: np.ndarray = field(repr=False)
    heading: np.ndarray = field(repr=False)
    curvature: np.ndarray = field(repr=False)
    banking: np.ndarray = field(repr=False)
    width_left: np.ndarray = field(repr=False)
    width_right: np.ndarray = field(repr=False)
    barrier_left: np.ndarray = field(repr=False)
    barrier_right: np.ndarray = field(repr=False)
    surface_id: np.ndarray = field(repr=False)
    piece: np.ndarray = field(repr=False)
    _geo: np.ndarray = field(repr=False)
    _grid: tuple = field(repr=False)
    runs: np.ndarray = field(repr=False)          # (R, rays.RUN_COLS) merged pieces, for rays
    piece_run: np.ndarray = field(repr=False)     # (P,) piece index -> run index

    # --- construction -------------------------------------------------------------------

    @classmethod
    def from_build(cls, b: BuildResult, source: str = "", name: str | None = None) -> "Track":
        """Sample a built piece table into a Track (translated so min x, y, z >= 0 as TORCS)."""
        p = b.pieces.copy()
        w = b.width
        first, last = p[0], p[-1]
        end_x, end_y, end_a = _piece_end(last)
        closure_gap = math.hypot(end_x - first[COL["x0"]], end_y - first[COL["y0"]])
        closure_heading = float(_wrap(end_a - first[COL["a0"]]))

        geo = _geo_of(p)
        samples = _sample(p, w, geo)
        # TORCS translates so that the minimum x, y, z over the track become 0, never upwards.
        outer_x = np.concatenate([samples["bl_x"], samples["br_x"]])
        outer_y = np.concatenate([samples["bl_y"], samples["br_y"]])
        zcols = p[:, [COL["zr0"], COL["zl0"], COL["zr1"], COL["zl1"]]]
        dx = min(0.0, float(outer_x.min()))
        dy = min(0.0, float(outer_y.min()))
        dz = min(0.0, float(zcols.min()))
        if dx or dy or dz:
            translate_pieces(p, -dx, -dy, -dz)
            geo = _geo_of(p)
            samples = _sample(p, w, geo)

        grid = _build_grid(samples["x"], samples["y"], samples["piece"],
                           float(np.max(np.maximum(samples["barrier_left"], samples["barrier_right"]))))
        return cls(
            name=name or b.name, title=b.name, category=b.category, version=b.version, author=b.author,
            description=b.description, source=source, width=w, length=b.length,
            pieces=_readonly(p), piece_names=tuple(b.piece_names), surfaces=tuple(b.surfaces),
            side_bank_tangent=b.side_bank_tangent, grid=dict(b.grid), pits=dict(b.pits),
            closure_gap=closure_gap, closure_heading_gap=closure_heading,
            offset=(-dx, -dy, -dz),
            s=_readonly(samples["s"]), x=_readonly(samples["x"]), y=_readonly(samples["y"]),
            z=_readonly(samples["z"]), heading=_readonly(samples["heading"]),
            curvature=_readonly(samples["curvature"]), banking=_readonly(samples["banking"]),
            width_left=_readonly(np.full_like(samples["s"], w / 2)),
            width_right=_readonly(np.full_like(samples["s"], w / 2)),
            barrier_left=_readonly(samples["barrier_left"]),
            barrier_right=_readonly(samples["barrier_right"]),
            surface_id=_readonly(samples["surface_id"]), piece=_readonly(samples["piece"]),
            _geo=_readonly(geo), _grid=grid,
            **dict(zip(("runs", "piece_run"), map(_readonly, rays.build_runs(p)))),
        )

    # --- facts --------------------------------------------------------------------------

    @property
    def n_pieces(self) -> int:
        return int(self.pieces.shape[0])

    @property
    def n_segments(self) -> int:
        return len(self.piece_names)

    @property
    def geo(self) -> np.ndarray:
        """(P, N_GEO) piece geometry for compiled kernels (columns: kernels.GEO_COLUMNS)."""
        return self._geo

    @property
    def elevation_range(self) -> tuple[float, float]:
        zc = self.pieces[:, [COL["zr0"], COL["zl0"], COL["zr1"], COL["zl1"]]]
        return float(zc.min()), float(zc.max())

    @property
    def bounding_box(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of the barrier lines, m."""
        lx, ly = self.barrier_polyline("left").T
        rx, ry = self.barrier_polyline("right").T
        return (float(min(lx.min(), rx.min())), float(min(ly.min(), ry.min())),
                float(max(lx.max(), rx.max())), float(max(ly.max(), ry.max())))

    def surface_index(self, name: str) -> int:
        for i, srf in enumerate(self.surfaces):
            if srf.name == name:
                return i
        raise KeyError(name)

    # --- polylines ----------------------------------------------------------------------

    def _offset_polyline(self, n: np.ndarray) -> np.ndarray:
        nx, ny = -np.sin(self.heading), np.cos(self.heading)
        return np.stack([self.x + n * nx, self.y + n * ny], axis=1)

    def edge_polyline(self, side: str) -> np.ndarray:
        """(K, 2) road edge on `side` ('left' or 'right') at every sample."""
        return self._offset_polyline(self.width_left if side == "left" else -self.width_right)

    def barrier_polyline(self, side: str) -> np.ndarray:
        """(K, 2) barrier line (outer edge of the side) on `side` at every sample."""
        return self._offset_polyline(self.barrier_left if side == "left" else -self.barrier_right)

    def edges_near(self, s: float, ahead: float, behind: float = 0.0) -> dict[str, np.ndarray]:
        """Edge and barrier polylines for the samples in [s - behind, s + ahead] (wrapping)."""
        rel = (self.s - s + behind) % self.length
        idx = np.nonzero(rel <= ahead + behind)[0]
        idx = idx[np.argsort(rel[idx])]
        return {k: getattr(self, f"{kind}_polyline")(side)[idx]
                for k, kind, side in (("edge_left", "edge", "left"), ("edge_right", "edge", "right"),
                                      ("barrier_left", "barrier", "left"),
                                      ("barrier_right", "barrier", "right"))}

    # --- queries (vectorised over points) -----------------------------------------------

    def piece_at(self, s) -> np.ndarray:
        """Index of the piece containing distance s (any real s, wrapped into [0, L))."""
        s = np.asarray(s, dtype=np.float64)
        out = np.empty(s.shape, dtype=np.int64)
        kernels.pieces_at(self._geo, self.length, np.ascontiguousarray(s.ravel()), out.reshape(-1))
        return out[()]

    def _piece_frac(self, s):
        s = np.mod(np.asarray(s, dtype=np.float64), self.length)
        i = self.piece_at(s)
        q = s - self.pieces[i, COL["s0"]]
        u = np.clip(q / self.pieces[i, COL["length"]], 0.0, 1.0)
        return i, q, u

    def heading_at(self, s) -> np.ndarray:
        """Centre-line tangent heading at s, wrapped to [-pi, pi)."""
        i, q, _ = self._piece_frac(s)
        p = self.pieces[i]
        kind = p[..., COL["kind"]]
        r = np.where(kind == STRAIGHT, 1.0, p[..., COL["radius"]])
        turn = np.select([kind == LEFT, kind == RIGHT], [q / r, -q / r], 0.0)
        return _wrap(p[..., COL["a0"]] + turn)

    def curvature_at(self, s) -> np.ndarray:
        """Signed centre-line curvature at s (1/m, left turns positive)."""
        i = self.piece_at(s)
        p = self.pieces[i]
        kind = p[..., COL["kind"]]
        with np.errstate(divide="ignore"):
            k = 1.0 / p[..., COL["radius"]]
        return np.select([kind == LEFT, kind == RIGHT], [k, -k], 0.0)

    def width_at(self, s) -> np.ndarray:
        """Main road width at s (constant in TORCS), m."""
        return np.full(np.shape(np.asarray(s)), self.width)

    def side_widths_at(self, s) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(border_right, side_right, border_left, side_left) widths at s, m."""
        i, _, u = self._piece_frac(s)
        p = self.pieces[i]
        sr = p[..., COL["side_w0_r"]] + u * (p[..., COL["side_w1_r"]] - p[..., COL["side_w0_r"]])
        sl = p[..., COL["side_w0_l"]] + u * (p[..., COL["side_w1_l"]] - p[..., COL["side_w0_l"]])
        return p[..., COL["border_w_r"]], sr, p[..., COL["border_w_l"]], sl

    def barrier_offsets_at(self, s) -> tuple[np.ndarray, np.ndarray]:
        """Lateral distance from the centre line to the (left, right) barrier line at s, m."""
        br, sr, bl, sl = self.side_widths_at(s)
        return self.width / 2 + bl + sl, self.width / 2 + br + sr

    def pit_wall_pieces(self) -> np.ndarray:
        """(P, 2) bool, per piece (left, right): the border is a solid wall (track spec 6: a
        border of style `wall`, width > 0, with a side beyond it: TORCS's pit walls)."""
        p = self.pieces
        out = np.zeros((p.shape[0], 2), dtype=bool)
        for k, sfx in enumerate(("l", "r")):
            out[:, k] = ((p[:, COL[f"border_style_{sfx}"]] == STYLE_WALL)
                         & (p[:, COL[f"border_w_{sfx}"]] > 0.0)
                         & ((p[:, COL[f"side_w0_{sfx}"]] > 0.0) | (p[:, COL[f"side_w1_{sfx}"]] > 0.0)))
        return out

    def pit_wall_quads(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The solid walls of `pit_wall_pieces` as convex quads over the border strip, a curved
        piece cut at most SAMPLE_SPACING_M apart along the centre line: (W, 4, 2) corners (m;
        inner start, outer start, outer end, inner end), (W,) piece index and (W,) side
        (0 left, 1 right)."""
        walls = self.pit_wall_pieces()
        quads, pieces, sides = [], [], []
        half = self.width / 2.0
        for i, k in zip(*np.nonzero(walls)):
            row = self.pieces[i]
            ln = row[COL["length"]]
            cuts = 1 if row[COL["kind"]] == STRAIGHT else max(1, math.ceil(ln / SAMPLE_SPACING_M))
            s = row[COL["s0"]] + ln * np.linspace(0.0, 1.0, cuts + 1)
            s[-1] = np.nextafter(s[-1], s[0])          # the piece's own end, not the next one's
            sign = 1.0 if k == 0 else -1.0
            outer = half + row[COL["border_w_l" if k == 0 else "border_w_r"]]
            xi, yi, _, _ = self.pose(s, sign * half)
            xo, yo, _, _ = self.pose(s, sign * outer)
            q = np.stack([np.stack([xi[:-1], yi[:-1]], 1), np.stack([xo[:-1], yo[:-1]], 1),
                          np.stack([xo[1:], yo[1:]], 1), np.stack([xi[1:], yi[1:]], 1)], axis=1)
            quads.append(q)
            pieces.append(np.full(cuts, i, dtype=np.int64))
            sides.append(np.full(cuts, k, dtype=np.int64))
        if not quads:
            return np.zeros((0, 4, 2)), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
        return np.concatenate(quads), np.concatenate(pieces), np.concatenate(sides)

    def banking_at(self, s) -> np.ndarray:
        """Cross slope at s (rad; positive = left edge higher), linear inside a piece."""
        i, _, u = self._piece_frac(s)
        p = self.pieces[i]
        b0 = np.arctan2(p[..., COL["zl0"]] - p[..., COL["zr0"]], self.width)
        b1 = np.arctan2(p[..., COL["zl1"]] - p[..., COL["zr1"]], self.width)
        return b0 + u * (b1 - b0)

    def elevation(self, s, n) -> np.ndarray:
        """Surface height at (s, n), m: TORCS's in-piece rule (linear right edge + banking);
        level sides stay at the road edge height, tangent sides continue the cross slope."""
        s, n = np.broadcast_arrays(np.asarray(s, dtype=np.float64), np.asarray(n, dtype=np.float64))
        i, _, u = self._piece_frac(s)
        p = self.pieces[i]
        zr = p[..., COL["zr0"]] + u * (p[..., COL["zr1"]] - p[..., COL["zr0"]])
        b0 = np.arctan2(p[..., COL["zl0"]] - p[..., COL["zr0"]], self.width)
        b1 = np.arctan2(p[..., COL["zl1"]] - p[..., COL["zr1"]], self.width)
        bank = b0 + u * (b1 - b0)
        y = n + self.width / 2  # toRight
        lo = -np.inf if self.side_bank_tangent[0] else 0.0
        hi = np.inf if self.side_bank_tangent[1] else self.width
        return zr + np.clip(y, lo, hi) * np.tan(bank)

    def grade_at(self, s) -> np.ndarray:
        """Longitudinal slope dz/ds of the centre line at s (piecewise constant)."""
        i = self.piece_at(s)
        p = self.pieces[i]
        z0 = (p[..., COL["zr0"]] + p[..., COL["zl0"]]) / 2
        z1 = (p[..., COL["zr1"]] + p[..., COL["zl1"]]) / 2
        return (z1 - z0) / p[..., COL["length"]]

    def surface_at(self, s, n) -> np.ndarray:
        """Material index (into `surfaces`) under (s, n): road, border, side, else barrier."""
        s, n = np.broadcast_arrays(np.asarray(s, dtype=np.float64), np.asarray(n, dtype=np.float64))
        i, _, u = self._piece_frac(s)
        p = self.pieces[i]
        br, sr, bl, sl = self.side_widths_at(s)
        half = self.width / 2
        over_r = -n - half
        over_l = n - half
        out = p[..., COL["surface"]].copy()
        for over, bw, sw, sfx in ((over_r, br, sr, "r"), (over_l, bl, sl, "l")):
            out = np.where((over > 0) & (over <= bw), p[..., COL[f"border_surf_{sfx}"]], out)
            out = np.where((over > bw) & (over <= bw + sw), p[..., COL[f"side_surf_{sfx}"]], out)
            out = np.where(over > bw + sw, p[..., COL[f"barrier_surf_{sfx}"]], out)
        return out.astype(np.int64)

    def pose(self, s, n=0.0):
        """(x, y, z, heading) of track point (s, n); heading = centre-line tangent, wrapped."""
        s, n = np.broadcast_arrays(np.asarray(s, dtype=np.float64), np.asarray(n, dtype=np.float64))
        i, q, _ = self._piece_frac(s)
        p = self.pieces[i]
        kind = p[..., COL["kind"]]
        a0 = p[..., COL["a0"]]
        r = np.where(kind == STRAIGHT, 1.0, p[..., COL["radius"]])
        a = a0 + np.select([kind == LEFT, kind == RIGHT], [q / r, -q / r], 0.0)
        cx, cy = p[..., COL["cx"]], p[..., COL["cy"]]
        x = np.select([kind == LEFT, kind == RIGHT],
                      [cx + r * np.sin(a), cx - r * np.sin(a)], p[..., COL["x0"]] + q * np.cos(a0))
        y = np.select([kind == LEFT, kind == RIGHT],
                      [cy - r * np.cos(a), cy + r * np.cos(a)], p[..., COL["y0"]] + q * np.sin(a0))
        x = x - n * np.sin(a)
        y = y + n * np.cos(a)
        return x, y, self.elevation(s, n), _wrap(a)

    def rangefinders(self, x, y, yaw, angles_deg, *, s_hint=None, max_range_m: float = 200.0) -> np.ndarray:
        """(N, A) distances from points (x, y) along yaw - angle (SCR angles: degrees, positive
        clockwise) to the first crossing of a road edge, capped at max_range_m. Exact (lines and
        circles). Points must be on the road; the SCR -1 sentinel is the sensor layer's job."""
        x, y, yaw = (np.atleast_1d(np.asarray(v, dtype=np.float64)) for v in (x, y, yaw))
        s, _ = self.locate(x, y, s_hint=s_hint)
        angles = np.radians(np.asarray(angles_deg, dtype=np.float64))
        out = np.empty((x.shape[0], angles.shape[0]))
        rays.rangefinders(self._geo, self.length, self.runs, self.piece_run, self.width / 2, s,
                          np.ascontiguousarray(x), np.ascontiguousarray(y), np.ascontiguousarray(yaw),
                          angles, max_range_m, out)
        return out

    def locate(self, x, y, s_hint=None):
        """(s, n) of global points: s in [0, L) = arc length of the projection on the centre
        line, n = signed lateral offset (left positive). Exact on the piece geometry.

        Without `s_hint` the walk starts at the nearest centre-line sample (ambiguous only where
        the track crosses itself in plan, e.g. wheel-2's bridge); with `s_hint` (a known nearby
        distance, e.g. the car's previous s) it starts from that piece, as TORCS does.
        """
        x, y = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
        shape = x.shape
        px, py = np.ascontiguousarray(x.ravel()), np.ascontiguousarray(y.ravel())
        out_s = np.empty(px.shape[0])
        out_n = np.empty(px.shape[0])
        out_piece = np.empty(px.shape[0], dtype=np.int64)
        if s_hint is not None:
            hint = np.ascontiguousarray(np.broadcast_to(self.piece_at(s_hint), shape).ravel(), dtype=np.int64)
            kernels.locate_many_hinted(px, py, self._geo, self.length, hint, out_s, out_n, out_piece)
        else:
            g = self._grid
            kernels.locate_many(px, py, self._geo, self.length, self.x, self.y, self.piece,
                                g[0], g[1], g[2], g[3], g[4], g[5], g[6], out_s, out_n, out_piece)
        return out_s.reshape(shape), out_n.reshape(shape)


# --- helpers ------------------------------------------------------------------------------


def translate_pieces(p: np.ndarray, dx: float, dy: float, dz: float) -> None:
    """Move a piece table (in place) by (dx, dy, dz), m."""
    for c in ("x0", "cx"):
        p[:, COL[c]] += dx
    for c in ("y0", "cy"):
        p[:, COL[c]] += dy
    for c in ("zr0", "zl0", "zr1", "zl1"):
        p[:, COL[c]] += dz


def _piece_end(row: np.ndarray) -> tuple[float, float, float]:
    kind, length, r = row[COL["kind"]], row[COL["length"]], row[COL["radius"]]
    a0, x0, y0 = row[COL["a0"]], row[COL["x0"]], row[COL["y0"]]
    if kind == STRAIGHT:
        return x0 + length * math.cos(a0), y0 + length * math.sin(a0), a0
    d = row[COL["arc"]]
    cx, cy = row[COL["cx"]], row[COL["cy"]]
    if kind == LEFT:
        a = a0 + d
        return cx + r * math.sin(a), cy - r * math.cos(a), a
    a = a0 - d
    return cx - r * math.sin(a), cy + r * math.cos(a), a


def _geo_of(p: np.ndarray) -> np.ndarray:
    """The (P, N_GEO) piece table of the compiled walk (`kernels.GEO_COLUMNS`)."""
    geo = np.empty((p.shape[0], kernels.N_GEO))
    for k, name in enumerate(kernels.GEO_COLUMNS[:kernels.GEO_CA0]):
        geo[:, k] = p[:, COL[name]]
    geo[:, kernels.GEO_CA0] = np.cos(p[:, COL["a0"]])
    geo[:, kernels.GEO_SA0] = np.sin(p[:, COL["a0"]])
    return geo


def _sample(p: np.ndarray, w: float, geo: np.ndarray) -> dict[str, np.ndarray]:
    """Sample every piece at its start and at most SAMPLE_SPACING_M apart inside (vectorised)."""
    lengths = p[:, COL["length"]]
    counts = np.maximum(1, np.ceil(lengths / SAMPLE_SPACING_M).astype(np.int64))
    piece = np.repeat(np.arange(len(p)), counts)
    first = np.cumsum(counts) - counts
    k = np.arange(piece.shape[0]) - first[piece]
    u = k / counts[piece]
    q = u * lengths[piece]
    pp = p[piece]
    kind = pp[:, COL["kind"]]
    r = np.where(kind == STRAIGHT, 1.0, pp[:, COL["radius"]])
    a0 = pp[:, COL["a0"]]
    turn = np.select([kind == LEFT, kind == RIGHT], [q / r, -q / r], 0.0)
    a = a0 + turn
    cx, cy = pp[:, COL["cx"]], pp[:, COL["cy"]]
    x = np.select([kind == LEFT, kind == RIGHT], [cx + r * np.sin(a), cx - r * np.sin(a)],
                  pp[:, COL["x0"]] + q * np.cos(a0))
    y = np.select([kind == LEFT, kind == RIGHT], [cy - r * np.cos(a), cy + r * np.cos(a)],
                  pp[:, COL["y0"]] + q * np.sin(a0))
    zr = pp[:, COL["zr0"]] + u * (pp[:, COL["zr1"]] - pp[:, COL["zr0"]])
    zl = pp[:, COL["zl0"]] + u * (pp[:, COL["zl1"]] - pp[:, COL["zl0"]])
    b0 = np.arctan2(pp[:, COL["zl0"]] - pp[:, COL["zr0"]], w)
    b1 = np.arctan2(pp[:, COL["zl1"]] - pp[:, COL["zr1"]], w)
    with np.errstate(divide="ignore"):
        k_abs = 1.0 / pp[:, COL["radius"]]
    curvature = np.select([kind == LEFT, kind == RIGHT], [k_abs, -k_abs], 0.0)
    sl = pp[:, COL["side_w0_l"]] + u * (pp[:, COL["side_w1_l"]] - pp[:, COL["side_w0_l"]])
    sr = pp[:, COL["side_w0_r"]] + u * (pp[:, COL["side_w1_r"]] - pp[:, COL["side_w0_r"]])
    barrier_left = w / 2 + pp[:, COL["border_w_l"]] + sl
    barrier_right = w / 2 + pp[:, COL["border_w_r"]] + sr
    nx, ny = -np.sin(a), np.cos(a)
    return {
        "s": pp[:, COL["s0"]] + q, "x": x, "y": y, "z": (zr + zl) / 2, "heading": a,
        "curvature": curvature, "banking": b0 + u * (b1 - b0),
        "barrier_left": barrier_left, "barrier_right": barrier_right,
        "surface_id": pp[:, COL["surface"]].astype(np.int64), "piece": piece,
        "bl_x": x + barrier_left * nx, "bl_y": y + barrier_left * ny,
        "br_x": x - barrier_right * nx, "br_y": y - barrier_right * ny,
    }


def _build_grid(x: np.ndarray, y: np.ndarray, piece: np.ndarray, reach: float) -> tuple:
    """Uniform grid (cell lists in CSR form) over the centre-line samples for nearest search."""
    margin = reach + GRID_CELL_M
    gx0, gy0 = float(x.min() - margin), float(y.min() - margin)
    nx = int(math.ceil((x.max() + margin - gx0) / GRID_CELL_M)) + 1
    ny = int(math.ceil((y.max() + margin - gy0) / GRID_CELL_M)) + 1
    ix = np.floor((x - gx0) / GRID_CELL_M).astype(np.int64)
    iy = np.floor((y - gy0) / GRID_CELL_M).astype(np.int64)
    cell = ix * ny + iy
    order = np.argsort(cell, kind="stable")
    counts = np.bincount(cell, minlength=nx * ny)
    cell_start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    return (gx0, gy0, GRID_CELL_M, nx, ny, _readonly(cell_start), _readonly(order.astype(np.int64)))
