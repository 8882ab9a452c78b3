"""madsim's compiled track form (`.mtrack`) and writing a Track back to TORCS XML.

A `.mtrack` file is a numpy `.npz` archive holding the piece table (pre-translation) and a JSON
header; loading it skips XML parsing and takes milliseconds. `track_to_xml` writes one TORCS v4
segment per piece with explicit edge heights and a linear profile, so TORCS rebuilds exactly the
same pieces (length kept to float32 rounding).
"""

from __future__ import annotations

import io
import json
import os
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from madsim.tracks.build import COL, KIND_NAMES, PIECE_COLUMNS, STRAIGHT, STYLE_FENCE, BuildResult, Surface
from madsim.tracks.errors import TrackError
from madsim.tracks.track import Track, translate_pieces

FORMAT = "madsim-track"
FORMAT_VERSION = 1


def save_compiled(track: Track, path: str | os.PathLike) -> None:
    """Write `track` to a compact `.mtrack` file."""
    p = np.array(track.pieces)
    translate_pieces(p, *(-v for v in track.offset))   # store the file's own coordinates
    header = {
        "format": FORMAT, "format_version": FORMAT_VERSION, "columns": list(PIECE_COLUMNS),
        "name": track.name, "title": track.title, "category": track.category, "version": track.version,
        "author": track.author, "description": track.description, "width": track.width,
        "length": track.length, "piece_names": list(track.piece_names),
        "surfaces": [s.__dict__ for s in track.surfaces],
        "side_bank_tangent": list(track.side_bank_tangent), "grid": track.grid, "pits": track.pits,
    }
    buf = io.BytesIO()
    np.savez_compressed(buf, pieces=p, header=np.frombuffer(json.dumps(header).encode(), dtype=np.uint8))
    Path(path).write_bytes(buf.getvalue())


