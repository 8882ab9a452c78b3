"""Finding and loading tracks: a path, a bundled track, or an installed TORCS track."""

from __future__ import annotations

import os
from pathlib import Path

from madsim.torcsxml import ParamsError, read_params
from madsim.tracks.build import BuildError, build_pieces
from madsim.tracks.errors import TrackError
from madsim.tracks.track import Track

BUNDLED_DIR = Path(__file__).resolve().parent.parent / "assets" / "tracks"
DEFAULT_TRACK = "madsim-road"
CATEGORIES = ("road", "oval", "dirt")
COMPILED_SUFFIX = ".mtrack"


def torcs_data_dirs() -> list[Path]:
    """TORCS data roots searched for installed tracks and cars, in order."""
    dirs = []
    env = os.environ.get("TORCS_DATA")
    if env:
        dirs.append(Path(env))
    dirs += [Path("/usr/share/games/torcs"), Path("/usr/local/share/games/torcs")]
    return dirs


def _bundled(name: str) -> Path | None:
    p = BUNDLED_DIR / name / f"{name}.xml"
    return p if p.is_file() else None


def _installed(name: str) -> Path | None:
    for root in torcs_data_dirs():
        for cat in CATEGORIES:
            p = root / "tracks" / cat / name / f"{name}.xml"
            if p.is_file():
                return p
    return None


def find_track(name_or_path: str | os.PathLike) -> Path:
    """Resolve a track: an existing path, else a bundled name, else an installed TORCS name."""
    text = os.fspath(name_or_path)
    p = Path(text)
    if p.is_file():
        return p
    if p.is_dir() and (p / f"{p.name}.xml").is_file():
        return p / f"{p.name}.xml"
    if os.sep not in text and not text.endswith((".xml", COMPILED_SUFFIX)):
        found = _bundled(text) or _installed(text)
        if found is not None:
            return found
    looked = [str(p), str(BUNDLED_DIR / text)] + [str(r / "tracks" / "<category>" / text) for r in torcs_data_dirs()]
    raise TrackError(f"track '{text}' not found; looked in: " + "; ".join(looked))


def load_track(name_or_path: str | os.PathLike = DEFAULT_TRACK) -> Track:
    """Load a track by path or name (TORCS XML or madsim's compiled form) into a Track."""
    path = find_track(name_or_path)
    if path.suffix == COMPILED_SUFFIX:
        from madsim.tracks.compiled import load_compiled
        return load_compiled(path)
    return load_track_xml(path)


def load_track_xml(path: str | os.PathLike) -> Track:
    """Read a TORCS track XML file; any fault becomes a TrackError naming file and element."""
    path = Path(path)
    try:
        root = read_params(path)
        built = build_pieces(root)
    except ParamsError as exc:
        raise TrackError(str(exc).split(": ", 1)[-1] if exc.file else str(exc), file=str(path),
                         element=exc.element) from None
    except BuildError as exc:
        raise TrackError(str(exc), file=str(path), element=exc.element) from None
    return Track.from_build(built, source=str(path), name=path.stem)


def list_tracks() -> list[dict]:
    """Bundled and installed tracks: name, category, source ('bundled'|'torcs') and path."""
    out = []
    if BUNDLED_DIR.is_dir():
        for d in sorted(BUNDLED_DIR.iterdir()):
            if (d / f"{d.name}.xml").is_file():
                out.append({"name": d.name, "source": "bundled", "path": str(d / f"{d.name}.xml")})
    seen = {t["name"] for t in out}
    for root in torcs_data_dirs():
        for cat in CATEGORIES:
            base = root / "tracks" / cat
            if not base.is_dir():
                continue
            for d in sorted(base.iterdir()):
                if d.name not in seen and (d / f"{d.name}.xml").is_file():
                    seen.add(d.name)
                    out.append({"name": d.name, "source": "torcs", "path": str(d / f"{d.name}.xml")})
    return out
