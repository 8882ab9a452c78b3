"""The `madsim` command line: tracks, cars, convert (more doors are added by later layers)."""

from __future__ import annotations

import argparse
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
                       damage: bool = True, grid: dict | None = None):
    """A function seed -> World on the starting grid (cars repeat the last name if short);
    `grid`: the race's Starting Grid values (`World.reset(grid=...)`)."""
    import numpy as np

    from madsim.cars import load_car
    from madsim.physics.world import World, check_grid
    from madsim.tracks import load_track

    track = load_track(track_name)
    specs = [load_car(n) for n in car_names]
    specs += [specs[-1]] * (n_cars - len(specs))

    def make(seed: int):
        world = World(track, specs[:n_cars], np.random.default_rng(seed), fuel=fuel, damage=damage)
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
                                  damage=not args.nodamage, grid=parse_grid(args.grid))
    except ValueError as exc:
        raise CliError(str(exc)) from None
    server = ScrServer(make, args.clients, tick_schedule=args.tick_schedule, host=args.host, port=args.port, mode=args.mode,
                       timeout_ms=args.timeout_ms, noisy=args.noisy, identified_reply=args.identified_reply,
                       seed=args.seed, laps=args.laps, max_ticks=args.max_ticks, countdown_ticks=args.countdown,
                       start_timeout_s=args.start_timeout, client_deadline_s=args.client_deadline,
                       log=lambda m: print(f"madsim serve: {m}", flush=True), log_csv=args.log_csv)
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


# --- parser -------------------------------------------------------------------------------


class Parser(argparse.ArgumentParser):
    """argparse with errors on one line (no usage block): `madsim run: error: ...`."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _int(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    value = _int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def seed_int(text: str) -> int:
    """argparse type: a seed, an integer >= 0 (numpy's seeds are non-negative)."""
    value = _int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"a seed must be >= 0, got {value}")
    return value


def udp_port(text: str) -> int:
    """argparse type: a UDP port, 1..65535."""
    value = _int(text)
    if not 1 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"a UDP port is 1..65535, got {value}")
    return value



def add_run_parser(sub) -> None:
    """`madsim run`."""
    r = sub.add_parser("run", help="drive a scenario (default: one lap of madsim-road with traffic)")
    r.add_argument("config", nargs="?", default=None, help="scenario YAML (default: the bundled run scenario)")
    r.add_argument("--episodes", type=positive_int, default=1)
    r.add_argument("--driver", default="pid",
                   help="pid: the built-in driver fitting each agent's action space (T-S: lane and speed "
                        "through the PID; S-A-B: steering and pedals); random; or a saved policy")
    r.add_argument("--seed", type=seed_int, default=0)
    r.add_argument("--video", default=None,
                   help="write the episodes as out.mp4 (800x600, 25 frames/s) or out.gif (400x300, 5 frames/s: "
                        "about 5 MB a lap)")
    r.add_argument("--plot", default=None, help="write trajectories and speed/trackPos plots (PNG)")
    r.add_argument("--render", action="store_true", help="open a window")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.add_argument("--max-steps", type=positive_int, default=None, help="end each episode after this many env steps")
    r.add_argument("--port", type=udp_port, default=None,
                   help="drive the cars of a running SCR server (madsim serve, TORCS) from this UDP port on")
    r.add_argument("--host", default="127.0.0.1", help="the SCR server's host (with --port)")
    add_import_option(r)
    r.set_defaults(func=cmd_run)


def add_tracks_parser(sub) -> None:
    """`madsim tracks`."""
    tracks = sub.add_parser("tracks", help="list, inspect, draw and generate tracks")
    tsub = tracks.add_subparsers(dest="tracks_command", required=True)
    t = tsub.add_parser("list", help="bundled and installed TORCS tracks")
    t.add_argument("--json", action="store_true")
    t.set_defaults(func=cmd_tracks_list)
    t = tsub.add_parser("info", help="facts about one track")
    t.add_argument("track", help="track name or path")
    t.add_argument("--json", action="store_true")
    t.set_defaults(func=cmd_tracks_info)
    t = tsub.add_parser("show", help="draw a track map")
    t.add_argument("track", help="track name or path")
    t.add_argument("-o", "--output", required=True, help="image file (e.g. map.png)")
    t.add_argument("--marks", type=float, default=500.0, help="distance marks every M metres (0: none)")
    t.set_defaults(func=cmd_tracks_show)
    t = tsub.add_parser("generate", help="write a random closed track as TORCS XML")
    t.add_argument("--seed", type=int, required=True)
    t.add_argument("--length", type=float, default=3000.0, help="approximate length, m")
    t.add_argument("--width", type=float, default=12.0, help="road width, m")
    t.add_argument("--name", default=None)
    t.add_argument("-o", "--output", required=True)
    t.set_defaults(func=cmd_tracks_generate)


def add_cars_parser(sub) -> None:
    """`madsim cars`."""
    cars = sub.add_parser("cars", help="list and inspect cars")
    csub = cars.add_subparsers(dest="cars_command", required=True)
    c = csub.add_parser("list", help="bundled and installed TORCS cars")
    c.add_argument("--json", action="store_true")
    c.set_defaults(func=cmd_cars_list)
    c = csub.add_parser("info", help="facts about one car")
    c.add_argument("car", help="car name or path")
    c.add_argument("--json", action="store_true")
    c.set_defaults(func=cmd_cars_info)


