"""`madsim render` and `madsim plot`: the handlers of this package's commands (their options:
madsim.cli_parsers). Bad input raises ValueError (the CLI prints it as one line), a missing
optional dependency is reported the same way.
"""

from __future__ import annotations

import sys


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
