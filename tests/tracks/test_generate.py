"""Procedural tracks (madsim.tracks.generate): determinism, closure, size, self-clearance, inputs.

Generated files are read back with the track loader, which knows nothing of the generator, and
checked with a crossing test written here.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from trackfiles import polyline_crossings

import madsim
import madsim.tracks.generate as gen
from madsim.torcsxml import parse_params
from madsim.tracks import load_track
from madsim.tracks.build import COL, STRAIGHT
from madsim.tracks.generate import (
    BORDER_W,
    SIDE_W,
    _edges_cross,
    generate_track_xml,
    write_generated_track,
)




def _layout(text: str) -> list[tuple]:
    """(type, lg or radius, arc) of every segment, as numbers TORCS reads them."""
    segs = parse_params(text).sub("Main Track/Track Segments")
    return [(s.str("type"), s.num("lg", 0.0) or s.num("radius"), s.num("arc", 0.0)) for s in segs]


# (seed, length_m, width_m): the default, short and narrow, short and wide, wide, long
CASES = [(s, 3000.0, 12.0) for s in range(5)] + [(5, 300.0, 3.0), (6, 300.0, 12.0),
                                                  (7, 1000.0, 20.0), (8, 800.0, 5.0), (9, 6000.0, 10.0)]


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    """Each case written as <tmp>/<name>/<name>.xml and loaded: {case: (text, Track)}."""
    root = tmp_path_factory.mktemp("generated")
    out = {}
    for seed, length, width in CASES:
        name = f"gen-{seed}"
        path = write_generated_track(seed, root / name / f"{name}.xml", length_m=length, width_m=width)
        out[(seed, length, width)] = (path.read_text(encoding="utf-8"), load_track(path))
    return out


# --- determinism ---------------------------------------------------------------------------


def test_same_seed_gives_byte_identical_text():
    assert generate_track_xml(11) == generate_track_xml(11)
    assert generate_track_xml(11, 900, 7, name="x") == generate_track_xml(11, 900.0, 7.0, name="x")


def test_same_seed_gives_the_same_text_in_another_process():
    code = "import sys; from madsim.tracks.generate import generate_track_xml as g; " \
           "sys.stdout.write(g(12, 1200, 9))"
    root = str(Path(madsim.__file__).resolve().parents[1])
    env = dict(os.environ, PYTHONHASHSEED="123",
               PYTHONPATH=os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")])))
    other = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                           timeout=120, check=True).stdout
    assert other == generate_track_xml(12, 1200, 9)


def test_different_seeds_give_different_tracks(generated):
    # five seeds with the same length and width: five different segment lists
    layouts = {tuple(_layout(generated[c][0])) for c in CASES[:5]}
    assert len(layouts) == 5


# --- geometry -------------------------------------------------------------------------------


@pytest.mark.parametrize("case", CASES, ids=[f"seed{s}-{L:g}m-{w:g}w" for s, L, w in CASES])
def test_generated_track_closes_with_the_requested_size(generated, case):
    seed, length, width = case
    text, t = generated[case]
    assert t.category == "road" and t.version == 4
    assert t.width == width
    # issue 2 allows 10 %; the generator promises 1 %
    assert abs(t.length - length) < 0.01 * length
    # issue 2 allows 0.5 m; rounding to the written digits leaves ~1e-4 m
    assert t.closure_gap < 0.01
    assert abs(math.degrees(t.closure_heading_gap)) < 0.001
    first, last = t.pieces[0], t.pieces[-1]
    assert last[COL["zl1"]] == pytest.approx(first[COL["zl0"]], abs=1e-3)
    # corner radii: at least the road width, and the verge's outer edge never folds
    radii = t.pieces[t.pieces[:, COL["kind"]] != STRAIGHT, COL["radius"]]
    assert radii.min() >= width
    assert radii.min() > width / 2 + BORDER_W + SIDE_W


@pytest.mark.parametrize("case", CASES, ids=[f"seed{s}-{L:g}m-{w:g}w" for s, L, w in CASES])
def test_generated_barriers_never_cross(generated, case):
    t = generated[case][1]
    assert polyline_crossings([t.barrier_polyline("left"), t.barrier_polyline("right")]) == 0


def test_grade_stays_below_the_limit_and_zero_gives_a_flat_track(tmp_path):
    for seed, grade in ((21, 0.03), (22, 0.08)):
        p = write_generated_track(seed, tmp_path / f"g{seed}" / f"g{seed}.xml", max_grade=grade)
        t = load_track(p)
        slope = np.diff(t.z) / np.diff(t.s)
        # heights between piece ends are linear chords of the Hermite profile (spec 5.4)
        assert np.abs(slope).max() <= grade * 1.05
        assert np.abs(slope).max() >= grade * 0.3          # the hills are really there
    flat = load_track(write_generated_track(23, tmp_path / "f" / "f.xml", max_grade=0.0))
    assert np.ptp(flat.z) == 0.0


def test_a_layout_that_crosses_itself_is_redrawn_and_attempts_are_bounded(monkeypatch):
    plain = generate_track_xml(31, 800)
    calls = []
    real = gen._edges_cross

    def first_layout_crosses(left, right):
        calls.append(1)
        return len(calls) == 1 or real(left, right)

    monkeypatch.setattr(gen, "_edges_cross", first_layout_crosses)
    redrawn = generate_track_xml(31, 800)
    assert len(calls) >= 2 and redrawn != plain
    monkeypatch.setattr(gen, "_edges_cross", lambda left, right: True)
    with pytest.raises(ValueError, match=f"no self-clearing layout found in {gen.MAX_ATTEMPTS} draws"):
        generate_track_xml(31, 800)


def test_crossing_detector_of_the_generator_sees_crossings():
    square = np.array([[0, 0], [10, 0], [10, 10], [0, 10]], float)
    bowtie = np.array([[0, 0], [10, 10], [10, 0], [0, 10]], float)
    assert _edges_cross(square, square * 3 - 10) is False
    assert _edges_cross(bowtie, square * 3 + 50) is True           # one polyline crosses itself
    assert _edges_cross(square, square + 5) is True                # the two polylines cross


# --- files and inputs ------------------------------------------------------------------------


def test_write_generated_track_names_the_track_after_the_file(tmp_path):
    path = write_generated_track(4, tmp_path / "a" / "b" / "my-track.xml", length_m=500, width_m=8)
    assert path == tmp_path / "a" / "b" / "my-track.xml" and path.is_file()
    header = parse_params(path.read_text(encoding="utf-8")).sub("Header")
    assert header.str("name") == "my-track"
    assert path.read_text(encoding="utf-8") == generate_track_xml(4, 500, 8, name="my-track")
    with pytest.raises(ValueError, match="xml"):
        write_generated_track(4, tmp_path / "no-suffix")


@pytest.mark.parametrize("kwargs, field", [
    (dict(seed=-1), "seed"),
    (dict(seed=1.5), "seed"),
    (dict(seed=True), "seed"),
    (dict(seed=1, length_m=-3000), "length_m"),
    (dict(seed=1, length_m=299), "length_m"),
    (dict(seed=1, length_m=float("nan")), "length_m"),
    (dict(seed=1, width_m=2.9), "width_m"),
    (dict(seed=1, width_m=float("inf")), "width_m"),
    (dict(seed=1, length_m=300, width_m=20), "width_m"),
    (dict(seed=1, name="a/b"), "name"),
    (dict(seed=1, name=""), "name"),
    (dict(seed=1, max_grade=0.5), "max_grade"),
])
def test_nonsense_inputs_raise_a_clear_value_error(kwargs, field):
    with pytest.raises(ValueError, match=field):
        generate_track_xml(**kwargs)
