"""Video files (MP4, GIF) and the replay of serve traces: files are written and read back."""

from __future__ import annotations

import numpy as np
import pytest

from madsim.render.trace import TraceError, check_track, read_trace


def solid_frames(n, h=48, w=64):
    """n frames, frame i a solid colour that changes with i."""
    return [np.full((h, w, 3), (20 * i % 256, 255 - 20 * i % 256, 128), dtype=np.uint8) for i in range(n)]


def test_mp4_holds_every_frame_with_its_colour(tmp_path):
    ffmpeg = pytest.importorskip("imageio_ffmpeg", reason="MP4 needs imageio-ffmpeg: pip install 'madsim[render]'")
    from madsim.render.video import write_video

    frames = solid_frames(12, 47, 63)          # odd sizes: padded to 48 x 64
    path = tmp_path / "clip.mp4"
    assert write_video(frames, path, fps=25) == 12
    reader = ffmpeg.read_frames(str(path))
    meta = next(reader)
    assert meta["size"] == (64, 48) and meta["fps"] == pytest.approx(25.0)
    got = [np.frombuffer(b, np.uint8).reshape(48, 64, 3) for b in reader]
    assert len(got) == 12
    for f, g in zip(frames, got):
        # H.264 in yuv420p changes colours by a few levels
        assert np.abs(g[:47, :63].astype(int).mean(axis=(0, 1)) - f[0, 0]).max() < 8


def test_gif_holds_every_frame(tmp_path):
    from PIL import Image

    from madsim.render.video import write_video

    frames = solid_frames(5)
    path = tmp_path / "clip.gif"
    write_video(frames, path, fps=10)
    with Image.open(path) as im:
        assert im.n_frames == 5 and im.size == (64, 48)
        im.seek(3)
        assert np.abs(np.asarray(im.convert("RGB"))[0, 0].astype(int) - frames[3][0, 0]).max() <= 4
        assert im.info["duration"] == 100


def test_video_writer_refuses_bad_input(tmp_path):
    from madsim.render.video import VideoWriter

    with pytest.raises(ValueError, match="unknown video type"):
        VideoWriter(tmp_path / "x.txt")
    w = VideoWriter(tmp_path / "x.gif")
    with pytest.raises(ValueError, match="uint8"):
        w.append(np.zeros((4, 4, 3)))
    w.append(np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(ValueError, match="size changed"):
        w.append(np.zeros((5, 4, 3), np.uint8))
    with pytest.raises(ValueError, match="no frames"):
        VideoWriter(tmp_path / "y.gif").close()


def test_read_trace_gives_ticks_by_cars_without_the_countdown(trace_file):
    tr = read_trace(trace_file)
    assert (tr.n_ticks, tr.n_cars) == (60, 2)
    np.testing.assert_array_equal(tr["tick"][:, 0], np.arange(60))
    np.testing.assert_array_equal(tr["car"][0], [0, 1])
    assert read_trace(trace_file, countdown=True).n_ticks == 62
    # car 1 starts 10 m behind car 0 on the grid, both behind the start line: positions 1, 2
    np.testing.assert_array_equal(tr.race_positions(3037.910400390625)[0], [1, 2])


def test_bad_traces_are_named_with_line_and_column(tmp_path, trace_file):
    lines = trace_file.read_text().splitlines()
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join([lines[0], lines[1].replace(lines[1].split(",")[3], "abc", 1)] + lines[2:]))
    with pytest.raises(TraceError, match=r"bad.csv: line 2: column 'x' is not a number: 'abc'"):
        read_trace(bad)
    bad.write_text("a,b,c\n1,2,3\n")
    with pytest.raises(TraceError, match="missing column"):
        read_trace(bad)
    bad.write_text("\n".join(lines[:4] + lines[5:]))    # a car missing in one tick
    with pytest.raises(TraceError, match="line 5: every tick must list cars 0..1"):
        read_trace(bad)
    with pytest.raises(TraceError, match="cannot read"):
        read_trace(tmp_path / "missing.csv")


def test_a_trace_on_the_wrong_track_is_refused(trace_file):
    from madsim.tracks import load_track

    check_track(read_trace(trace_file), load_track("madsim-road"))
    with pytest.raises(TraceError, match="--track"):
        check_track(read_trace(trace_file), load_track("madsim-oval"))


def test_render_trace_writes_a_replay(tmp_path, trace_file):
    pytest.importorskip("pygame", reason="the renderer needs pygame: pip install 'madsim[render]'")
    from PIL import Image

    from madsim.render.video import render_trace

    out = tmp_path / "replay.gif"
    seen = []
    n = render_trace(trace_file, out, every=10, size=(320, 240), camera="rotate", car=1,
                     progress=lambda done, total: seen.append((done, total)))
    assert n == 6 and seen[-1] == (6, 6)
    with Image.open(out) as im:
        assert im.n_frames == 6 and im.size == (320, 240)
        im.seek(5)
        last = np.asarray(im.convert("RGB"))
    # the followed car (a learner, red) sits at the rotating camera's anchor
    assert np.abs(last[int(0.65 * 240), 160].astype(int) - (232, 64, 48)).max() < 40
    with pytest.raises(ValueError, match="car 5"):
        render_trace(trace_file, tmp_path / "x.gif", car=5)
