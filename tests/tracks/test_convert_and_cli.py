"""`madsim convert track` round trips, track resolution order and the `madsim tracks` CLI."""

import json
import subprocess
import sys
import time

import numpy as np
import pytest
from trackfiles import segment, torcs_installed, track_xml, trackgen_available

from madsim.cli import main
from madsim.tracks import find_track, list_tracks, load_track
from madsim.tracks.compiled import load_compiled, save_compiled, track_to_xml

ROUND_TRIP = ["alpine-1", "a-speedway", "wheel-2", "dirt-4"]


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "madsim.cli", *args], capture_output=True, text=True,
                          timeout=120)


@pytest.mark.skipif(not torcs_installed(), reason="TORCS data not installed: apt-get install torcs-data")
@pytest.mark.parametrize("name", ROUND_TRIP)
def test_compiled_and_xml_round_trips_keep_the_track(tmp_path, name):
    t = load_track(name)
    save_compiled(t, tmp_path / f"{name}.mtrack")
    start = time.perf_counter()
    c = load_track(str(tmp_path / f"{name}.mtrack"))
    assert time.perf_counter() - start < 0.5  # "loads in milliseconds"; generous for CI
    assert c.length == t.length and c.name == t.name and c.title == t.title
    assert np.array_equal(c.pieces, t.pieces) and np.array_equal(c.x, t.x)
    assert [s.name for s in c.surfaces] == [s.name for s in t.surfaces]

    d = tmp_path / "back"
    d.mkdir()
    (d / "back.xml").write_text(track_to_xml(c))
    b = load_track(d / "back.xml")
    assert b.length == pytest.approx(t.length, abs=0.01)  # issue 2: round trip keeps L to 0.01 m
    assert np.abs(b.x - t.x).max() < 0.01 and np.abs(b.z - t.z).max() < 0.01
    assert np.allclose(b.barrier_left, t.barrier_left, atol=1e-4)
    assert np.array_equal(b.surface_at(t.s, 0.0), t.surface_at(t.s, 0.0)) or \
        [b.surfaces[i].name for i in b.surface_at(t.s, 0.0)] == [t.surfaces[i].name for i in t.surface_at(t.s, 0.0)]


@pytest.mark.skipif(not (torcs_installed() and trackgen_available()),
                    reason="real TORCS trackgen not installed: apt-get install torcs xvfb")
def test_real_torcs_reads_our_exported_xml(tmp_path):
    t = load_track("alpine-2")
    d = tmp_path / "rt-alpine"
    d.mkdir()
    (d / "rt-alpine.xml").write_text(track_to_xml(t))
    out = subprocess.run(["xvfb-run", "-a", "/usr/games/trackgen", "-c", "road", "-n", "rt-alpine",
                          "-i", f"{d}/", "-z"], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    line = [ln for ln in out.stdout.splitlines() if ln.strip().startswith("length")]
    assert line, out.stdout + out.stderr
    assert float(line[0].split("=")[1]) == pytest.approx(t.length, abs=0.01)


def test_compiled_file_garbage_is_a_track_error(tmp_path):
    from madsim.tracks import TrackError
    p = tmp_path / "x.mtrack"
    p.write_bytes(b"PK\x03\x04 not really a zip")
    with pytest.raises(TrackError, match="x.mtrack"):
        load_compiled(p)


def test_resolution_order_path_then_bundled_then_torcs(tmp_path, monkeypatch):
    # a track folder inside a fake TORCS data root, found through $TORCS_DATA
    root = tmp_path / "torcsdata"
    d = root / "tracks" / "road" / "mytest"
    d.mkdir(parents=True)
    segs = [segment("c", "lft", radius=30, arc=360)]
    (d / "mytest.xml").write_text(track_xml(segs, name="mytest"))
    monkeypatch.setenv("TORCS_DATA", str(root))
    assert find_track("mytest") == d / "mytest.xml"
    assert any(r["name"] == "mytest" and r["source"] == "torcs" for r in list_tracks())
    # an explicit path wins over names
    other = tmp_path / "elsewhere.xml"
    other.write_text(track_xml(segs, name="elsewhere"))
    assert find_track(str(other)) == other
    # bundled tracks come before installed ones of the same name
    bundled = [r for r in list_tracks() if r["source"] == "bundled"]
    for r in bundled:
        assert find_track(r["name"]).parent.parent.name == "tracks"
        assert "assets" in str(find_track(r["name"]))


def test_cli_info_json_has_the_required_keys(capsys):
    assert main(["tracks", "info", "madsim-road", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    for key in ("name", "length", "width", "closure_gap", "segments", "pieces", "elevation_min",
                "elevation_max", "bounding_box", "category"):
        assert key in info
    t = load_track("madsim-road")
    assert info["length"] == t.length and info["name"] == "madsim-road"


def test_cli_list_json_includes_bundled_and_installed(capsys):
    assert main(["tracks", "list", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    names = {r["name"]: r for r in rows}
    assert "madsim-road" in names and names["madsim-road"]["source"] == "bundled"
    assert all(r["length"] > 0 for r in rows)
    if torcs_installed():
        assert sum(r["source"] == "torcs" for r in rows) == 38
        assert names["spring"]["length"] == pytest.approx(22129.77, abs=0.05)


def test_cli_show_writes_a_png(tmp_path):
    import matplotlib.image as mpimg
    out = tmp_path / "map.png"
    proc = _cli("tracks", "show", "madsim-road", "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    img = mpimg.imread(out)
    assert img.shape[0] >= 600 and img.shape[1] >= 600
    # not a blank picture: the road is drawn (many non-white pixels)
    assert (img[..., :3].mean(axis=2) < 0.9).mean() > 0.02


def test_cli_convert_both_ways(tmp_path):
    assert _cli("convert", "track", "madsim-road", "-o", str(tmp_path / "r.mtrack")).returncode == 0
    d = tmp_path / "r2"
    d.mkdir()
    assert _cli("convert", "track", str(tmp_path / "r.mtrack"), "-o", str(d / "r2.xml")).returncode == 0
    assert load_track(d / "r2.xml").length == pytest.approx(load_track("madsim-road").length, abs=0.01)
    bad = _cli("convert", "track", "madsim-road", "-o", str(tmp_path / "r.txt"))
    assert bad.returncode == 2 and "must end in" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