def add_config_parser(sub) -> None:
    """`madsim config`."""
    cfg = sub.add_parser("config", help="check or show a scenario configuration (YAML)")
    gsub = cfg.add_subparsers(dest="config_command", required=True)
    g = gsub.add_parser("check", help="validate a config file (MADRaS files accepted)")
    g.add_argument("file")
    add_import_option(g)
    g.set_defaults(func=cmd_config_check)
    g = gsub.add_parser("show", help="print the fully resolved config with defaults")
    g.add_argument("file")
    add_import_option(g)
    g.set_defaults(func=cmd_config_show)


def add_serve_parser(sub) -> None:
    """`madsim serve`."""
    sv = sub.add_parser("serve", help="a drop-in TORCS scr_server on UDP")
    sv.add_argument("--track", default="madsim-road")
    sv.add_argument("--cars", default="madsim-sedan", help="comma-separated car names, one per client")
    sv.add_argument("--clients", type=int, default=1)
    sv.add_argument("--host", default="127.0.0.1")
    sv.add_argument("--port", type=udp_port, default=3001)
    sv.add_argument("--laps", type=int, default=None)
    sv.add_argument("--mode", choices=["sync", "timeout", "realtime"], default="sync")
    sv.add_argument("--timeout-ms", type=float, default=10.0)
    sv.add_argument("--noisy", action="store_true", help="SCR sensor noise (as torcs -noisy)")
    sv.add_argument("--identified-reply", choices=["plain", "pid"], default="plain",
                    help="'pid' answers ***identified***:<pid> as MADRaS' snakeoil expects")
    sv.add_argument("--seed", type=int, default=0)
    sv.add_argument("--max-ticks", type=int, default=None)
    sv.add_argument("--countdown", type=int, default=49, help="frozen ticks before the start (TORCS: 49)")
    sv.add_argument("--tick-schedule", choices=["fixed", "torcs"], default="fixed",
                    help="'fixed': every tick 20 ms; 'torcs': TORCS's own 20 or 22 ms driver calls")
    sv.add_argument("--grid", default=None,
                    help="the race's Starting Grid, e.g. rows=1,distance_to_start=100 (the track's own "
                         "grid overrides it, as in TORCS); default quickrace's: 2 rows, 25 m")
    sv.add_argument("--start-timeout", type=float, default=None, help="give up if clients do not come (s)")
    sv.add_argument("--client-deadline", type=float, default=5.0,
                    help="sync mode: seconds of silence before a client is treated as in timeout mode")
    sv.add_argument("--nofuel", action="store_true")
    sv.add_argument("--nodamage", action="store_true")
    sv.add_argument("--log-csv", default=None, help="write a per-tick trace to this CSV file")
    sv.set_defaults(func=cmd_serve)


def add_drive_parser(sub) -> None:
    """`madsim drive`."""
    dv = sub.add_parser("drive", help="drive one car of a scr_server with the built-in simple driver")
    dv.add_argument("--host", default="127.0.0.1")
    dv.add_argument("--port", type=udp_port, default=3001)
    dv.add_argument("--id", default="SCR")
    dv.add_argument("--driver", choices=["simple"], default="simple",
                    help="simple: steer to the track axis, slow for bends, shift by rpm")
    dv.add_argument("--max-steps", type=int, default=None)
    dv.add_argument("--wait", type=float, default=30.0,
                    help="seconds to look for the server (and to wait for it mid-race) before giving up")
    dv.set_defaults(func=cmd_drive)


def add_convert_parser(sub) -> None:
    """`madsim convert`."""
    conv = sub.add_parser("convert", help="convert TORCS assets to madsim's compiled form and back")
    vsub = conv.add_subparsers(dest="convert_command", required=True)
    v = vsub.add_parser("track", help="TORCS XML <-> compiled .mtrack")
    v.add_argument("input")
    v.add_argument("-o", "--output", required=True)
    v.set_defaults(func=cmd_convert_track)
    v = vsub.add_parser("car", help="TORCS car XML <-> compiled .json")
    v.add_argument("input")
    v.add_argument("-o", "--output", required=True)
    v.set_defaults(func=cmd_convert_car)


def _add_traffic_parser(sub) -> None:
    from madsim.agents.traffic_client import add_traffic_parser

    add_traffic_parser(sub)


def _add_train_parser(sub) -> None:
    from madsim.train.commands import add_parsers

    add_parsers(sub, with_plot=False)   # madsim train; `madsim plot DIR` is render's plot


def _add_experiment_parser(sub) -> None:
    from madsim.experiments.commands import add_parser

    add_parser(sub)


def _add_render_parsers(sub) -> None:
    from madsim.render.commands import add_render_commands

    add_render_commands(sub)


# One function per subcommand (or family), called in this order by build_parser: a new
# subcommand is one function here, or an `add_...(sub)` in its own module listed here.
SUBCOMMANDS = (add_run_parser, add_tracks_parser, add_cars_parser, add_config_parser, add_serve_parser,
               add_drive_parser, _add_traffic_parser, _add_train_parser, _add_experiment_parser,
               add_convert_parser, _add_render_parsers)


def build_parser() -> argparse.ArgumentParser:
    from madsim import __version__

    p = Parser(prog="madsim", description="madsim: a TORCS-like driving simulator for RL.")
    p.add_argument("--version", action="version", version=f"madsim {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    for add in SUBCOMMANDS:
        add(sub)
    return p


def add_import_option(parser) -> None:
    """`--import MODULE_OR_FILE` (repeatable): the user's rewards, dones, behaviours."""
    parser.add_argument("--import", dest="imports", action="append", default=[], metavar="MODULE",
                        help="import this module or .py file first (registers your rewards, dones, "
                             "traffic behaviours); repeatable; or list them under `plugins:` in the YAML")


def main(argv: list[str] | None = None) -> int:
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
    sys.exit(main())
