"""madsim's own tracks (madsim/assets/tracks): file format, closure, what issue 2 asks of each,
and agreement with real TORCS's trackgen (also for three generated tracks)."""

from __future__ import annotations

import math
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from trackfiles import polyline_crossings, trackgen_available

import madsim
from madsim.torcsxml import read_params
from madsim.tracks import load_track
from madsim.tracks.build import COL, LEFT, RIGHT, STRAIGHT
from madsim.tracks.generate import write_generated_track

ASSETS = Path(madsim.__file__).parent / "assets" / "tracks"
BUNDLED = {"madsim-oval": "oval", "madsim-road": "road", "madsim-street": "road",
           "madsim-speedway": "oval"}
SIDE_SECTIONS = ("Left Side", "Right Side", "Left Border", "Right Border", "Left Barrier",
                 "Right Barrier")


def _xml(name: str) -> Path:
    return ASSETS / name / f"{name}.xml"


def _segments(name: str) -> list[tuple[str, float, float, float]]:
    """The XML segments in order: (type, lg m, radius m, arc rad) as TORCS reads them."""
    segs = read_params(_xml(name)).sub("Main Track/Track Segments")
    return [(s.str("type"), s.num("lg", 0.0), s.num("radius", 0.0), s.num("arc", 0.0)) for s in segs]




def _longest_straight(track) -> float:
    """Longest run of consecutive straight pieces, m (wrapping over the start line)."""
    kind, length = track.pieces[:, COL["kind"]], track.pieces[:, COL["length"]]
    if np.all(kind == STRAIGHT):
        return float(length.sum())
    start = int(np.argmax(kind != STRAIGHT))
    best = run = 0.0
    for k in range(len(kind)):
        i = (start + k) % len(kind)
        run = run + length[i] if kind[i] == STRAIGHT else 0.0
        best = max(best, run)
    return best


# --- every bundled track ------------------------------------------------------------------


def test_the_table_covers_every_bundled_track():
    assert sorted(d.name for d in ASSETS.iterdir() if d.is_dir()) == sorted(BUNDLED)


@pytest.mark.parametrize("name", sorted(BUNDLED))
def test_file_is_self_contained_torcs_v4(name):
    text = _xml(name).read_text(encoding="utf-8")
    # our package ships no surfaces.xml: an external entity would silently read as empty
    assert "<!ENTITY" not in text and "<!DOCTYPE" not in text
    assert re.search(r"&(?!amp;|lt;|gt;|quot;|apos;)", text) is None
    header = read_params(_xml(name)).sub("Header")
    assert header.num("version") == 4
    assert header.str("name") == name
    assert header.str("category") == BUNDLED[name]
    assert header.str("author") == "madsim"
    assert len(header.str("description", "")) > 10


@pytest.mark.parametrize("name", sorted(BUNDLED))
def test_every_surface_it_uses_is_defined_inline(name):
    # TORCS gives an undefined surface all defaults (friction 0.8) without a word: catch typos
    root = read_params(_xml(name))
    defined = {s.name: s for s in root.sub("Surfaces")}
    main = root.sub("Main Track")
    used = {main.str("surface")}
    for owner in [main, *main.sub("Track Segments")]:
        used.add(owner.str("surface"))
        for sub in SIDE_SECTIONS:
            if owner.sub(sub) is not None:
                used.add(owner.sub(sub).str("surface"))
    used.discard(None)
    assert used <= set(defined), f"undefined: {sorted(used - set(defined))}"
    for s in defined.values():
        assert 0.0 <= s.num("friction") <= 1.5, s.name
        assert 0.0 <= s.num("rolling resistance", 0.0) <= 0.2, s.name


@pytest.mark.parametrize("name", sorted(BUNDLED))
def test_track_closes(name):
    t = load_track(name)
    assert t.name == name and t.category == BUNDLED[name]
    # designed to close exactly; what is left is the written digits and float32 (spec 4.6)
    assert t.closure_gap < 0.01
    assert abs(math.degrees(t.closure_heading_gap)) < 0.001
    first, last = t.pieces[0], t.pieces[-1]
    assert last[COL["zl1"]] == pytest.approx(first[COL["zl0"]], abs=1e-3)
    assert last[COL["zr1"]] == pytest.approx(first[COL["zr0"]], abs=1e-3)


@pytest.mark.parametrize("name", sorted(BUNDLED))
def test_barriers_never_cross(name):
    t = load_track(name)
    assert polyline_crossings([t.barrier_polyline("left"), t.barrier_polyline("right")]) == 0
    curved = t.pieces[:, COL["kind"]] != STRAIGHT
    inner = t.pieces[curved, COL["radius"]] - t.width / 2
    assert inner.min() > t.width / 2, "the inner road edge would nearly fold"


# --- what issue 2 asks of each -----------------------------------------------------------


