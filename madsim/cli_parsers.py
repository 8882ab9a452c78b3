"""The `madsim` command line's whole parser tree, in one place: every subcommand and option.

`build_parser()` adds the subcommands in the order of SUBCOMMANDS (one `add_..._parser(sub)`
each, here). A subcommand's handler is named as "module:function" and imported only when the
command runs, so building the parser (`madsim --help`, docs/cli.md) imports no command's
dependencies; the handlers live beside the code they drive (madsim/cli.py, train/commands.py,
experiments/commands.py, render/commands.py, agents/traffic_client.py).
"""

from __future__ import annotations

import argparse
import importlib

__all__ = ["Parser", "build_parser", "positive_int", "seed_int", "udp_port"]


def _handler(target: str):
    """The handler "module:function" as a callable args -> exit status, imported when called."""
    module, name = target.split(":")

    def run(args):
        return getattr(importlib.import_module(module), name)(args)

    run.__qualname__ = run.__name__ = target
    return run


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


def add_import_option(parser) -> None:
    """`--import MODULE_OR_FILE` (repeatable): the user's rewards, dones, behaviours."""
    parser.add_argument("--import", dest="imports", action="append", default=[], metavar="MODULE",
                        help="import this module or .py file first (registers your rewards, dones, "
                             "traffic behaviours); repeatable; or list them under `plugins:` in the YAML")


# --- arguments of each subcommand ----------------------------------------------------------


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
    r.set_defaults(func=_handler("madsim.cli:cmd_run"))


def add_tracks_parser(sub) -> None:
    """`madsim tracks`."""
    tracks = sub.add_parser("tracks", help="list, inspect, draw and generate tracks")
    tsub = tracks.add_subparsers(dest="tracks_command", required=True)
    t = tsub.add_parser("list", help="bundled and installed TORCS tracks")
    t.add_argument("--json", action="store_true")
    t.set_defaults(func=_handler("madsim.cli:cmd_tracks_list"))
    t = tsub.add_parser("info", help="facts about one track")
    t.add_argument("track", help="track name or path")
    t.add_argument("--json", action="store_true")
    t.set_defaults(func=_handler("madsim.cli:cmd_tracks_info"))
    t = tsub.add_parser("show", help="draw a track map")
    t.add_argument("track", help="track name or path")
    t.add_argument("-o", "--output", required=True, help="image file (e.g. map.png)")
    t.add_argument("--marks", type=float, default=500.0, help="distance marks every M metres (0: none)")
    t.set_defaults(func=_handler("madsim.cli:cmd_tracks_show"))
    t = tsub.add_parser("generate", help="write a random closed track as TORCS XML")
    t.add_argument("--seed", type=int, required=True)
    t.add_argument("--length", type=float, default=3000.0, help="approximate length, m")
    t.add_argument("--width", type=float, default=12.0, help="road width, m")
    t.add_argument("--name", default=None)
    t.add_argument("-o", "--output", required=True)
    t.set_defaults(func=_handler("madsim.cli:cmd_tracks_generate"))


def add_cars_parser(sub) -> None:
    """`madsim cars`."""
    cars = sub.add_parser("cars", help="list and inspect cars")
    csub = cars.add_subparsers(dest="cars_command", required=True)
    c = csub.add_parser("list", help="bundled and installed TORCS cars")
    c.add_argument("--json", action="store_true")
    c.set_defaults(func=_handler("madsim.cli:cmd_cars_list"))
    c = csub.add_parser("info", help="facts about one car")
    c.add_argument("car", help="car name or path")
    c.add_argument("--json", action="store_true")
    c.set_defaults(func=_handler("madsim.cli:cmd_cars_info"))


def add_config_parser(sub) -> None:
    """`madsim config`."""
    cfg = sub.add_parser("config", help="check or show a scenario configuration (YAML)")
    gsub = cfg.add_subparsers(dest="config_command", required=True)
    g = gsub.add_parser("check", help="validate a config file (MADRaS files accepted)")
    g.add_argument("file")
    add_import_option(g)
    g.set_defaults(func=_handler("madsim.cli:cmd_config_check"))
    g = gsub.add_parser("show", help="print the fully resolved config with defaults")
    g.add_argument("file")
    add_import_option(g)
    g.set_defaults(func=_handler("madsim.cli:cmd_config_show"))


