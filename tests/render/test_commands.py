"""`madsim render` and `madsim plot` through their argparse front end."""

from __future__ import annotations

import pytest

from madsim.cli_parsers import build_parser


def run(argv):
    """The command's handler called directly, so its ValueErrors reach the test."""
    args = build_parser().parse_args(argv)
    return args.func(args)


def test_render_command_writes_the_video(tmp_path, trace_file, capsys):
    pytest.importorskip("pygame", reason="the renderer needs pygame: pip install 'madsim[render]'")
    out = tmp_path / "replay.gif"
    assert run(["render", str(trace_file), "-o", str(out), "--every", "20", "--size", "200x150",
                "--camera", "track", "-q"]) == 0
    assert out.stat().st_size > 1000
    assert "3 frames" in capsys.readouterr().out


def test_plot_command_writes_the_figure(tmp_path, trace_file, capsys):
    out = tmp_path / "plot.png"
    assert run(["plot", str(trace_file), str(trace_file), "-o", str(out), "--cars", "1",
                "--labels", "a,b", "--title", "same run twice"]) == 0
    assert out.stat().st_size > 20_000
    assert "2 run(s)" in capsys.readouterr().out


def test_bad_arguments_are_reported(tmp_path, trace_file):
    with pytest.raises(SystemExit):
        run(["render", str(trace_file), "-o", "x.mp4", "--size", "big"])
    with pytest.raises(ValueError, match="--cars"):
        run(["plot", str(trace_file), "-o", str(tmp_path / "p.png"), "--cars", "one"])
    with pytest.raises(ValueError, match="--track"):
        run(["plot", str(trace_file), "-o", str(tmp_path / "p.png"), "--track", "madsim-oval"])