def test_oval_is_a_banked_oval():
    t = load_track("madsim-oval")
    # two 330 m straights and two 180 deg turns of 150 m radius (see the file's comment);
    # 0.05 m covers TORCS's float32 length sum (spec 4.6)
    assert t.length == pytest.approx(2 * 330 + 2 * math.pi * 150, abs=0.05)
    assert 1500 <= t.length <= 2000
    assert not np.any(t.pieces[:, COL["kind"]] == RIGHT)
    turning = t.curvature != 0
    assert math.degrees(t.banking[turning].min()) == pytest.approx(-10.0, abs=0.01)
    assert np.all(t.banking[turning] <= 0)        # right (outer) edge higher in left turns


def test_road_course_is_the_default_and_has_what_a_road_course_needs():
    t = load_track()
    assert t.name == "madsim-road"
    assert t.category == "road"
    assert 2800 <= t.length <= 3200
    assert t.z.max() - t.z.min() > 10.0
    assert math.degrees(np.abs(t.banking).max()) >= 5.0
    segs = _segments("madsim-road")
    turns = [(typ, r, arc) for typ, _, r, arc in segs if typ != "str"]
    assert any(arc >= math.radians(150) and r <= 25 for _, r, arc in turns), "no hairpin"
    assert sum(r >= 150 for _, r, _ in turns) >= 2, "no fast sweepers"
    # a chicane: three tight turns, alternating, with only straights shorter than 30 m between
    kept = [(typ, r) for typ, lg, r, _ in segs if not (typ == "str" and lg < 30)]
    triples = [kept[k:k + 3] for k in range(len(kept) - 2)]
    assert any(all(typ != "str" and r <= 40 for typ, r in tri) and tri[0][0] == tri[2][0] != tri[1][0]
               for tri in triples), "no chicane"
    # sides, curbs and barriers everywhere
    p = t.pieces
    for col in ("border_w_l", "border_w_r", "side_w0_l", "side_w0_r", "barrier_h_l", "barrier_h_r"):
        assert np.all(p[:, COL[col]] > 0), col


def test_street_circuit_is_narrow_with_walls_close():
    t = load_track("madsim-street")
    assert t.category == "road"
    assert t.width == pytest.approx(5.0)
    # barrier line = outer edge of the sidewalk: never more than 2 m beyond the road edge
    assert np.all(t.barrier_left - t.width_left <= 2.0)
    assert np.all(t.barrier_right - t.width_right <= 2.0)
    assert np.all(t.barrier_left > t.width_left) and np.all(t.barrier_right > t.width_right)
    assert np.any(t.pieces[:, COL["kind"]] == LEFT) and np.any(t.pieces[:, COL["kind"]] == RIGHT)


def test_speedway_has_a_straight_of_at_least_a_kilometre():
    t = load_track("madsim-speedway")
    assert _longest_straight(t) >= 1000.0
    # 2 x 1200 m straights, 2 x 100 m chutes, four 90 deg turns of 260 m radius (file comment)
    assert t.length == pytest.approx(2 * 1200 + 2 * 100 + 2 * math.pi * 260, abs=0.05)


# --- real TORCS (bundled tracks and three generated ones) ---------------------------------


def _trackgen(xml: Path, category: str, workdir: Path) -> dict[str, float]:
    """Length and closure that real TORCS computes (`trackgen -z`) for a track file."""
    name = xml.stem
    folder = workdir / "trackgen" / name      # trackgen wants <folder named like the track>/<name>.xml
    folder.mkdir(parents=True)
    shutil.copy(xml, folder / f"{name}.xml")
    run = subprocess.run(["xvfb-run", "-a", "/usr/games/trackgen", "-c", category, "-n", name,
                          "-i", str(folder), "-z"], capture_output=True, text=True, cwd=workdir,
                         timeout=120)
    values = dict(re.findall(r"^(length|Delta X|Delta Y)\s*=\s*(\S+)", run.stdout, re.M))
    output = f"{run.stdout[-2000:]}\n{run.stderr[-2000:]}"
    assert len(values) == 3, f"trackgen printed no result for {name}:\n{output}"
    return {k: float(v) for k, v in values.items()}


TORCS_CASES = [("bundled", name) for name in sorted(BUNDLED)] + [("generated", s) for s in (0, 1, 2)]


@pytest.mark.skipif(not trackgen_available(),
                    reason="real TORCS trackgen not available: apt-get install torcs xvfb")
@pytest.mark.parametrize("kind, which", TORCS_CASES)
def test_real_torcs_builds_the_same_track(tmp_path, kind, which):
    if kind == "bundled":
        xml, category = _xml(which), BUNDLED[which]
    else:
        xml = write_generated_track(which, tmp_path / "gen" / f"madsim-gen-{which}.xml")
        category = "road"
    torcs = _trackgen(xml, category, tmp_path)
    # TORCS prints its float32 length sum; our loader reproduces it (spec 4.6: +-0.05 m)
    assert torcs["length"] == pytest.approx(load_track(xml).length, abs=0.05)
    # issue 2 allows 0.5 m; these tracks are built to close, so hold them to 0.05 m
    assert abs(torcs["Delta X"]) < 0.05 and abs(torcs["Delta Y"]) < 0.05
