"""TORCS track XML -> a table of pieces (spec/torcs-track-format.md sections 2-9, 12).

A *piece* is one TORCS track segment after `profil steps` sub-division: a straight or a
constant-radius arc of the centre line, with its edge heights, side/border/barrier settings and
start distance. `build_pieces` reproduces TORCS's carry-over rules for both reader versions
(v0-3 and v4); the planar geometry and elevation are identical in both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from madsim.torcsxml import Section

STRAIGHT, LEFT, RIGHT = 0, 1, 2
_KINDS = {"str": STRAIGHT, "lft": LEFT, "rgt": RIGHT}
KIND_NAMES = {v: k for k, v in _KINDS.items()}

STYLE_PLAN, STYLE_CURB, STYLE_WALL, STYLE_FENCE = 0, 1, 2, 3
_STYLES = {"plan": STYLE_PLAN, "curb": STYLE_CURB, "wall": STYLE_WALL, "fence": STYLE_FENCE}

# Piece table columns (float64). Angles in rad, lengths in m; side index 0 = right, 1 = left.
PIECE_COLUMNS = (
    "kind", "seg", "s0", "length", "radius", "arc", "x0", "y0", "a0", "cx", "cy",
    "zr0", "zl0", "zr1", "zl1", "surface",
    "border_w_r", "border_w_l", "border_h_r", "border_h_l", "border_style_r", "border_style_l",
    "border_surf_r", "border_surf_l",
    "side_w0_r", "side_w1_r", "side_w0_l", "side_w1_l", "side_surf_r", "side_surf_l",
    "barrier_surf_r", "barrier_surf_l", "barrier_style_r", "barrier_style_l",
    "barrier_h_r", "barrier_h_l", "barrier_w_r", "barrier_w_l",
)
COL = {name: i for i, name in enumerate(PIECE_COLUMNS)}


class BuildError(ValueError):
    """A track file describes something that cannot be built; carries the element at fault."""

    def __init__(self, message: str, element: str):
        self.element = element
        super().__init__(message)


@dataclass(frozen=True)
class Surface:
    """A track material: tyre friction factor, rolling resistance, wall rebound, damage factor."""

    name: str
    friction: float = 0.8
    rolling_resistance: float = 0.001
    roughness: float = 0.0
    roughness_wavelength: float = 1.0
    dammage: float = 10.0
    rebound: float = 0.5


@dataclass
class BuildResult:
    """Everything read from a track file: metadata, surface table, piece table, extras."""

    name: str
    category: str
    version: int
    author: str
    description: str
    width: float
    length: float                      # TORCS float32 running sum of piece lengths
    pieces: np.ndarray                 # (P, len(PIECE_COLUMNS)) float64
    piece_names: list[str]             # XML segment name per XML segment index
    surfaces: list[Surface]
    side_bank_tangent: tuple[bool, bool]   # (right, left): side continues the road's cross slope
    grid: dict = field(default_factory=dict)
    pits: dict = field(default_factory=dict)


class _Surfaces:
    """Interns material names to indices, reading their properties on first use."""

    def __init__(self, root: Section, version: int):
        self.table: list[Surface] = []
        self.index: dict[str, int] = {}
        base = root.sub("Surfaces/List") if version < 4 else root.sub("Surfaces")
        self.defs = base if base is not None else Section("Surfaces", "Surfaces")
        self.rebound_default = 1.0 if version < 4 else 0.5

    def __call__(self, name: str) -> int:
        if name not in self.index:
            sec = self.defs.children.get(name) or Section(name, name)
            wl = sec.num("roughness wavelength", 1.0)
            self.table.append(Surface(
                name=name,
                friction=sec.num("friction", 0.8),
                rolling_resistance=sec.num("rolling resistance", 0.001),
                roughness=sec.num("roughness", 0.0) / 2.0,
                roughness_wavelength=wl if wl else 1.0,
                dammage=sec.num("dammage", 10.0),
                rebound=sec.num("rebound", self.rebound_default),
            ))
            self.index[name] = len(self.table) - 1
        return self.index[name]


def _style(text: str | None, default: int) -> int:
    if text is None:
        return default
    return _STYLES.get(text, STYLE_WALL if text not in ("plan", "curb", "fence") else default)


class _Sides:
    """Side/border/barrier state carried from segment to segment, per reader version."""

    def __init__(self, main: Section, version: int, surf: _Surfaces):
        self.v4 = version >= 4
        self.surf = surf
        self.side_end_w = [0.0, 0.0]
        self.side_start_w = [0.0, 0.0]
        self.side_surf = [0, 0]
        self.bank_tangent = [False, False]
        self.border_w = [0.0, 0.0]
        self.border_h = [0.0, 0.0]
        self.border_style = [STYLE_PLAN, STYLE_PLAN]
        self.border_surf = [0, 0]
        self.barrier_surf = [0, 0]
        self.barrier_style = [STYLE_FENCE, STYLE_FENCE]
        self.barrier_h = [0.0, 0.0]
        self.barrier_w = [0.0, 0.0]
        for side in (0, 1):
            if self.v4:
                name = ("Right", "Left")[side]
                sides = main.sub(f"{name} Side") or Section("", "")
                border = main.sub(f"{name} Border") or Section("", "")
                barrier = main.sub(f"{name} Barrier") or Section("", "")
                g = lambda sec, key, d: sec.num(key, d)  # noqa: E731
                gs = lambda sec, key, d: sec.str(key, d)  # noqa: E731
                self.side_surf[side] = surf(gs(sides, "surface", "grass"))
                self.side_end_w[side] = g(sides, "width", 0.0)
                self.bank_tangent[side] = gs(sides, "banking type", "level") != "level"
                self.border_surf[side] = surf(gs(border, "surface", "grass"))
                self.border_w[side] = g(border, "width", 0.0)
                self.border_h[side] = g(border, "height", 0.0)
                self.border_style[side] = _style(gs(border, "style", "plan"), STYLE_PLAN)
                self.barrier_surf[side] = surf(gs(barrier, "surface", "barrier"))
                self.barrier_h[side] = g(barrier, "height", 0.6)
                self.barrier_style[side] = STYLE_FENCE if gs(barrier, "style", "fence") == "fence" else STYLE_WALL
                self.barrier_w[side] = 0.0 if self.barrier_style[side] == STYLE_FENCE else g(barrier, "width", 0.5)
            else:
                p = "rl"[side]
                self.side_surf[side] = surf(main.str(f"{p}side surface", "grass"))
                self.side_end_w[side] = main.num(f"{p}side width", 0.0)
                self.bank_tangent[side] = main.str(f"{p}side type", "level") != "level"
                self.border_surf[side] = surf(main.str(f"{p}border surface", "grass"))
                self.border_w[side] = main.num(f"{p}border width", 0.0)
                self.border_h[side] = main.num(f"{p}border height", 0.0)
                self.border_style[side] = _style(main.str(f"{p}border style", "plan"), STYLE_PLAN)
                self.barrier_surf[side] = surf(main.str(f"{p}barrier surface", "barrier"))
                self.barrier_h[side] = main.num(f"{p}barrier height", 1.0)
                style = main.str(f"{p}barrier style", "fence")
                self.barrier_style[side] = STYLE_FENCE if style == "fence" else STYLE_WALL
                self.barrier_w[side] = 0.0 if style == "fence" else main.num(f"{p}barrier width", 0.5)

    def update(self, seg: Section) -> None:
        """Apply one XML segment's side settings (carry rules of spec section 6 / 9)."""
        for side in (0, 1):
            if self.v4:
                name = ("Right", "Left")[side]
                sides = seg.sub(f"{name} Side") or Section("", "")
                sw = sides.num("start width", self.side_end_w[side])
                w = sides.num("width", sw)
                ew = sides.num("end width", w)
                self.side_surf[side] = self.surf(sides.str("surface", None) or self.surf.table[self.side_surf[side]].name)
                border = seg.sub(f"{name} Border") or Section("", "")
                self.border_w[side] = border.num("width", self.border_w[side])
                self.border_h[side] = border.num("height", self.border_h[side])
                if border.str("surface") is not None:
                    self.border_surf[side] = self.surf(border.str("surface"))
                self.border_style[side] = _style(border.str("style"), self.border_style[side])
                barrier = seg.sub(f"{name} Barrier") or Section("", "")
                if barrier.str("surface") is not None:
                    self.barrier_surf[side] = self.surf(barrier.str("surface"))
                self.barrier_h[side] = barrier.num("height", self.barrier_h[side])
                style = barrier.str("style")
                if style is not None:
                    self.barrier_style[side] = STYLE_FENCE if style == "fence" else STYLE_WALL
                if self.barrier_style[side] == STYLE_FENCE:
                    self.barrier_w[side] = 0.0
                else:
                    self.barrier_w[side] = barrier.num("width", self.barrier_w[side] or 0.5)
            else:
                p = "rl"[side]
                sw = seg.num(f"{p}side start width", self.side_end_w[side])
                ew = seg.num(f"{p}side end width", sw)
                if seg.str(f"{p}side surface") is not None:
                    self.side_surf[side] = self.surf(seg.str(f"{p}side surface"))
                self.border_w[side] = seg.num(f"{p}border width", self.border_w[side])
                self.border_h[side] = seg.num(f"{p}border height", 0.0)  # v3: resets per segment
                if seg.str(f"{p}border surface") is not None:
                    self.border_surf[side] = self.surf(seg.str(f"{p}border surface"))
                self.border_style[side] = _style(seg.str(f"{p}border style"), self.border_style[side])
            self.side_start_w[side] = sw
            self.side_end_w[side] = ew


