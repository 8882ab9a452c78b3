"""`madsim-torcs`: a stand-in for the SCR-patched `torcs` binary, so that programs which start
TORCS themselves (gym_torcs, MADRaS) drive madsim without a line changed.

Put it on PATH under the name `torcs`, e.g. `ln -s "$(command -v madsim-torcs)" ~/.local/bin/torcs`.
It reads TORCS's command line (spec/scr-protocol.md sections 8, 10 and 12) and runs
`madsim.net.server.ScrServer` in this process, so a pid it reports is its own and safe to kill.

    -r FILE      console race from a TORCS raceman file: the track (`Tracks/1`: name, category),
                 the race named in `Races/1` (its `laps`, or `distance` -> int(distance / L) + 1
                 laps, and its `Starting Grid`), and the scr_server drivers (`Drivers/*` with
                 module `scr_server` and `idx` 0-9; car k of the grid is the k-th of them and
                 listens on port base + idx). Other drivers (TORCS robots) are left out with a note.
    -t USEC      client timeout in MICROseconds: timeout mode, TORCS's behaviour (send, wait,
                 reuse the last controls). Without -t the server runs in sync mode: it waits for
                 every client's answer (deterministic; a silent client is dropped to timeout
                 behaviour after 5 s with a warning).
    -nofuel -nodamage -noisy   as TORCS.
    -nolaptime   no lap-time limit. Without it a car whose current lap has lasted longer than
                 84.5 s + the track's length at 10 m/s is out of the race, as in TORCS (the SCR
                 1.3.7 build ignores -nolaptime; vtorcs, gym_torcs' TORCS, honours it).
    -p PORT      base port (vtorcs). Else $TORCS_PORT (MADRaS' fork). Else 3001 with -r, 3101
                 without (gym_torcs' vtorcs default).
    -tick-schedule fixed|torcs   madsim's option (not TORCS's): `torcs` calls the clients on
                 TORCS's own schedule (0.02 or 0.022 s apart, as real TORCS does, tick for tick);
                 default `fixed` (every 0.02 s).
    -identified plain|pid   the identification reply; default `pid` (***identified***:<pid>)
                 when $TORCS_PORT is set, as MADRaS' fork answers, else `plain`.
    -T -vision -s -k -d -e -m, -a N -ver YEAR -l DIR -L DIR -D DIR: accepted and ignored
                 (a note says so; madsim has no vision field and no GUI).

Without -r (gym_torcs' `torcs -nofuel -nodamage -nolaptime`): vtorcs defaults, one scr_server
car (index 0) on madsim-road, no countdown, no lap limit (the client ends episodes with
`meta 1` or by killing this process). Note that vtorcs polls its robot every 0.2 s; madsim's
server keeps the standard 0.02 s.

Cars: `~/.torcs/drivers/scr_server/scr_server.xml`, else the copy in an installed TORCS data
folder, section `Robots/index/<idx>`, attribute `car name`; without one, SCR's default
car1-trb1 (or madsim-sedan when TORCS's cars are not installed).

Stopping: SIGTERM and SIGKILL end it at once, as they end TORCS (gym_torcs' `pkill torcs`
matches it: the process is named after the script, `torcs` or `madsim-torcs`; MADRaS kills the
pid from the identification reply), which frees the ports for the relaunch. Ctrl-C first sends
`***shutdown***` to the clients. In console mode (-r) it exits when the race is over.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

NBBOTS = 10                   # scr_server instances in one TORCS (spec section 1)
DEFAULT_CAR = "car1-trb1"     # SCR's scr_server.xml chooses it for every instance
FALLBACK_CAR = "madsim-sedan"
GYM_TORCS_TRACK = "madsim-road"
USAGE = ("usage: madsim-torcs [-r RACE.xml] [-t USEC] [-p PORT] [-nofuel] [-nodamage] [-nolaptime] "
         "[-noisy] [-identified plain|pid] [-T] [-vision]")
_IGNORED_FLAGS = ("-T", "-vision", "-s", "-k", "-d", "-e", "-m")
_IGNORED_WITH_VALUE = ("-a", "-ver", "-l", "-L", "-D")


class StandinError(Exception):
    """Bad command line or race set-up: printed as one line, exit status 2."""


@dataclass
class Options:
    """TORCS's command line, parsed."""

    race_file: Path | None = None
    timeout_us: int | None = None
    port: int | None = None
    fuel: bool = True
    damage: bool = True
    noisy: bool = False
    lap_time_limit: bool = True       # TORCS's; -nolaptime turns it off (as vtorcs does)
    identified: str | None = None
    tick_schedule: str = "fixed"
    notes: list[str] = field(default_factory=list)


