"""The `madsim` command line: `main`, and the handlers of the commands that have no package of
their own (run, tracks, cars, config, serve, drive, convert). Every subcommand's options, and the
parser tree, are in madsim.cli_parsers."""

from __future__ import annotations

import json
import sys
from pathlib import Path


class CliError(Exception):
    """A user-facing failure: printed as one line, exit status 2."""


def output_path(text: str) -> Path:
    """An output file's path with its folder created (as `-o gen/gen.xml` promises)."""
    path = Path(text)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CliError(f"cannot create the folder of {text}: {exc.strerror}") from None
    return path


# --- tracks -------------------------------------------------------------------------------


def _track_summary(track) -> dict:
    zmin, zmax = track.elevation_range
    return {
        "name": track.name, "title": track.title, "category": track.category, "length": track.length,
        "width": track.width, "closure_gap": track.closure_gap,
        "closure_heading_gap_deg": float(__import__("math").degrees(track.closure_heading_gap)),
        "segments": track.n_segments, "pieces": track.n_pieces,
        "elevation_min": zmin, "elevation_max": zmax, "bounding_box": list(track.bounding_box),
        "version": track.version, "source": track.source,
    }


def cmd_tracks_list(args) -> int:
    from madsim.tracks import list_tracks, load_track

    rows = []
    for entry in list_tracks():
        try:
            t = load_track(entry["path"])
            rows.append({**entry, "category": t.category, "length": t.length, "width": t.width})
        except ValueError as exc:
            rows.append({**entry, "category": "?", "length": None, "width": None, "error": str(exc)})
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    print(f"{'name':16s} {'category':8s} {'length (m)':>11s} {'width (m)':>9s}  source")
    for r in rows:
        length = f"{r['length']:11.2f}" if r["length"] is not None else f"{'error':>11s}"
        width = f"{r['width']:9g}" if r["width"] is not None else f"{'':9s}"
        print(f"{r['name']:16s} {r['category']:8s} {length} {width}  {r['source']}")
    return 0


def cmd_tracks_info(args) -> int:
    from madsim.tracks import load_track

    info = _track_summary(load_track(args.track))
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    for k, v in info.items():
        if isinstance(v, float):
            v = f"{v:.4f}" if "gap" in k else f"{v:.2f}"
        elif isinstance(v, list):
            v = ", ".join(f"{x:.1f}" for x in v)
        print(f"{k:24s} {v}")
    return 0


def cmd_tracks_show(args) -> int:
    from madsim.render.trackmap import save_track_map
    from madsim.tracks import load_track

    track = load_track(args.track)
    save_track_map(track, output_path(args.output), marks_every_m=args.marks)
    print(f"wrote {args.output} ({track.name}, {track.length:.2f} m)")
    return 0


def cmd_tracks_generate(args) -> int:
    from madsim.tracks.generate import generate_track_xml

    try:
        text = generate_track_xml(args.seed, length_m=args.length, width_m=args.width, name=args.name)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    output_path(args.output).write_text(text, encoding="utf-8")
    print(f"wrote {args.output}")
    return 0


# --- convert ------------------------------------------------------------------------------


def cmd_convert_track(args) -> int:
    from madsim.tracks import load_track
    from madsim.tracks.compiled import save_compiled, track_to_xml
    from madsim.tracks.library import COMPILED_SUFFIX

    out = Path(args.output)
    if out.suffix not in (COMPILED_SUFFIX, ".xml"):
        raise CliError(f"output must end in {COMPILED_SUFFIX} (compiled) or .xml (TORCS XML), got '{out.name}'")
    track = load_track(args.input)
    output_path(args.output)
    if out.suffix == COMPILED_SUFFIX:
        save_compiled(track, out)
    else:
        out.write_text(track_to_xml(track), encoding="utf-8")
    print(f"wrote {out} ({track.name}, {track.length:.2f} m, {track.n_pieces} pieces)")
    return 0


def cmd_convert_car(args) -> int:
    from madsim.cars import load_car
    from madsim.cars.catalog import car_to_json, car_to_xml

    out = Path(args.output)
    if out.suffix not in (".json", ".xml"):
        raise CliError(f"output must end in .json (compiled) or .xml (TORCS XML), got '{out.name}'")
    spec = load_car(args.input)
    output_path(args.output)
    out.write_text(car_to_json(spec) if out.suffix == ".json" else car_to_xml(spec), encoding="utf-8")
    print(f"wrote {out} ({spec.name})")
    return 0


# --- cars ---------------------------------------------------------------------------------


def cmd_cars_list(args) -> int:
    from madsim.cars.catalog import list_cars

    rows = list_cars()
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    print(f"{'name':16s} {'category':16s} {'drive':5s} {'mass (kg)':>9s} {'power (kW)':>10s}  source")
    for r in rows:
        if r.get("error"):
            print(f"{r['name']:16s} {'?':16s} {'?':5s} {'error':>9s} {'':>10s}  {r['source']}: {r['error'].splitlines()[0]}")
            continue
        print(f"{r['name']:16s} {r['category'] or '-':16s} {r['drive_type']:5s} "
              f"{r['mass_kg']:9.0f} {r['power_kw']:10.0f}  {r['source']}")
    return 0


def cmd_cars_info(args) -> int:
    from madsim.cars.catalog import car_info

    info = car_info(args.car)
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    for k, v in info.items():
        print(f"{k:24s} {v}")
    return 0


# --- run ---------------------------------------------------------------------------------


def cmd_run(args) -> int:
    from madsim.run import RunInterrupted, run

    try:
        run(args.config, episodes=args.episodes, driver=args.driver, seed=args.seed, video=args.video,
            plot=args.plot, render=args.render, progress=not args.quiet, host=args.host, port=args.port,
            max_steps=args.max_steps)
    except RunInterrupted as exc:
        print(f"madsim run: {exc}", file=sys.stderr, flush=True)
        return exc.status
    return 0