def add_serve_parser(sub) -> None:
    """`madsim serve`."""
    sv = sub.add_parser("serve", help="a drop-in TORCS scr_server on UDP")
    sv.add_argument("--track", default="madsim-road")
    sv.add_argument("--cars", default="madsim-sedan", help="comma-separated car names, one per client")
    sv.add_argument("--clients", type=int, default=1)
    sv.add_argument("--host", default="127.0.0.1")
    sv.add_argument("--port", type=udp_port, default=3001)
    sv.add_argument("--laps", type=int, default=None,
                    help="the race's laps: a car past them, or at its first crossing after another's "
                         "finish, has finished (no more damage, slow pace, its laps stop); the race ends "
                         "when every car has finished or a finished car crosses again (TORCS's rules; "
                         "default: no end)")
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
    sv.add_argument("--lap-time-limit", action="store_true",
                    help="TORCS's lap-time limit: a car whose current lap has lasted longer than 84.5 s + "
                         "the track's length at 10 m/s is out of the race (default off, as torcs -nolaptime)")
    sv.add_argument("--log-csv", default=None, help="write a per-tick trace to this CSV file")
    sv.set_defaults(func=_handler("madsim.cli:cmd_serve"))


def add_drive_parser(sub) -> None:
    """`madsim drive`."""
    dv = sub.add_parser("drive", help="drive one car of a scr_server with the built-in simple driver")
    dv.add_argument("--host", default="127.0.0.1")
    dv.add_argument("--port", type=udp_port, default=3001)
    dv.add_argument("--id", default="SCR")
    dv.add_argument("--driver", choices=["simple"], default="simple",
                    help="simple: steer to the track axis, slow for bends, shift by rpm")
    dv.add_argument("--max-steps", type=int, default=None)
    dv.add_argument("--wait", type=float, default=60.0,
                    help="seconds to look for the server (and to wait for it mid-race) before giving up")
    dv.set_defaults(func=_handler("madsim.cli:cmd_drive"))


def add_convert_parser(sub) -> None:
    """`madsim convert`."""
    conv = sub.add_parser("convert", help="convert TORCS assets to madsim's compiled form and back")
    vsub = conv.add_subparsers(dest="convert_command", required=True)
    v = vsub.add_parser("track", help="TORCS XML <-> compiled .mtrack")
    v.add_argument("input")
    v.add_argument("-o", "--output", required=True)
    v.set_defaults(func=_handler("madsim.cli:cmd_convert_track"))
    v = vsub.add_parser("car", help="TORCS car XML <-> compiled .json")
    v.add_argument("input")
    v.add_argument("-o", "--output", required=True)
    v.set_defaults(func=_handler("madsim.cli:cmd_convert_car"))


def _size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"size must be WIDTHxHEIGHT, e.g. 800x600, got {text!r}") from None
    if w < 16 or h < 16:
        raise argparse.ArgumentTypeError(f"size must be at least 16x16, got {text!r}")
    return w, h


def add_traffic_parser(sub) -> None:
    """`madsim traffic`."""
    from madsim.agents.traffic import BEHAVIOURS

    tp = sub.add_parser("traffic", help="drive cars of a scr_server with a traffic behaviour")
    tp.add_argument("--behaviour", required=True, help=f"one of: {', '.join(sorted(BEHAVIOURS))}")
    tp.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                    help="behaviour parameter in SI units (repeatable), e.g. target_speed=12.5")
    tp.add_argument("--host", default="127.0.0.1")
    tp.add_argument("--port", type=int, default=3001, help="port of the first car")
    tp.add_argument("--count", type=int, default=1, help="cars, on ports PORT .. PORT+COUNT-1")
    tp.add_argument("--seed", type=int, default=0, help="car k draws from default_rng([SEED, k])")
    tp.add_argument("--car", default=None, help="car model, for its size and steering (default sedan)")
    tp.add_argument("--track-length", type=float, default=None,
                    help="m; else learnt at the first start-line crossing")
    tp.add_argument("--collision-time-window", type=float, default=1.0, help="s of headway")
    tp.add_argument("--min-safe-dist", type=float, default=1.0, help="m to cars and road edges")
    tp.add_argument("--max-steps", type=int, default=None)
    tp.set_defaults(func=_handler("madsim.agents.traffic_client:cmd_traffic"))