@dataclass
class RacePlan:
    """What to run: the track, one car name and one scr_server index per grid slot, laps
    (None: no limit) or a race distance (m), countdown ticks and the race file's
    `Starting Grid` values (SI)."""

    track: str
    cars: list[str]
    indices: list[int]
    laps: int | None
    countdown: int
    distance_m: float | None = None
    grid: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def parse_args(argv: list[str]) -> Options:
    """TORCS's single-dash options; unknown ones are an error (exit 2), as a typo should be."""
    opts = Options()
    args = list(argv)
    while args:
        a = args.pop(0)

        def value(kind=str):
            if not args:
                raise StandinError(f"option {a} needs a value\n{USAGE}")
            text = args.pop(0)
            try:
                return kind(text)
            except ValueError:
                raise StandinError(f"option {a}: {text!r} is not a valid {kind.__name__}") from None

        if a == "-r":
            opts.race_file = Path(os.path.expanduser(value()))
        elif a == "-t":
            opts.timeout_us = value(int)
            if opts.timeout_us <= 0:
                raise StandinError(f"option -t: the timeout must be > 0 microseconds, got {opts.timeout_us}")
        elif a == "-p":
            opts.port = value(int)
        elif a == "-nofuel":
            opts.fuel = False
        elif a == "-nodamage":
            opts.damage = False
        elif a == "-nolaptime":
            opts.lap_time_limit = False
        elif a == "-noisy":
            opts.noisy = True
        elif a == "-tick-schedule":
            opts.tick_schedule = value()
            if opts.tick_schedule not in ("fixed", "torcs"):
                raise StandinError(f"option -tick-schedule: use 'fixed' or 'torcs', got {opts.tick_schedule!r}")
        elif a == "-identified":
            opts.identified = value()
            if opts.identified not in ("plain", "pid"):
                raise StandinError(f"option -identified: use 'plain' or 'pid', got {opts.identified!r}")
        elif a in _IGNORED_FLAGS:
            opts.notes.append(f"option {a} ignored" + (" (madsim sends no img field)" if a == "-vision" else ""))
        elif a in _IGNORED_WITH_VALUE:
            opts.notes.append(f"option {a} {value()} ignored")
        elif a in ("-h", "--help", "-help"):
            print(__doc__)
            raise SystemExit(0)
        else:
            raise StandinError(f"unknown option {a!r}\n{USAGE}")
    return opts


def _track_name(name: str, category: str | None) -> str:
    """An installed TORCS track path for name + category, else the name (bundled, other folder)."""
    from madsim.tracks.library import torcs_data_dirs

    if category:
        for root in torcs_data_dirs():
            p = root / "tracks" / category / name / f"{name}.xml"
            if p.is_file():
                return str(p)
    return name


