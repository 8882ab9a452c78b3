"""Run plots: files are written, are not blank, and show what they say."""

from __future__ import annotations

import numpy as np
import pytest

from madsim.render.plots import Run, plot_runs, plot_traces, unwrap_distance


def read_png(path):
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))


def test_distance_unwraps_over_the_start_line():
    L = 1000.0
    d = unwrap_distance([990.0, 995.0, 2.0, 10.0, 500.0, 999.0, 5.0], L)
    np.testing.assert_allclose(d, [-10.0, -5.0, 2.0, 10.0, 500.0, 999.0, 1005.0])


def _has_colour(img, rgb01, tol=12) -> bool:
    return bool(np.any(np.abs(img.astype(int) - np.array(rgb01[:3]) * 255).max(axis=2) < tol))


def test_plot_traces_writes_a_picture_with_the_speed_colours(tmp_path, trace_file):
    """One car: its trajectory is coloured by speed (the fastest stretch in plasma's top
    colour, yellow). Several cars: one colour per car in every panel, no shared speed map
    (issue 14: whose speed is whose could not be told)."""
    import matplotlib

    top = matplotlib.colormaps["plasma"](1.0)
    out = tmp_path / "one.png"
    assert plot_traces([trace_file], out, cars=[0], dpi=80) == 1
    img = read_png(out)
    assert img.shape[0] > 400 and img.shape[1] > 800
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 200    # a picture, not a blank page
    assert _has_colour(img, top)
    out = tmp_path / "two.png"
    assert plot_traces([trace_file], out, dpi=80) == 2
    img = read_png(out)
    tab10 = matplotlib.colormaps["tab10"].colors
    assert _has_colour(img, tab10[0]) and _has_colour(img, tab10[1])
    assert not _has_colour(img, top, tol=6)


def test_two_traces_overlay_with_their_labels(tmp_path, trace_file):
    out = tmp_path / "compare.png"
    n = plot_traces([trace_file, trace_file], out, cars=[0], labels=["driver A", "driver B"])
    assert n == 2 and out.stat().st_size > 20_000
    with pytest.raises(ValueError, match="labels"):
        plot_traces([trace_file], out, labels=["a", "b"])
    with pytest.raises(ValueError, match="no car 7"):
        plot_traces([trace_file], out, cars=[7])


def test_plot_runs_takes_plain_arrays(tmp_path, road):
    s = np.linspace(0.0, 600.0, 300)
    x, y, _, _ = road.pose(s, 0.0)
    runs = [Run("slow", x, y, np.full_like(s, 50.0), s, np.zeros_like(s)),
            Run("fast", x, y, np.linspace(50.0, 150.0, 300), s, np.full_like(s, 0.3))]
    out = tmp_path / "runs.png"
    plot_runs(road, runs, out, title="two drivers")
    assert read_png(out).std() > 20
    with pytest.raises(ValueError, match="no runs"):
        plot_runs(road, [], out)
