"""`madsim render` and `madsim plot`: the command-line doors of this package.

`add_render_commands(sub)` adds both sub-commands to the CLI's sub-parsers; bad input raises
ValueError (the CLI prints it as one line), a missing optional dependency is reported the same way.
"""

from __future__ import annotations

import argparse
import sys

from madsim.render.scene import CAMERAS


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must be WIDTHxHEIGHT, e.g. 800x600, got {text!r}") from None
    if w < 16 or h < 16:
        raise argparse.ArgumentTypeError(f"size must be at least 16x16, got {text!r}")
    return w, h


def _names(text: str | None) -> list[str] | None:
    return None if text is None else [v.strip() for v in text.split(",") if v.strip()]


def cmd_render(args) -> int:
    from tqdm import tqdm

    from madsim.interrupts import StopRequest
    from madsim.render.topdown import Camera
    from madsim.render.video import render_trace

    bar = tqdm(unit="frame", desc="madsim render", disable=args.quiet)

    def progress(done: int, total: int) -> None:
        bar.total = total
        bar.update(done - bar.n)

    try:
        with StopRequest() as stop:
            n = render_trace(args.trace, args.output, track=args.track, cars=_names(args.cars), car=args.car,
                             camera=Camera(args.camera, ppm=args.zoom), size=args.size, fps=args.fps,
                             every=args.every, progress=progress, stop=stop)
    except ModuleNotFoundError as exc:
        raise ValueError(str(exc)) from None
    finally:
        bar.close()
    if stop:
        print(f"madsim render: interrupted by {stop.signal_name}; wrote {n} frames -> {args.output} (playable)",
              file=sys.stderr, flush=True)
        return stop.exit_status
    print(f"madsim render: {n} frames -> {args.output}")
    return 0


def cmd_plot(args) -> int:
    """Trace CSVs -> trajectories and speed/trackPos plots; a `madsim train` run folder ->
    its learning curves (one command for both, as the CLI has one `plot`)."""
    from pathlib import Path

    if len(args.traces) == 1 and Path(args.traces[0]).is_dir():
        from madsim.render.learning_curves import plot_learning_curves

        out = plot_learning_curves(args.traces[0], args.output)
        print(f"wrote {out}")
        return 0
    if args.output is None:
        raise ValueError("plotting traces needs -o OUT.png")
    from madsim.render.plots import plot_traces

    rows = None
    if args.cars is not None:
        try:
            rows = [int(v) for v in _names(args.cars)]
        except ValueError:
            raise ValueError(f"--cars must be comma-separated car rows (0, 1, ...), got {args.cars!r}") from None
    n = plot_traces(args.traces, args.output, track=args.track, cars=rows, labels=_names(args.labels),
                    title=args.title)
    print(f"madsim plot: {n} run(s) -> {args.output}")
    return 0


def add_render_commands(sub) -> None:
    """Add `render` and `plot` to the sub-parsers `sub` of the madsim CLI."""
    r = sub.add_parser("render", help="replay a `madsim serve --log-csv` trace as a video (MP4 or GIF)")
    r.add_argument("trace", help="the trace CSV")
    r.add_argument("-o", "--output", required=True, help="out.mp4 or out.gif")
    r.add_argument("--track", default="madsim-road", help="the track the trace was recorded on")
    r.add_argument("--cars", default=None, help="car names by row, comma-separated (body sizes)")
    r.add_argument("--car", type=int, default=0, help="row the camera follows and the HUD shows")
    r.add_argument("--camera", choices=CAMERAS, default="follow",
                   help="track: whole track; follow: north up; rotate: the car points up")
    r.add_argument("--zoom", type=float, default=6.0, help="pixels per metre of follow/rotate")
    r.add_argument("--size", type=_size, default=(800, 600), help="WIDTHxHEIGHT pixels")
    r.add_argument("--every", type=int, default=None, help="draw every k-th tick (GIF default 5)")
    r.add_argument("--fps", type=float, default=None, help="playback rate (default real time)")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    r.set_defaults(func=cmd_render)
    p = sub.add_parser("plot", help="plot traces (trajectory by speed, speed and trackPos) or the "
                                    "learning curves of a `madsim train` run folder")
    p.add_argument("traces", nargs="+", help="one or more trace CSVs (overlaid), or one run folder")
    p.add_argument("-o", "--output", default=None,
                   help="image file (PNG, SVG, PDF); for a run folder default RUN_DIR/learning_curves.png")
    p.add_argument("--track", default="madsim-road", help="the track the traces were recorded on")
    p.add_argument("--cars", default=None, help="car rows to plot, comma-separated (default all)")
    p.add_argument("--labels", default=None, help="one name per trace, comma-separated")
    p.add_argument("--title", default=None)
    p.set_defaults(func=cmd_plot)