def _hermite(u: float, z0: float, z1: float, m0: float, m1: float, ln: float) -> float:
    h = 3 * u * u - 2 * u ** 3
    return (1 - h) * z0 + h * z1 + (u ** 3 - 2 * u * u + u) * m0 * ln + (u ** 3 - u * u) * m1 * ln


def _f32(v: float) -> float:
    return float(np.float32(v))


def build_pieces(root: Section) -> BuildResult:
    """Build the piece table from a parsed track file (raises BuildError on bad geometry)."""
    header = root.sub("Header") or Section("Header", "Header")
    version = int(header.num("version", 0) or 0)
    main = root.sub("Main Track")
    if main is None:
        raise BuildError("no 'Main Track' section", "section 'Main Track'")
    list_name = "Track Segments" if version >= 4 else "segments"
    seglist = main.sub(list_name)
    if seglist is None:
        other = "segments" if version >= 4 else "Track Segments"
        hint = (f"; the file has 'Main Track/{other}', which the reader for Header version "
                f"{'0-3' if other == 'segments' else '4'} uses" if main.sub(other) is not None else "")
        raise BuildError(f"no segment list 'Main Track/{list_name}' (Header version {version}){hint}",
                         f"section 'Main Track/{list_name}'")
    w = main.num("width", 15.0)
    if not (w > 0 and math.isfinite(w)):
        raise BuildError(f"track width must be positive, got {w}", "attnum 'width' in 'Main Track'")
    surf = _Surfaces(root, version)
    road_surface = surf(main.str("surface", "asphalt"))
    global_step_len = main.num("profil steps length", 0.0)
    sides = _Sides(main, version, surf)

    rows: list[list[float]] = []
    names: list[str] = []
    x, y, a = 0.0, w / 2.0, 0.0
    s32 = np.float32(0.0)
    zel = zer = 0.0
    tan_el = tan_er = 0.0
    grade: float | None = None

    for seg in seglist:
        kind_name = seg.str("type")
        if kind_name is None:
            continue  # TORCS skips children without a type
        where = f"segment '{seg.name}'"
        if kind_name not in _KINDS:
            raise BuildError(f"unknown segment type '{kind_name}' (expected str, lft or rgt)", where)
        kind = _KINDS[kind_name]
        names.append(seg.name)
        seg_index = len(names) - 1

        if kind == STRAIGHT:
            ln = seg.num("lg", 0.0)
            if not (ln > 0 and math.isfinite(ln)):
                raise BuildError(f"straight length 'lg' must be positive, got {ln}", where)
            r0 = r1 = arc = 0.0
        else:
            r0 = seg.num("radius", 0.0)
            r1 = seg.num("end radius", r0)
            arc = seg.num("arc", 0.0)
            for label, v in (("radius", r0), ("end radius", r1), ("arc", arc)):
                if not (v > 0 and math.isfinite(v)):
                    raise BuildError(f"curve '{label}' must be positive, got {v}", where)
            ln = (r0 + r1) / 2.0 * arc

        if seg.str("surface") is not None:
            road_surface = surf(seg.str("surface"))
        sides.update(seg)

        # --- elevation at the ends of the XML segment (spec 5.1) ---
        zsl = seg.num("z start left", zel)
        zsr = seg.num("z start right", zer)
        zel = seg.num("z end left", zel)
        zer = seg.num("z end right", zer)
        if seg.has("grade"):
            grade = seg.num("grade", 0.0)
        if seg.num("z start") is not None:
            zs = zsl = zsr = seg.num("z start")
        else:
            zs = (zsl + zsr) / 2.0
        if seg.num("z end") is not None:
            ze = zel = zer = seg.num("z end")
        elif grade is not None:
            ze = zs + ln * grade
        else:
            ze = (zel + zer) / 2.0
        bs = seg.num("banking start", math.atan2(zsl - zsr, w))
        be = seg.num("banking end", math.atan2(zel - zer, w))
        zsl, zsr = zs + math.tan(bs) * w / 2, zs - math.tan(bs) * w / 2
        zel, zer = ze + math.tan(be) * w / 2, ze - math.tan(be) * w / 2

        # --- profile tangents (spec 5.2) ---
        profil = seg.str("profil", "spline")
        if profil == "linear":
            t0l = t1l = (zel - zsl) / ln
            t0r = t1r = (zer - zsr) / ln
        else:
            ts = seg.num("profil start tangent", None)
            te = seg.num("profil end tangent", None)
            t0l = seg.num("profil start tangent left", ts if ts is not None else tan_el)
            t0r = seg.num("profil start tangent right", ts if ts is not None else tan_er)
            t1l = seg.num("profil end tangent left", te if te is not None else tan_el)
            t1r = seg.num("profil end tangent right", te if te is not None else tan_er)
        tan_el, tan_er = t1l, t1r

        # --- sub-division (spec 4.3, 4.4) ---
        if profil == "spline":
            n = int(seg.num("profil steps", 1.0))
            if n == 1:
                sl = seg.num("profil steps length", global_step_len)
                n = int(math.floor(ln / sl)) + 1 if sl > 0 else 1
        else:
            n = 1
        if n < 1:
            raise BuildError(f"'profil steps' must be >= 1, got {n}", where)
        if n > 100000:
            raise BuildError(f"segment would be cut into {n} pieces", where)

        if kind == STRAIGHT:
            radii = [0.0] * n
            lengths = [ln / n] * n
        elif r1 == r0:
            radii = [r0] * n
            lengths = [ln / n] * n
        elif n == 1:
            radii = [r0]            # TORCS quirk: one piece at the start radius, length Ln
            lengths = [ln]
        else:
            radii = [r0 + k * (r1 - r0) / (n - 1) for k in range(n)]
            piece_len = arc / sum(1.0 / r for r in radii)
            lengths = [piece_len] * n

        for k in range(n):
            length = _f32(lengths[k])
            rk = radii[k]
            d = length / rk if kind != STRAIGHT else 0.0
            cx = cy = 0.0
            if kind == STRAIGHT:
                xe, ye, ae = x + length * math.cos(a), y + length * math.sin(a), a
            elif kind == LEFT:
                cx, cy = x - rk * math.sin(a), y + rk * math.cos(a)
                ae = a + d
                xe, ye = cx + rk * math.sin(ae), cy - rk * math.cos(ae)
            else:
                cx, cy = x + rk * math.sin(a), y - rk * math.cos(a)
                ae = a - d
                xe, ye = cx - rk * math.sin(ae), cy + rk * math.cos(ae)
            u0, u1 = k / n, (k + 1) / n
            row = [0.0] * len(PIECE_COLUMNS)
            row[COL["kind"]] = kind
            row[COL["seg"]] = seg_index
            row[COL["s0"]] = float(s32)
            row[COL["length"]] = length
            row[COL["radius"]] = rk
            row[COL["arc"]] = d
            row[COL["x0"]], row[COL["y0"]], row[COL["a0"]] = x, y, a
            row[COL["cx"]], row[COL["cy"]] = cx, cy
            row[COL["zr0"]] = _hermite(u0, zsr, zer, t0r, t1r, ln)
            row[COL["zl0"]] = _hermite(u0, zsl, zel, t0l, t1l, ln)
            row[COL["zr1"]] = _hermite(u1, zsr, zer, t0r, t1r, ln)
            row[COL["zl1"]] = _hermite(u1, zsl, zel, t0l, t1l, ln)
            row[COL["surface"]] = road_surface
            for side, sfx in ((0, "r"), (1, "l")):
                sw, ew = sides.side_start_w[side], sides.side_end_w[side]
                row[COL[f"side_w0_{sfx}"]] = sw + k * (ew - sw) / n
                row[COL[f"side_w1_{sfx}"]] = sw + (k + 1) * (ew - sw) / n
                row[COL[f"side_surf_{sfx}"]] = sides.side_surf[side]
                row[COL[f"border_w_{sfx}"]] = sides.border_w[side]
                row[COL[f"border_h_{sfx}"]] = sides.border_h[side]
                row[COL[f"border_style_{sfx}"]] = sides.border_style[side]
                row[COL[f"border_surf_{sfx}"]] = sides.border_surf[side]
                row[COL[f"barrier_surf_{sfx}"]] = sides.barrier_surf[side]
                row[COL[f"barrier_style_{sfx}"]] = sides.barrier_style[side]
                row[COL[f"barrier_h_{sfx}"]] = sides.barrier_h[side]
                row[COL[f"barrier_w_{sfx}"]] = sides.barrier_w[side]
            rows.append(row)
            s32 = np.float32(s32 + np.float32(length))
            x, y, a = xe, ye, ae

    if not rows:
        raise BuildError(f"the segment list 'Main Track/{list_name}' holds no segment with a type",
                         f"section 'Main Track/{list_name}'")
    return BuildResult(
        name=header.str("name", root.name) or root.name,
        category=header.str("category", "road") or "road",
        version=version,
        author=header.str("author", "") or "",
        description=header.str("description", "") or "",
        width=w,
        length=float(s32),
        pieces=np.array(rows, dtype=np.float64),
        piece_names=names,
        surfaces=surf.table,
        side_bank_tangent=(sides.bank_tangent[0], sides.bank_tangent[1]),
        grid=_read_grid(root),
        pits=_read_pits(main, version),
    )


def _read_grid(root: Section) -> dict:
    sec = root.sub("Starting Grid")
    if sec is None:
        return {}
    out: dict = {}
    for key in ("rows", "distance to start", "distance between columns",
                "offset within a column", "initial height"):
        if sec.num(key) is not None:
            out[key] = sec.num(key)
    if sec.str("pole position side") is not None:
        out["pole position side"] = sec.str("pole position side")
    return out


def _read_pits(main: Section, version: int) -> dict:
    out: dict = {}
    if version >= 4:
        sec = main.sub("Pits")
        if sec is None:
            return out
        for k, v in sec.attrs.items():
            out[k] = getattr(v, "value")
    else:
        for k, v in main.attrs.items():
            if k.startswith("pit "):
                out[k[4:]] = getattr(v, "value")
    return out