def read_race(path: Path) -> RacePlan:
    """Track, scr_server drivers, laps and grid of a TORCS raceman file (e.g. quickrace.xml)."""
    from madsim.torcsxml import Num, read_params

    root = read_params(path)
    where = str(path)
    track = root.sub("Tracks/1")
    name = track.str("name") if track is not None else None
    if not name:
        raise StandinError(f"{where}: section Tracks/1 has no 'name' attribute (the track to race on)")
    category = track.str("category")
    plan = RacePlan(track=_track_name(name, category), cars=[], indices=[], laps=None, countdown=49)
    race_name = (root.sub("Races/1").str("name") if root.sub("Races/1") is not None else None) or "Quick Race"
    race = root.sub(race_name)
    if race is not None:   # TORCS: a distance (SI) sets the laps, else `laps`, default 30
        distance = race.num("distance", 0.0)
        if distance >= 0.001:
            plan.distance_m = distance
        else:
            plan.laps = int(race.num("laps", 30.0))
        grid = race.sub("Starting Grid")
        if grid is not None:
            plan.grid = {k: a.value for k, a in grid.attrs.items() if isinstance(a, Num)}
    else:
        plan.notes.append(f"{where}: no section '{race_name}' (named in Races/1): no lap limit")
    drivers = root.sub("Drivers")
    for d in (drivers or ()):
        module = d.str("module", "")
        idx = d.num("idx")
        if module != "scr_server":
            plan.notes.append(f"{where}: Drivers/{d.name}: module '{module}' left out "
                              f"(madsim runs only scr_server cars)")
            continue
        if idx is None or not float(idx).is_integer() or not 0 <= idx < NBBOTS:
            raise StandinError(f"{where}: Drivers/{d.name}: 'idx' must be an integer 0..{NBBOTS - 1}, got {idx}")
        if int(idx) in plan.indices:
            raise StandinError(f"{where}: Drivers/{d.name}: scr_server idx {int(idx)} appears twice")
        plan.indices.append(int(idx))
    if not plan.indices:
        raise StandinError(f"{where}: section Drivers names no scr_server driver (module scr_server, idx 0..9)")
    return plan


def scr_server_file(home: Path) -> Path | None:
    """The scr_server.xml TORCS would read: the user's, else an installed one."""
    from madsim.tracks.library import torcs_data_dirs

    for p in [home / ".torcs" / "drivers" / "scr_server" / "scr_server.xml"] + [
            root / "drivers" / "scr_server" / "scr_server.xml" for root in torcs_data_dirs()]:
        if p.is_file():
            return p
    return None


def choose_cars(indices: list[int], home: Path) -> tuple[list[str], list[str]]:
    """Car name per scr_server index from scr_server.xml (`Robots/index/<i>`, `car name`)."""
    from madsim.cars import load_car
    from madsim.torcsxml import read_params

    path = scr_server_file(home)
    robots = read_params(path).sub("Robots/index") if path is not None else None
    notes, cars = [], []
    for i in indices:
        entry = robots.sub(str(i)) if robots is not None else None
        name = entry.str("car name") if entry is not None else None
        if name:
            try:
                load_car(name)
            except ValueError as exc:
                raise StandinError(f"{path}: Robots/index/{i}: car name '{name}': {exc}") from None
            cars.append(name)
            continue
        try:
            load_car(DEFAULT_CAR)
            cars.append(DEFAULT_CAR)
        except ValueError:
            notes.append(f"scr_server {i}: {DEFAULT_CAR} is not installed; driving {FALLBACK_CAR}")
            cars.append(FALLBACK_CAR)
    return cars, notes


def grid_placements(track, n: int, race_grid: dict[str, float]) -> np.ndarray | None:
    """(n, 3) (s, n, speed) for World.reset from the race file's Starting Grid, overridden by
    the track's (track spec 7, as `madsim.physics.tables.grid_positions`); None when the race
    file changes nothing (the World's own grid is then the same)."""
    from madsim.physics.tables import QUICKRACE_GRID, grid_positions

    keys = set(QUICKRACE_GRID) | {"initial speed"}
    given = {k: v for k, v in race_grid.items() if k in keys}
    if all(QUICKRACE_GRID.get(k) == v for k, v in given.items() if k != "initial speed") \
            and not given.get("initial speed"):
        return None
    s, lateral = grid_positions(track, n, given)
    return np.column_stack([s, lateral, np.full(n, float(given.get("initial speed", 0.0)))])


