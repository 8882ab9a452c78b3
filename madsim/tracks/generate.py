"""Procedural race tracks written as TORCS track XML (version 4).

`generate_track_xml(seed, length_m, width_m)` draws a random star-shaped polygon, rounds every
corner with a constant-radius arc (a fillet tangent to both edges) and scales the polygon so the
centre line has the requested length. Straights and arcs tangent to each other close exactly by
construction; after the numbers are rounded for writing, two straights are re-solved so the
written track closes to ~1e-4 m and its headings sum to exactly 360 deg. A layout whose outer
edges (road + curb + verge, where the barriers stand) cross themselves is redrawn; elevation is a
smooth periodic sum of sines, so heights and slopes close too.

Only `numpy.random.default_rng(seed)` supplies randomness: the same arguments give byte-identical
text. The output is read by `madsim.tracks.load_track` and by real TORCS (checked with trackgen).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

__all__ = ["generate_track_xml", "write_generated_track"]

BORDER_W = 1.0          # curb width on both sides, m
SIDE_W = 4.0            # grass verge width on both sides, m (the barrier stands at its outer edge)
STEP_M = 5.0            # profil steps length, m
EDGE_MARGIN_M = 1.0     # extra clearance added to both outer edges in the crossing test, m
MAX_ATTEMPTS = 200      # layouts drawn before giving up

_NAME_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")

# (name, friction, rolling resistance, rebound, dammage); rebound/dammage None = TORCS default
_SURFACES = (
    ("gen-tarmac", 1.2, 0.001, None, None),
    ("gen-kerb", 1.1, 0.002, None, None),
    ("gen-grass", 0.45, 0.012, None, None),
    ("gen-wall", 0.05, 0.0, 0.3, 5.0),
)


# --- inputs ---------------------------------------------------------------------------------


def _check_inputs(seed, length_m, width_m, name, max_grade) -> str:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    for label, value in (("length_m", length_m), ("width_m", width_m), ("max_grade", max_grade)):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
                or not math.isfinite(value):
            raise ValueError(f"{label} must be a finite number, got {value!r}")
    if not 300.0 <= length_m <= 25_000.0:
        raise ValueError(f"length_m must be between 300 and 25000 m, got {length_m}")
    if not 3.0 <= width_m <= 30.0:
        raise ValueError(f"width_m must be between 3 and 30 m, got {width_m}")
    if width_m > length_m / 25.0:
        raise ValueError(f"width_m={width_m} is too wide for a {length_m} m track "
                         f"(at most length/25 = {length_m / 25.0:.1f} m)")
    if not 0.0 <= max_grade <= 0.15:
        raise ValueError(f"max_grade must be between 0 and 0.15 (15 %), got {max_grade}")
    if name is None:
        name = f"madsim-gen-{int(seed)}"
    if not isinstance(name, str) or not _NAME_RE.fullmatch(name):
        raise ValueError(f"name must be letters, digits, '-', '_' or '.', starting with a letter "
                         f"or digit (it becomes a file name), got {name!r}")
    return name


# --- layout: polygon -> straights and fillet arcs --------------------------------------------


def _wrap(a):
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def _draw_polygon(rng: np.random.Generator, length_m: float) -> np.ndarray:
    """Vertices (K, 2) of a counter-clockwise star-shaped polygon of mean radius 1."""
    k_lo = min(max(4, round(length_m / 550.0)), 24)
    k_hi = min(max(k_lo + 2, round(length_m / 220.0)), 30)
    k = int(rng.integers(k_lo, k_hi + 1))
    ang = 2.0 * np.pi * (np.arange(k) + rng.uniform(-0.35, 0.35, k)) / k
    rho = rng.uniform(0.45, 1.35, k)
    return np.column_stack([rho * np.cos(ang), rho * np.sin(ang)])


def _turns(poly: np.ndarray):
    """Edge lengths (K,), edge headings (K,) and turning angle at each vertex (K,), rad.

    Edge k runs from vertex k to k+1; the turn at vertex k joins edge k-1 to edge k.
    Vertices turning less than 4 deg are dropped first (they would make useless tiny arcs).
    """
    while True:
        d = np.roll(poly, -1, axis=0) - poly
        heading = np.arctan2(d[:, 1], d[:, 0])
        turn = _wrap(heading - np.roll(heading, 1))
        keep = np.abs(turn) >= math.radians(4.0)
        if keep.all() or keep.sum() < 3:
            return np.hypot(d[:, 0], d[:, 1]), heading, turn
        poly = poly[keep]


def _fillets(scale, edge, turn, r_want):
    """Radii (K,) and tangent lengths (K,) of the corner arcs for a polygon scaled by `scale`.

    A corner may use at most 45 % of each adjacent edge, so every straight keeps >= 10 %.
    """
    tan_half = np.tan(np.abs(turn) / 2.0)
    room = 0.45 * scale * np.minimum(edge, np.roll(edge, 1))
    radius = np.minimum(r_want, room / tan_half)
    return radius, radius * tan_half


def _centre_length(scale, edge, turn, r_want) -> float:
    radius, tangent = _fillets(scale, edge, turn, r_want)
    straight = scale * edge - tangent - np.roll(tangent, -1)
    return float(straight.sum() + (radius * np.abs(turn)).sum())


def _draw_layout(rng, length_m: float, r_min: float):
    """One random layout as a list of pieces, or None when its corners come out too tight.

    Pieces are ("str", length, 0) or ("lft"/"rgt", radius, arc_rad); the first and last are the
    two halves of the longest straight, so the track starts heading +x in mid-straight.
    """
    edge, _, turn = _turns(_draw_polygon(rng, length_m))
    if abs(turn.sum() - 2.0 * np.pi) > 1e-6:   # not a simple counter-clockwise loop
        return None
    r_max = max(1.5 * r_min, 0.1 * length_m)
    r_want = np.exp(rng.uniform(math.log(r_min), math.log(r_max), edge.size))
    lo, hi = 1e-3, length_m
    for _ in range(80):  # the centre length grows with the scale: bisect for the target
        mid = 0.5 * (lo + hi)
        if _centre_length(mid, edge, turn, r_want) < length_m:
            lo = mid
        else:
            hi = mid
    scale = 0.5 * (lo + hi)
    radius, tangent = _fillets(scale, edge, turn, r_want)
    if radius.min() < r_min:
        return None
    straight = scale * edge - tangent - np.roll(tangent, -1)   # straight k lies on edge k
    if straight.min() < 1.0:
        return None
    first = int(np.argmax(straight))
    k = edge.size
    pieces = [("str", straight[first] / 2.0, 0.0)]
    for j in range(1, k + 1):
        v = (first + j) % k                       # vertex at the end of edge v-1
        kind = "lft" if turn[v] > 0 else "rgt"
        pieces.append((kind, float(radius[v]), float(abs(turn[v]))))
        length = straight[v] / 2.0 if v == first else straight[v]
        pieces.append(("str", float(length), 0.0))
    return pieces


# --- exact closure after rounding ------------------------------------------------------------


def _integrate(pieces):
    """End position (2,) and heading of the centre line, plus the heading of every piece start."""
    x = y = a = 0.0
    starts = []
    for kind, p, arc in pieces:
        starts.append(a)
        if kind == "str":
            x, y = x + p * math.cos(a), y + p * math.sin(a)
            continue
        sign = 1.0 if kind == "lft" else -1.0
        cx, cy = x - sign * p * math.sin(a), y + sign * p * math.cos(a)
        a += sign * arc
        x, y = cx + sign * p * math.sin(a), cy - sign * p * math.cos(a)
    return np.array([x, y]), a, starts


def _round_and_close(pieces):
    """Pieces with written values: radii to 1 cm, arcs to 1e-6 deg summing to exactly 360 deg,
    straights to 0.1 mm with the last straight and the most sideways one solved for closure."""
    out = []
    micro = []
    for kind, p, arc in pieces:
        if kind == "str":
            out.append([kind, p, 0.0])
        else:
            out.append([kind, round(p, 2), 0.0])
            micro.append(round(math.degrees(arc) * 1e6) * (1 if kind == "lft" else -1))
    micro[-1] += 360_000_000 - sum(micro)       # turning of a closed CCW loop
    curves = [row for row in out if row[0] != "str"]
    for row, m in zip(curves, micro):
        row[0] = "lft" if m > 0 else "rgt"
        row[2] = math.radians(abs(m) * 1e-6)
    gap, _, starts = _integrate(out)
    side = max((i for i, row in enumerate(out[:-1]) if row[0] == "str"),
               key=lambda i: abs(math.sin(starts[i])))
    db = -gap[1] / math.sin(starts[side])
    da = -gap[0] - db * math.cos(starts[side])
    out[side][1] += db
    out[-1][1] += da
    for row in out:
        if row[0] == "str":
            row[1] = round(row[1], 4)
    return [tuple(row) for row in out], micro


# --- self-intersection -----------------------------------------------------------------------


def _outer_edges(pieces, offset: float, step: float = 3.0):
    """Left and right polylines (N, 2) at +-offset from the centre line, sampled every <= step m."""
    pts, heads = [], []
    x = y = a = 0.0
    for kind, p, arc in pieces:
        if kind == "str":
            u = np.linspace(0.0, p, max(2, math.ceil(p / step) + 1))[:-1]
            pts.append(np.column_stack([x + u * math.cos(a), y + u * math.sin(a)]))
            heads.append(np.full(u.size, a))
            x, y = x + p * math.cos(a), y + p * math.sin(a)
            continue
        sign = 1.0 if kind == "lft" else -1.0
        cx, cy = x - sign * p * math.sin(a), y + sign * p * math.cos(a)
        t = np.linspace(0.0, arc, max(2, math.ceil(p * arc / step) + 1))[:-1]
        h = a + sign * t
        pts.append(np.column_stack([cx + sign * p * np.sin(h), cy - sign * p * np.cos(h)]))
        heads.append(h)
        a += sign * arc
        x, y = cx + sign * p * math.sin(a), cy - sign * p * math.cos(a)
    c, h = np.concatenate(pts), np.concatenate(heads)
    normal = np.column_stack([-np.sin(h), np.cos(h)])
    return c + offset * normal, c - offset * normal


def _edges_cross(left: np.ndarray, right: np.ndarray) -> bool:
    """True if any two non-adjacent segments of the closed polylines `left`, `right` intersect.

    Candidate pairs come from a uniform grid of cells at least one segment long: two segments
    that meet have midpoints in the same or neighbouring cells.
    """
    p = np.concatenate([left, right])
    q = np.concatenate([np.roll(left, -1, axis=0), np.roll(right, -1, axis=0)])
    owner = np.repeat([0, 1], [len(left), len(right)])
    index = np.concatenate([np.arange(len(left)), np.arange(len(right))])
    size = np.where(owner == 0, len(left), len(right))
    cell = float(np.hypot(*(q - p).T).max()) + 1e-9
    ij = np.floor((p + q) / 2.0 / cell).astype(np.int64)
    ij -= ij.min(axis=0) - 1                     # cells 1..n, so neighbours stay >= 0
    stride = int(ij[:, 1].max()) + 2
    key = ij[:, 0] * stride + ij[:, 1]
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    box_lo, box_hi = np.minimum(p, q), np.maximum(p, q)

    def orient(a, b, c):
        return np.sign((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))

    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            target = key + dx * stride + dy
            lo = np.searchsorted(sorted_key, target, side="left")
            count = np.searchsorted(sorted_key, target, side="right") - lo
            i = np.repeat(np.arange(len(p)), count)
            rank = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
            j = order[np.repeat(lo, count) + rank]
            gap = np.abs(index[i] - index[j])
            keep = (j > i) & ~((owner[i] == owner[j]) & ((gap <= 1) | (gap == size[i] - 1)))
            keep &= np.all(box_lo[j] <= box_hi[i], axis=1) & np.all(box_hi[j] >= box_lo[i], axis=1)
            i, j = i[keep], j[keep]
            d1 = orient(p[i], q[i], p[j]) * orient(p[i], q[i], q[j])
            d2 = orient(p[j], q[j], p[i]) * orient(p[j], q[j], q[i])
            if np.any((d1 <= 0) & (d2 <= 0)):
                return True
    return False


# --- elevation -------------------------------------------------------------------------------


def _elevation(rng, total: float, max_grade: float):
    """z(s) and dz/ds(s) callables: three periodic harmonics, z(0) = 0, |dz/ds| <= max_grade."""
    amp = rng.uniform(0.2, 1.0, 3) / np.arange(1, 4)
    phase = rng.uniform(0.0, 2.0 * np.pi, 3)
    w = 2.0 * np.pi * np.arange(1, 4) / total
    s = np.linspace(0.0, total, 2049)
    slope = (amp * w * np.cos(np.outer(s, w) + phase)).sum(axis=1)
    amp = amp * (max_grade * rng.uniform(0.4, 1.0) / max(np.abs(slope).max(), 1e-12))
    z0 = float((amp * np.sin(phase)).sum())
    return (lambda x: float((amp * np.sin(w * x + phase)).sum()) - z0,
            lambda x: float((amp * w * np.cos(w * x + phase)).sum()))


# --- XML -------------------------------------------------------------------------------------


def _fmt(value: float, digits: int) -> str:
    text = f"{value:.{digits}f}"
    return f"{0.0:.{digits}f}" if float(text) == 0.0 else text   # no "-0.000"


def _xml(name, seed, width, pieces, micro, z, dz) -> str:
    total = sum(p if k == "str" else p * arc for k, p, arc in pieces)
    out = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f"<!-- Generated by madsim.tracks.generate (seed {seed}): do not edit by hand. -->",
        f'<params name="{name}" type="trackdef" mode="mw">',
        '  <section name="Header">',
        f'    <attstr name="name" val="{name}"/>',
        '    <attstr name="category" val="road"/>',
        '    <attnum name="version" val="4"/>',
        '    <attstr name="author" val="madsim"/>',
        f'    <attstr name="description" val="Procedural track, seed {seed}, '
        f'{total:.0f} m, {width:g} m wide"/>',
        "  </section>",
        '  <section name="Surfaces">',
    ]
    for sname, fr, rr, rebound, dammage in _SURFACES:
        out.append(f'    <section name="{sname}">')
        out.append(f'      <attnum name="friction" val="{fr:g}"/>')
        out.append(f'      <attnum name="rolling resistance" val="{rr:g}"/>')
        if rebound is not None:
            out.append(f'      <attnum name="rebound" val="{rebound:g}"/>')
        if dammage is not None:
            out.append(f'      <attnum name="dammage" val="{dammage:g}"/>')
        out.append("    </section>")
    out += [
        "  </section>",
        '  <section name="Graphic">',
        '    <section name="Terrain Generation">',
        '      <attnum name="track step" unit="m" val="20"/>',
        '      <attnum name="border margin" unit="m" val="50"/>',
        '      <attnum name="border step" unit="m" val="30"/>',
        '      <attnum name="border height" unit="m" val="10"/>',
        '      <attstr name="surface" val="gen-grass"/>',
        "    </section>",
        "  </section>",
        '  <section name="Main Track">',
        f'    <attnum name="width" unit="m" val="{width:g}"/>',
        '    <attstr name="surface" val="gen-tarmac"/>',
        f'    <attnum name="profil steps length" unit="m" val="{STEP_M:g}"/>',
    ]
    for side in ("Left", "Right"):
        out += [
            f'    <section name="{side} Side">',
            f'      <attnum name="width" unit="m" val="{SIDE_W:g}"/>',
            '      <attstr name="surface" val="gen-grass"/>',
            "    </section>",
            f'    <section name="{side} Border">',
            f'      <attnum name="width" unit="m" val="{BORDER_W:g}"/>',
            '      <attnum name="height" unit="m" val="0.05"/>',
            '      <attstr name="surface" val="gen-kerb"/>',
            '      <attstr name="style" val="curb"/>',
            "    </section>",
            f'    <section name="{side} Barrier">',
            '      <attnum name="width" unit="m" val="0.5"/>',
            '      <attnum name="height" unit="m" val="1"/>',
            '      <attstr name="surface" val="gen-wall"/>',
            '      <attstr name="style" val="wall"/>',
            "    </section>",
        ]
    out.append('    <section name="Track Segments">')
    s = 0.0
    arcs = iter(micro)
    n_str = n_turn = 0
    for i, (kind, p, arc) in enumerate(pieces):
        if kind == "str":
            n_str += 1
            seg = "start" if i == 0 else "finish" if i == len(pieces) - 1 else f"straight {n_str - 1}"
            body = [f'<attnum name="lg" unit="m" val="{p:.4f}"/>']
            s += p
        else:
            n_turn += 1
            seg = f"turn {n_turn}"
            body = [f'<attnum name="radius" unit="m" val="{p:.2f}"/>',
                    f'<attnum name="arc" unit="deg" val="{abs(next(arcs)) / 1e6:.6f}"/>']
            s += p * arc
        if i == 0:
            body += [f'<attnum name="z start" unit="m" val="{_fmt(z(0.0), 3)}"/>',
                     f'<attnum name="profil start tangent" unit="%" val="{_fmt(100 * dz(0.0), 4)}"/>']
        s_end = 0.0 if i == len(pieces) - 1 else s     # the loop ends where it started
        body += [f'<attnum name="z end" unit="m" val="{_fmt(z(s_end), 3)}"/>',
                 f'<attnum name="profil end tangent" unit="%" val="{_fmt(100 * dz(s_end), 4)}"/>']
        out.append(f'      <section name="{seg}">')
        out.append(f'        <attstr name="type" val="{kind}"/>')
        out += ["        " + line for line in body]
        out.append("      </section>")
    out += ["    </section>", "  </section>", "</params>", ""]
    return "\n".join(out)


# --- public ----------------------------------------------------------------------------------


def generate_track_xml(seed: int, length_m: float = 3000.0, width_m: float = 12.0,
                       name: str | None = None, *, max_grade: float = 0.03) -> str:
    """TORCS v4 XML text of a random closed road course.

    seed: non-negative int for `numpy.random.default_rng`; equal arguments give identical text.
    length_m: centre-line length, m (300-25000; the result is within 1 %, typically 0.01 %).
    width_m: road width, m (3-30 and at most length_m / 25); every corner radius is >= the
    width and > the distance from the centre line to the barrier, so no edge folds.
    name: track name (default "madsim-gen-<seed>"); `max_grade`: largest slope dz/ds (0 = flat).
    Raises ValueError on bad inputs, or if no layout clears itself within MAX_ATTEMPTS draws.
    """
    name = _check_inputs(seed, length_m, width_m, name, max_grade)
    length_m, width_m = float(length_m), float(width_m)
    rng = np.random.default_rng(int(seed))
    half_out = width_m / 2.0 + BORDER_W + SIDE_W
    r_min = max(width_m, half_out + 2.0)
    for _ in range(MAX_ATTEMPTS):
        raw = _draw_layout(rng, length_m, r_min)
        if raw is None:
            continue
        pieces, micro = _round_and_close(raw)
        if not _edges_cross(*_outer_edges(pieces, half_out + EDGE_MARGIN_M)):
            break
    else:
        raise ValueError(f"no self-clearing layout found in {MAX_ATTEMPTS} draws for "
                         f"seed={seed}, length_m={length_m}, width_m={width_m}")
    total = sum(p if k == "str" else p * arc for k, p, arc in pieces)
    z, dz = _elevation(rng, total, float(max_grade))
    return _xml(name, int(seed), width_m, pieces, micro, z, dz)


def write_generated_track(seed: int, path: str | Path, **kw) -> Path:
    """Write `generate_track_xml(seed, **kw)` to `path` (a .xml file; folders are created).

    The track name defaults to the file stem; TORCS itself wants the file at
    `<folder named like the track>/<name>.xml`. Returns the path written.
    """
    path = Path(path)
    if path.suffix != ".xml":
        raise ValueError(f"path must name an .xml file, got '{path}'")
    kw.setdefault("name", path.stem)
    text = generate_track_xml(seed, **kw)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path