def add_train_parser(sub) -> None:
    """`madsim train` (its run folders are plotted by `madsim plot DIR`)."""
    t = sub.add_parser("train", help="train a policy with PPO (extra [train]: torch, stable-baselines3)")
    t.add_argument("config", help="scenario YAML with one learning agent (e.g. examples/ts_single_lap.yml)")
    t.add_argument("--algo", choices=["ppo"], default="ppo")
    t.add_argument("--steps", type=int, required=True, help="env steps to train, over all envs")
    t.add_argument("--out", required=True, help="run folder: policy.zip, CSV logs, checkpoints, config")
    t.add_argument("--num-envs", type=int, default=1, help="episodes stepped side by side")
    t.add_argument("--seed", type=int, default=0)
    t.add_argument("--eval-every", type=int, default=None,
                   help="env steps between evaluations (default: steps / 10)")
    t.add_argument("--eval-episodes", type=int, default=3)
    t.add_argument("--n-steps", type=int, default=None,
                   help="PPO rollout length per env (default 2048 / num-envs)")
    t.add_argument("--gamma", type=float, default=0.99, help="discount per env step")
    t.add_argument("--ent-coef", type=float, default=0.0, help="PPO entropy bonus")
    t.add_argument("--vec", choices=["auto", "native", "sync"], default="auto",
                   help="vector env: madsim's batched make_vec (native), gymnasium's SyncVectorEnv "
                        "of MadrasEnv (sync), or native when installed (auto)")
    t.add_argument("--overwrite", action="store_true", help="reuse an --out folder holding a run")
    t.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_import_option(t)
    t.set_defaults(func=_handler("madsim.train.commands:cmd_train"))


def add_experiment_parser(sub) -> None:
    """`madsim experiment` (list, run, report)."""
    from madsim.experiments.registry import BUDGETS

    e = sub.add_parser("experiment", help="the MADRaS paper's six experiments: list, run, report")
    esub = e.add_subparsers(dest="experiment_command", required=True)
    ls = esub.add_parser("list", help="the experiments, their sub-runs and the budgets")
    ls.set_defaults(func=_handler("madsim.experiments.commands:cmd_list"))
    r = esub.add_parser("run", help="train, evaluate over 100 episodes, write a result folder")
    r.add_argument("name", help="exp1..exp6, or a sub-run such as exp1-sab, exp1-ts, exp2-random")
    r.add_argument("--budget", choices=list(BUDGETS), default="smoke")
    r.add_argument("--out", default=None, help="result folder (default runs/NAME-BUDGET-seedS)")
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--address", default=None,
                   help="Ray cluster for exp6's RLlib training ('auto' or ray://HOST:10001)")
    r.set_defaults(func=_handler("madsim.experiments.commands:cmd_run"))
    p = esub.add_parser("report", help="rewrite table.md and the picture of a result folder")
    p.add_argument("dir")
    p.set_defaults(func=_handler("madsim.experiments.commands:cmd_report"))


def add_render_parsers(sub) -> None:
    """`madsim render` and `madsim plot` (traces, or a `madsim train` run folder)."""
    from madsim.render.scene import CAMERAS

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
    r.set_defaults(func=_handler("madsim.render.commands:cmd_render"))
    p = sub.add_parser("plot", help="plot traces (trajectory by speed, speed and trackPos) or the "
                                    "learning curves of a `madsim train` run folder")
    p.add_argument("traces", nargs="+", help="one or more trace CSVs (overlaid), or one run folder")
    p.add_argument("-o", "--output", default=None,
                   help="image file (PNG, SVG, PDF); for a run folder default RUN_DIR/learning_curves.png")
    p.add_argument("--track", default="madsim-road", help="the track the traces were recorded on")
    p.add_argument("--cars", default=None, help="car rows to plot, comma-separated (default all)")
    p.add_argument("--labels", default=None, help="one name per trace, comma-separated")
    p.add_argument("--title", default=None)
    p.set_defaults(func=_handler("madsim.render.commands:cmd_plot"))


# One function per subcommand (or family), called in this order by build_parser.
SUBCOMMANDS = (add_run_parser, add_tracks_parser, add_cars_parser, add_config_parser, add_serve_parser,
               add_drive_parser, add_traffic_parser, add_train_parser, add_experiment_parser,
               add_convert_parser, add_render_parsers)


def build_parser() -> argparse.ArgumentParser:
    from madsim import __version__

    p = Parser(prog="madsim", description="madsim: a TORCS-like driving simulator for RL.")
    p.add_argument("--version", action="version", version=f"madsim {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    for add in SUBCOMMANDS:
        add(sub)
    return p
