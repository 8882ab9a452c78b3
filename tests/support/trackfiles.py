"""Test support for tracks: TORCS data location, trackgen reference data, a tiny XML track writer."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

TORCS_ROOT = Path("/usr/share/games/torcs")
REFERENCE_CSV = Path(__file__).parent.parent / "tracks" / "data" / "torcs_trackgen_reference.csv"


def torcs_installed() -> bool:
    return (TORCS_ROOT / "tracks").is_dir()


def trackgen_available() -> bool:
    return Path("/usr/games/trackgen").exists() and shutil.which("xvfb-run") is not None


def reference_rows() -> list[tuple[str, str, float, float, float]]:
    """(category, name, length, closure dx, closure dy) measured with real TORCS trackgen."""
    rows = []
    for line in REFERENCE_CSV.read_text().splitlines():
        if line.startswith("#") or not line.strip():
            continue
        cat, name, length, dx, dy, _ = line.split(",")
        rows.append((cat, name, float(length), float(dx), float(dy)))
    return rows


def segment(name: str, kind: str, **attrs) -> str:
    """One `<section>` of a Track Segments list; numbers get unit m / deg as TORCS files use."""
    units = {"lg": "m", "radius": "m", "end radius": "m", "arc": "deg", "z start": "m", "z end": "m",
             "grade": "%", "banking start": "deg", "banking end": "deg", "profil steps length": "m"}
    lines = [f'<section name="{name}">', f'<attstr name="type" val="{kind}"/>']
    for key, val in attrs.items():
        key = key.replace("_", " ")
        if isinstance(val, str):
            lines.append(f'<attstr name="{key}" val="{val}"/>')
        else:
            unit = units.get(key)
            u = f' unit="{unit}"' if unit else ""
            lines.append(f'<attnum name="{key}"{u} val="{val}"/>')
    lines.append("</section>")
    return "\n".join(lines)


def track_xml(segments: list[str], *, width: float = 10.0, version: int = 4, main_extra: str = "",
              surfaces: str = "", name: str = "t") -> str:
    """A minimal TORCS v4 (or v3) track file around a list of segment sections."""
    seglist = "Track Segments" if version >= 4 else "segments"
    surf = f'<section name="Surfaces">{surfaces}</section>' if version >= 4 else \
        f'<section name="Surfaces"><section name="List">{surfaces}</section></section>'
    return (f'<?xml version="1.0"?>\n<params name="{name}">\n'
            f'<section name="Header"><attstr name="name" val="{name}"/><attstr name="category" val="road"/>'
            f'<attnum name="version" val="{version}"/></section>\n{surf}\n'
            f'<section name="Main Track"><attnum name="width" unit="m" val="{width}"/>{main_extra}\n'
            f'<section name="{seglist}">\n' + "\n".join(segments) + "\n</section></section>\n</params>\n")



def polyline_crossings(polylines: list[np.ndarray], block: int = 256) -> int:
    """Pairs of non-adjacent segments of the closed polylines (each (K, 2)) that cross properly."""
    a = np.concatenate(polylines)
    b = np.concatenate([np.roll(p, -1, axis=0) for p in polylines])
    owner = np.concatenate([np.full(len(p), k) for k, p in enumerate(polylines)])
    index = np.concatenate([np.arange(len(p)) for p in polylines])
    size = np.array([len(p) for p in polylines])[owner]
    lo, hi = np.minimum(a, b), np.maximum(a, b)

    def side(p, q, r):
        return np.sign((q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0]))

    count = 0
    j = np.arange(len(a))[None, :]
    for start in range(0, len(a), block):
        i = np.arange(start, min(start + block, len(a)))[:, None]
        gap = np.abs(index[i] - index[j])
        adjacent = (owner[i] == owner[j]) & ((gap <= 1) | (gap == size[i] - 1))
        boxes = ((lo[i, 0] <= hi[j, 0]) & (lo[j, 0] <= hi[i, 0])
                 & (lo[i, 1] <= hi[j, 1]) & (lo[j, 1] <= hi[i, 1]))
        ii, jj = np.nonzero(boxes & ~adjacent & (j > i))
        ii, jj = ii + start, jj
        proper = ((side(a[ii], b[ii], a[jj]) * side(a[ii], b[ii], b[jj]) < 0)
                  & (side(a[jj], b[jj], a[ii]) * side(a[jj], b[jj], b[ii]) < 0))
        count += int(proper.sum())
    return count
