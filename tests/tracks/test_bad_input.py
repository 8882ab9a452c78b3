"""Broken track files give a TrackError naming the file and the element, never a traceback."""

import subprocess
import sys

import numpy as np
import pytest
from trackfiles import segment, track_xml

from madsim.tracks import Track, TrackError, load_track, load_track_xml

GOOD = [segment("s1", "str", lg=100), segment("c1", "lft", radius=30, arc=180),
        segment("s2", "str", lg=100), segment("c2", "lft", radius=30, arc=180)]

BROKEN = {
    "malformed xml": ('<params name="x"><section name="Main Track">', "line"),
    "not params": ('<foo/>', "<foo>"),
    "no main track": ('<params name="x"><section name="Header"/></params>', "Main Track"),
    "no segment list": ('<params name="x"><section name="Main Track"><attnum name="width" val="10"/>'
                        '</section></params>', "Main Track/segments"),  # no Header version: v3 reader
    "v3 list name in v4 file": (track_xml(GOOD).replace("Track Segments", "segments"),
                                "the file has 'Main Track/segments'"),
    "unknown segment type": (track_xml([segment("s1", "str", lg=100), segment("bad", "zigzag", lg=5)]),
                             "segment 'bad'"),
    "negative length": (track_xml([segment("neg", "str", lg=-10)]), "segment 'neg'"),
    "zero radius": (track_xml([segment("z", "lft", radius=0, arc=90)]), "segment 'z'"),
    "negative radius": (track_xml([segment("r", "rgt", radius=-30, arc=90)]), "segment 'r'"),
    "negative arc": (track_xml([segment("a", "rgt", radius=30, arc=-90)]), "segment 'a'"),
    "non-numeric value": (track_xml([segment("s1", "str", lg=100)]).replace('val="100"', 'val="lots"'),
                          "attnum 'lg'"),
    "empty segment list": (track_xml([]), "Track Segments"),
    "negative width": (track_xml(GOOD, width=-3), "width"),
    "duplicate segment": (track_xml([segment("s", "str", lg=10), segment("s", "str", lg=10)]),
                          "section 'Main Track/Track Segments/s'"),
    "nan length": (track_xml([segment("s1", "str", lg="nan")]).replace(
        '<attstr name="lg" val="nan"/>', '<attnum name="lg" val="nan"/>'), "segment 's1'"),
    "missing entity file": ('<!DOCTYPE params [<!ENTITY s SYSTEM "../../nowhere.xml">]>' + track_xml(GOOD)
                            .replace('<?xml version="1.0"?>\n', "").replace(
                                '<section name="Surfaces">', '<section name="Surfaces">&s;'), "ENTITY s"),
}


@pytest.mark.parametrize("label", sorted(BROKEN))
def test_broken_file_gives_track_error_with_file_and_element(write_track, label):
    text, where = BROKEN[label]
    path = write_track(text)
    with pytest.raises(TrackError) as err:
        load_track(path)
    assert err.value.file == str(path)
    assert where in str(err.value), str(err.value)


def test_unreadable_file(tmp_path):
    # a directory in place of the file cannot be read, even by root (chmod would not stop root)
    p = tmp_path / "t.xml"
    p.mkdir()
    with pytest.raises(TrackError, match="cannot read file") as err:
        load_track_xml(p)
    assert err.value.file == str(p)


def test_mutated_files_never_escape_as_other_errors(write_track):
    """Random byte mutations of a valid file: each load gives a Track or a TrackError."""
    base = track_xml(GOOD).encode()
    rng = np.random.default_rng(2026)
    outcomes = {"track": 0, "error": 0}
    for i in range(300):
        data = bytearray(base)
        for _ in range(int(rng.integers(1, 6))):
            pos = int(rng.integers(0, len(data)))
            op = rng.integers(0, 3)
            if op == 0:
                data[pos] = int(rng.integers(0, 256))
            elif op == 1:
                del data[pos]
            else:
                data.insert(pos, int(rng.choice(list(b'<>"/=&;0123456789-.e '))))
        path = write_track("", name=f"m{i}")
        path.write_bytes(bytes(data))
        try:
            t = load_track(path)
        except TrackError as exc:
            assert str(path) in str(exc)
            outcomes["error"] += 1
        else:
            assert isinstance(t, Track) and np.isfinite(t.length) and t.length > 0
            outcomes["track"] += 1
    assert outcomes["error"] > 50 and outcomes["track"] > 20, outcomes


def test_cli_prints_one_line_and_exits_non_zero(write_track):
    path = write_track(BROKEN["unknown segment type"][0])
    proc = subprocess.run([sys.executable, "-m", "madsim.cli", "tracks", "info", str(path)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "segment 'bad'" in lines[0] and "Traceback" not in proc.stderr


def test_unknown_track_name_lists_where_it_looked():
    with pytest.raises(TrackError, match="not found; looked in"):
        load_track("no-such-track-anywhere")