# --- config -------------------------------------------------------------------------------


def cmd_config_check(args) -> int:
    from madsim.envs.config import check_config

    print(check_config(args.file))
    return 0


def cmd_config_show(args) -> int:
    from madsim.envs.config import show_config

    print(show_config(args.file), end="")
    return 0


# --- serve / drive --------------------------------------------------------------------------


def make_world_factory(track_name: str, car_names: list[str], n_cars: int, *, fuel: bool = False,
                       damage: bool = True, grid: dict | None = None, race_laps: int | None = None):
    """A function seed -> World on the starting grid (cars repeat the last name if short);
    `grid`: the race's Starting Grid values (`World.reset(grid=...)`); `race_laps`: the race's
    laps (a car past them has finished and takes no damage; None: no end)."""
    import numpy as np

    from madsim.cars import load_car
    from madsim.physics.world import World, check_grid
    from madsim.tracks import load_track

    track = load_track(track_name)
    specs = [load_car(n) for n in car_names]
    specs += [specs[-1]] * (n_cars - len(specs))

    def make(seed: int):
        world = World(track, specs[:n_cars], np.random.default_rng(seed), fuel=fuel, damage=damage,
                      race_laps=race_laps)
        world.reset(grid=grid)
        return world
    check_grid(grid)        # a bad grid fails here, before any socket is opened
    return make


def parse_grid(text: str | None) -> dict | None:
    """"rows=1,distance_to_start=100" -> {"rows": 1.0, "distance to start": 100.0}."""
    if not text:
        return None
    out = {}
    for item in text.split(","):
        key, sep, value = item.partition("=")
        try:
            out[key.strip().replace("_", " ")] = float(value)
        except ValueError:
            raise CliError(f"--grid: {item!r} is not NAME=NUMBER") from None
        if not sep:
            raise CliError(f"--grid: {item!r} is not NAME=NUMBER")
    return out


def cmd_serve(args) -> int:
    import signal

    from madsim.interrupts import StopRequest
    from madsim.net.server import ScrServer, ServerError

    cars = [c for c in args.cars.split(",") if c]
    try:
        make = make_world_factory(args.track, cars, args.clients, fuel=not args.nofuel,
                                  damage=not args.nodamage, grid=parse_grid(args.grid), race_laps=args.laps)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    server = ScrServer(make, args.clients, tick_schedule=args.tick_schedule, host=args.host, port=args.port, mode=args.mode,
                       timeout_ms=args.timeout_ms, noisy=args.noisy, identified_reply=args.identified_reply,
                       seed=args.seed, laps=args.laps, max_ticks=args.max_ticks, countdown_ticks=args.countdown,
                       start_timeout_s=args.start_timeout, client_deadline_s=args.client_deadline,
                       log=lambda m: print(f"madsim serve: {m}", flush=True), log_csv=args.log_csv,
                       lap_time_limit=args.lap_time_limit)
    try:
        server.open()
    except ServerError as exc:
        raise CliError(str(exc)) from None
    print(f"madsim serve: {args.track}, {args.clients} car(s), mode {args.mode}, "
          f"ports {args.port}..{args.port + args.clients - 1} on {args.host}", flush=True)
    # SIGTERM stops the loop at the next wait; Ctrl-C stays the server's own KeyboardInterrupt
    with StopRequest(on_stop=server.stop, signals=(signal.SIGTERM,)) as stop:
        try:
            server.serve()
        except ServerError as exc:
            raise CliError(str(exc)) from None
    if stop:   # stopping is how a server ends (MADRaS kills it): say so, exit 0
        print(f"madsim serve: stopped by {stop.signal_name}"
              + (f"; trace in {args.log_csv}" if args.log_csv else ""), file=sys.stderr, flush=True)
    return 0


def cmd_drive(args) -> int:
    import math

    from madsim.net.client import ScrClient, ScrTimeout, simple_driver

    drivers = {"simple": simple_driver}
    if not args.wait > 0:
        raise CliError(f"--wait must be > 0 seconds, got {args.wait}")
    client = ScrClient(host=args.host, port=args.port, client_id=args.id,
                       identify_tries=max(1, math.ceil(args.wait)), silent_tries=max(1, math.ceil(args.wait)))
    print(f"madsim drive: looking for an SCR server on {args.host}:{args.port} (up to {args.wait:g} s) ...",
          flush=True)
    try:
        outcome, steps = client.run(drivers[args.driver], max_steps=args.max_steps)
    except ScrTimeout:
        raise CliError(f"no SCR server answered on {args.host}:{args.port} within {args.wait:g} s "
                       "(start one with `madsim serve`, or a TORCS race with scr_server cars)") from None
    finally:
        client.close()
    print(f"madsim drive: {outcome} after {steps} steps")
    return 0


def main(argv: list[str] | None = None) -> int:
    from madsim.cli_parsers import build_parser

    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        if getattr(args, "imports", None):
            from madsim.plugins import import_plugins

            import_plugins(args.imports)
        return int(args.func(args) or 0)
    except BrokenPipeError:  # e.g. `madsim tracks list | head`
        sys.stderr.close()
        return 0
    except CliError as exc:
        print(f"madsim: error: {exc}", file=sys.stderr)
        return 2
    except (ValueError, OSError) as exc:  # TrackError, CarError, ConfigError are ValueErrors
        print(f"madsim: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    # `python -m madsim.cli`: run the imported module's main, whose handlers (imported by name,
    # madsim.cli_parsers) raise that module's CliError, not this __main__ copy's
    from madsim.cli import main as _main

    sys.exit(_main())