def make_world_factory(track, plan: RacePlan, *, fuel: bool, damage: bool):
    """seed -> a fresh World on the race's starting grid."""
    from madsim.cars import load_car
    from madsim.physics.world import World

    specs = [load_car(c) for c in plan.cars]
    placements = grid_placements(track, len(specs), plan.grid)

    def make(seed: int):
        world = World(track, specs, np.random.default_rng(seed), fuel=fuel, damage=damage,
                      race_laps=plan.laps)
        world.reset(placements)
        return world
    return make


def build(opts: Options, env: dict[str, str], home: Path):
    """(ScrServer keyword arguments, race plan, Track) for a parsed command line."""
    from madsim.tracks import load_track

    if opts.race_file is not None:
        plan = read_race(opts.race_file)
    else:
        plan = RacePlan(track=GYM_TORCS_TRACK, cars=[], indices=[0], laps=None, countdown=0,
                        notes=["no -r: gym_torcs style race, one car on " + GYM_TORCS_TRACK])
    try:
        track = load_track(plan.track)
    except ValueError as exc:
        raise StandinError(f"{opts.race_file or 'no -r'}: Tracks/1: {exc}") from None
    if plan.distance_m is not None:
        plan.laps = int(plan.distance_m / track.length) + 1
    plan.cars, notes = choose_cars(plan.indices, home)
    plan.notes += notes
    env_port = env.get("TORCS_PORT")
    if opts.port is not None:
        base = opts.port
    elif env_port:
        try:
            base = int(env_port)
        except ValueError:
            raise StandinError(f"TORCS_PORT must be a port number, got {env_port!r}") from None
    else:
        base = 3001 if opts.race_file is not None else 3101
    ports = [base + i for i in plan.indices]
    if not all(0 < p < 65536 for p in ports):
        raise StandinError(f"ports {ports} out of range (base {base})")
    kwargs = dict(n_clients=len(ports), ports=ports, port=ports[0],
                  mode="timeout" if opts.timeout_us is not None else "sync",
                  timeout_ms=opts.timeout_us / 1000.0 if opts.timeout_us is not None else 10.0,
                  noisy=opts.noisy, laps=plan.laps, countdown_ticks=plan.countdown,
                  identified_reply=opts.identified or ("pid" if env_port else "plain"),
                  tick_schedule=opts.tick_schedule, lap_time_limit=opts.lap_time_limit)
    return kwargs, plan, track


def main(argv: list[str] | None = None) -> int:
    """Console entry point `madsim-torcs` (install it as `torcs`)."""
    from madsim.net.server import ScrServer, ServerError

    def log(msg: str) -> None:
        print(f"madsim-torcs: {msg}", flush=True)

    try:
        opts = parse_args(sys.argv[1:] if argv is None else argv)
        kwargs, plan, track = build(opts, dict(os.environ), Path(os.path.expanduser("~")))
        make = make_world_factory(track, plan, fuel=opts.fuel, damage=opts.damage)
        server = ScrServer(make, log=log, **kwargs)
        for note in opts.notes + plan.notes:
            log(note)
        server.open()
        log(f"{plan.track}, {len(plan.cars)} car(s) {', '.join(plan.cars)}, mode {kwargs['mode']}"
            + (f" ({kwargs['timeout_ms']:g} ms)" if kwargs["mode"] == "timeout" else "")
            + f", laps {plan.laps or 'unlimited'}, UDP ports {', '.join(map(str, server.ports))}, "
            f"identified reply {kwargs['identified_reply']}, pid {os.getpid()}")
        server.serve()
    except (StandinError, ServerError, ValueError, OSError) as exc:  # ValueError: track/car/XML errors
        print(f"madsim-torcs: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