def load_compiled(path: str | os.PathLike) -> Track:
    """Read a `.mtrack` file written by `save_compiled`."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            header = json.loads(bytes(data["header"]).decode())
            pieces = np.array(data["pieces"], dtype=np.float64)
    except Exception as exc:  # any fault in a foreign file is a TrackError
        raise TrackError(f"not a readable madsim compiled track ({type(exc).__name__}: {exc})",
                         file=str(path)) from None
    if header.get("format") != FORMAT or header.get("columns") != list(PIECE_COLUMNS):
        raise TrackError("not a madsim compiled track of this version", file=str(path), element="header")
    if pieces.ndim != 2 or pieces.shape[1] != len(PIECE_COLUMNS) or pieces.shape[0] == 0:
        raise TrackError(f"piece table has shape {pieces.shape}", file=str(path), element="pieces")
    built = BuildResult(
        name=header["title"], category=header["category"], version=header["version"],
        author=header["author"], description=header["description"], width=header["width"],
        length=header["length"], pieces=pieces, piece_names=header["piece_names"],
        surfaces=[Surface(**s) for s in header["surfaces"]],
        side_bank_tangent=tuple(header["side_bank_tangent"]), grid=header["grid"], pits=header["pits"],
    )
    return Track.from_build(built, source=str(path), name=header["name"])


def _num(name: str, value: float, unit: str | None = None) -> str:
    u = f' unit="{unit}"' if unit else ""
    return f'<attnum name="{name}"{u} val="{float(np.float32(value))!r}"/>'


def _str(name: str, value: str) -> str:
    return f"<attstr name={quoteattr(name)} val={quoteattr(value)}/>"


def track_to_xml(track: Track) -> str:
    """TORCS v4 XML that rebuilds `track` piece for piece (self-contained, surfaces inline)."""
    srf = track.surfaces
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           f"<params name={quoteattr(track.name)} type=\"param\" mode=\"mw\">",
           '  <section name="Header">',
           f"    {_str('name', track.title)}", f"    {_str('category', track.category)}",
           f"    {_num('version', 4)}", f"    {_str('author', track.author or 'madsim')}",
           f"    {_str('description', track.description)}",
           "  </section>",
           # TORCS's tools (trackgen, the 3D description builder) need a Graphic section.
           '  <section name="Graphic">', f"    {_str('3d description', track.name + '.ac')}",
           '    <section name="Terrain Generation">', f"      {_num('track step', 20, 'm')}",
           f"      {_num('border margin', 50, 'm')}", f"      {_num('border step', 30, 'm')}",
           f"      {_num('border height', 15, 'm')}", f"      {_str('orientation', 'clockwise')}",
           "    </section>", "  </section>",
           '  <section name="Surfaces">']
    for s in srf:
        out += [f"    <section name={quoteattr(s.name)}>",
                f"      {_num('friction', s.friction)}", f"      {_num('rolling resistance', s.rolling_resistance)}",
                f"      {_num('roughness', s.roughness * 2)}",
                f"      {_num('roughness wavelength', s.roughness_wavelength)}",
                f"      {_num('dammage', s.dammage)}", f"      {_num('rebound', s.rebound)}",
                "    </section>"]
    out.append("  </section>")
    p0 = track.pieces[0]
    out += ['  <section name="Main Track">', f"    {_num('width', track.width, 'm')}",
            f"    {_str('surface', srf[int(p0[COL['surface']])].name)}",
            f"    {_num('profil steps length', 0, 'm')}"]
    for side, sfx in (("Right", "r"), ("Left", "l")):
        tangent = track.side_bank_tangent[0 if sfx == "r" else 1]
        out += [f'    <section name="{side} Side">',
                f"      {_num('width', p0[COL[f'side_w0_{sfx}']], 'm')}",
                f"      {_str('surface', srf[int(p0[COL[f'side_surf_{sfx}']])].name)}",
                f"      {_str('banking type', 'tangent' if tangent else 'level')}", "    </section>"]
    out.append('    <section name="Track Segments">')
    dx, dy, dz = track.offset
    for i, p in enumerate(track.pieces):
        kind = int(p[COL["kind"]])
        seg = track.piece_names[int(p[COL["seg"]])]
        out.append(f"      <section name={quoteattr(f'{i:05d} {seg}')}>")
        out.append(f"        {_str('type', KIND_NAMES[kind])}")
        if kind == STRAIGHT:
            out.append(f"        {_num('lg', p[COL['length']], 'm')}")
        else:
            out.append(f"        {_num('radius', p[COL['radius']], 'm')}")
            out.append(f"        {_num('arc', p[COL['arc']], 'rad')}")
        out.append(f"        {_str('surface', srf[int(p[COL['surface']])].name)}")
        for key, col in (("z start left", "zl0"), ("z start right", "zr0"),
                         ("z end left", "zl1"), ("z end right", "zr1")):
            out.append(f"        {_num(key, p[COL[col]] - dz, 'm')}")
        out.append(f"        {_str('profil', 'linear')}")
        for side, sfx in (("Right", "r"), ("Left", "l")):
            style = {0: "plan", 1: "curb", 2: "wall"}.get(int(p[COL[f"border_style_{sfx}"]]), "plan")
            barrier_fence = int(p[COL[f"barrier_style_{sfx}"]]) == STYLE_FENCE
            out += [f'        <section name="{side} Side">',
                    f"          {_num('start width', p[COL[f'side_w0_{sfx}']], 'm')}",
                    f"          {_num('end width', p[COL[f'side_w1_{sfx}']], 'm')}",
                    f"          {_str('surface', srf[int(p[COL[f'side_surf_{sfx}']])].name)}",
                    "        </section>",
                    f'        <section name="{side} Border">',
                    f"          {_num('width', p[COL[f'border_w_{sfx}']], 'm')}",
                    f"          {_num('height', p[COL[f'border_h_{sfx}']], 'm')}",
                    f"          {_str('surface', srf[int(p[COL[f'border_surf_{sfx}']])].name)}",
                    f"          {_str('style', style)}",
                    "        </section>",
                    f'        <section name="{side} Barrier">',
                    f"          {_num('height', p[COL[f'barrier_h_{sfx}']], 'm')}",
                    f"          {_str('surface', srf[int(p[COL[f'barrier_surf_{sfx}']])].name)}",
                    f"          {_str('style', 'fence' if barrier_fence else 'wall')}",
                    *([] if barrier_fence else [f"          {_num('width', p[COL[f'barrier_w_{sfx}']], 'm')}"]),
                    "        </section>"]
        out.append("      </section>")
    out += ["    </section>", "  </section>", "</params>", ""]
    return "\n".join(out)
