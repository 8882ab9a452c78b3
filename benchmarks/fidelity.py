"""Fidelity against real TORCS 1.3.7: replay the real-TORCS traces through the World.

Each trace in ../shared/torcs-traces/ (see its README) is one race of real TORCS driven by the
fixed reference controller. This script drives madsim's World with the same controller from the
same start (100 m before the line, centred, at rest, after TORCS's 49-message countdown), on
TORCS's own driver-call schedule (20 or 22 ms, `madsim.physics.schedule.TorcsClock`), with fuel
use and damage on, in a race of 2 laps (`World(race_laps=2)`: a finished car takes no damage, as
in TORCS); after its finish madsim drives on for as many messages as TORCS's trace has after its
own (0.2-1.8 s, until TORCS's shutdown). It prints per run:

  lap2 %     second-lap (flying lap) time error against TORCS's lastLapTime
  v rms      RMS speedX difference (km/h), both runs resampled every metre of distance raced
  pos rms    RMS trackPos difference, by distance likewise
  z cm       RMS z difference (cm), by distance; spin %: per-wheel wheelSpinVel RMS difference
             over the RMS of TORCS's (the worst of the four wheels), by distance
  R-L %      each axle's right-minus-left wheelSpinVel (turns, differentials): RMS difference
             over the RMS of TORCS's, by distance (the worse axle)
  dmg        final damage, TORCS / madsim
  off at     distance raced (m) where the car first leaves the road (|trackPos| > 1), TORCS / madsim
  end        how each run ended: laps done, or DNF (TORCS's lap time limit: 84.5 s + length / 10 m/s,
             or damage above TORCS's 10000, `madsim.net.server.MAX_DAMAGE`)

Straight-line runs also print 0-100 km/h and speedX at 10 s against TORCS's.

Run: python benchmarks/fidelity.py [--all | --runs forza,alpine-2] [--jobs 2] [--tick-schedule fixed]
Default (quick): the three straight-line runs and four lap runs.
"""

from __future__ import annotations

import argparse
import csv
import gzip
import math
import multiprocessing
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

TRACES = Path(os.environ.get("MADSIM_TORCS_TRACES",
                             Path(__file__).resolve().parents[1].parent / "shared" / "torcs-traces"))
"""The traces: ../shared/torcs-traces beside the repository, or $MADSIM_TORCS_TRACES."""
QUICK = ("e-track-2__", "forza__car1-trb1__100", "michigan__car1-trb1__150", "g-track-2__car1-trb1__100",
         "alpine-2__car1-trb1__100")
COUNTDOWN_MESSAGES = 49
TRACE_GRID = {"rows": 1, "distance to start": 100.0}
"""The traces' race file's Starting Grid (a track's own grid overrides it, as wheel-2's does)."""
GEAR_UP = (5000, 6000, 6000, 6500, 7000)          # rpm x10 units, from gear 1..5
GEAR_DOWN = (0, 2500, 3000, 3000, 3500, 3500)     # from gear 1..6
STRAIGHT_STOP_S = 16.0
COLUMNS = ("curLapTime", "lastLapTime", "damage", "distRaced", "distFromStart", "speedX", "trackPos", "z",
           "wheelSpinVel_0", "wheelSpinVel_1", "wheelSpinVel_2", "wheelSpinVel_3", "rpm", "gear", "speedZ")


@dataclass
class Run:
    """One replay: the per-message records of TORCS and of madsim (same column names)."""
    name: str
    track: str
    car: str
    mode: str
    torcs: dict = field(default_factory=dict)
    madsim: dict = field(default_factory=dict)
    torcs_lap2: float = math.nan
    madsim_lap2: float = math.nan
    madsim_end: str = ""
    torcs_end: str = ""
    seconds: float = 0.0


def read_trace(path: Path) -> tuple[dict, dict]:
    """(the trace's racing messages (countdown dropped) as arrays by column name, its first
    message as a dict)."""
    with gzip.open(path, "rt", newline="") as f:
        rows = list(csv.reader(f))
    head = rows[0]
    idx = [head.index(c) for c in COLUMNS]
    data = np.array([[float(r[k]) for k in idx] for r in rows[1 + COUNTDOWN_MESSAGES:]])
    first = {c: float(rows[1][head.index(c)]) for c in COLUMNS}
    return {c: data[:, j] for j, c in enumerate(COLUMNS)}, first


def up_speeds_kmh(car) -> list[float]:
    """Straight-line up-shift speeds (trace README): 95 % of the rev limiter, rolling without slip."""
    return [0.95 * car.redline_speed(g) * 3.6 for g in range(1, car.top_gear)]


def controls(sense, prev_gear: int, mode: str, target_kmh: float, up_kmh: list[float]) -> tuple:
    """The reference controller: (steer, accel, brake, gear) from SCR values."""
    angle, pos, speed, rpm = sense
    steer = min(max((angle - 0.5 * pos) / 0.366519, -1.0), 1.0)
    gear = prev_gear
    if mode == "full":
        accel, brake = 1.0, 0.0
        if gear <= len(up_kmh) and speed >= up_kmh[gear - 1]:
            gear += 1
    else:
        e = target_kmh - speed
        accel, brake = min(max(e / 10.0, 0.0), 1.0), min(max(-e / 10.0, 0.0), 1.0)
        if gear < 6 and rpm >= GEAR_UP[gear - 1]:
            gear += 1
        elif gear > 1 and rpm <= GEAR_DOWN[gear - 1]:
            gear -= 1
    return steer, accel, brake, gear


def replay(path: Path, schedule: str = "torcs", until_s: float | None = None, watch=None,
           until_message: int | None = None) -> Run:
    """Drive madsim like the trace's TORCS run and record both (up to race time `until_s` or
    racing message `until_message` if given: both records are cut there). `watch(message,
    world, frame)`, if given, is called at each racing message (0 = the first) before the
    car acts on it (benchmarks/slide_window.py reads madsim's state there)."""
    from madsim.cars import load_car
    from madsim.net.server import MAX_DAMAGE, lap_time_limit_s
    from madsim.physics.schedule import FIRST_MESSAGE_TIME, make_clock
    from madsim.physics.sensors import SensorSuite
    from madsim.physics.world import World
    from madsim.tracks import load_track

    t0 = time.perf_counter()
    track_name, car_name, mode = path.name.removesuffix(".csv.gz").split("__")
    run = Run(path.name.removesuffix(".csv.gz"), track_name, car_name, mode)
    run.torcs, first = read_trace(path)
    lt = run.torcs["lastLapTime"]
    laps_done = np.count_nonzero(np.diff(lt) != 0) + (lt[0] != 0)
    run.torcs_lap2 = float(lt[-1]) if laps_done >= 2 else math.nan
    # TORCS goes on 0.2-1.8 s after the car's finish (its messages are in the trace): madsim
    # drives as many messages past its own finish, the car finished (no damage, as TORCS)
    changes = np.flatnonzero(np.diff(lt) != 0) + 1
    tail = lt.shape[0] - 1 - int(changes[1]) if laps_done >= 2 and changes.size >= 2 else 0
    track = load_track(track_name)
    car = load_car(car_name)
    limit_s = lap_time_limit_s(track.length)
    run.torcs_end = "16 s" if mode == "full" else ("2 laps" if laps_done >= 2 else "DNF")
    world = World(track, [car], np.random.default_rng(0), fuel=True, damage=True,
                  race_laps=None if mode == "full" else 2)
    world.reset(grid=TRACE_GRID)
    suite = SensorSuite(world)
    f = suite.frame()
    if abs(f.distFromStart[0] - first["distFromStart"]) > 0.05 or abs(f.trackPos[0] - first["trackPos"]) > 0.01:
        print(f"{run.name}: start differs from TORCS's: distFromStart {f.distFromStart[0]:.2f} vs "
              f"{first['distFromStart']:.2f}, trackPos {f.trackPos[0]:.3f} vs {first['trackPos']:.3f}", file=sys.stderr)
    u = np.zeros((1, 5))
    for _ in range(COUNTDOWN_MESSAGES):      # TORCS holds the car; the engine revs in neutral
        f = suite.frame()
        u[0] = (controls((f.angle[0], f.trackPos[0], f.speedX[0], f.rpm[0]), 1, mode, 0.0, [])[0],
                1.0, 1.0, 0.0, 0.0)
        world.step(u)
    start_time = world.time - FIRST_MESSAGE_TIME   # race time of the message at start_time is TORCS's first
    suite.reset()                                   # distRaced from the green light
    clock = make_clock(schedule)
    target = 0.0 if mode == "full" else float(mode)
    up = up_speeds_kmh(car)
    gear = 1
    rec = {c: [] for c in COLUMNS}
    while True:
        f = suite.frame()
        race_t = world.time - start_time
        # the first lap's timer runs from the green light, later ones from the line
        cur_lap = race_t if world.laps[0] <= 1 else float(world.cur_lap_time[0])
        vals = (cur_lap, f.lastLapTime[0], f.damage[0], f.distRaced[0], f.distFromStart[0], f.speedX[0],
                f.trackPos[0], f.z[0], *f.wheelSpinVel[0], f.rpm[0], f.gear[0], f.speedZ[0])
        for c, v in zip(COLUMNS, vals):
            rec[c].append(float(v))
        message = len(rec["curLapTime"]) - 1
        if watch is not None:
            watch(message, world, f)
        if until_s is not None and race_t >= until_s:
            run.madsim_end = f"{until_s:g} s"
            break
        if until_message is not None and message >= until_message:
            run.madsim_end = f"message {message}"
            break
        if mode == "full" and race_t >= STRAIGHT_STOP_S:
            run.madsim_end = "16 s"
            break
        if world.laps[0] >= 3:
            if not run.madsim_end:
                run.madsim_lap2 = float(world.last_lap_time[0])
                run.madsim_end = "2 laps"
            if tail <= 0:
                break
            tail -= 1
        if cur_lap > limit_s or (f.damage[0] > MAX_DAMAGE and not run.madsim_end):
            run.madsim_end = "DNF"
            break
        steer, accel, brake, gear = controls((f.angle[0], f.trackPos[0], f.speedX[0], f.rpm[0]), gear, mode,
                                             target, up)
        u[0] = (steer, accel, brake, gear, 0.0)
        world.step(u, clock.substeps())
    run.madsim = {c: np.array(v) for c, v in rec.items()}
    if until_s is not None or until_message is not None:
        keep = np.arange(run.torcs["curLapTime"].shape[0]) < run.madsim["curLapTime"].shape[0]
        run.torcs = {c: v[keep] for c, v in run.torcs.items()}
    run.seconds = time.perf_counter() - t0
    return run


# --- figures ---------------------------------------------------------------------------------


def _by_distance(rec: dict, col: str, grid: np.ndarray) -> np.ndarray:
    d = np.maximum.accumulate(rec["distRaced"])
    return np.interp(grid, d, rec[col])


def compare(run: Run) -> dict:
    """The figures of one run (see the module docstring)."""
    t, m = run.torcs, run.madsim
    end = min(np.max(t["distRaced"]), np.max(m["distRaced"]))
    grid = np.arange(0.0, max(end, 1.0), 1.0)
    out = {"name": run.name, "lap2_torcs": run.torcs_lap2, "lap2_madsim": run.madsim_lap2,
           "lap2_err": 100.0 * (run.madsim_lap2 - run.torcs_lap2) / run.torcs_lap2,
           "end_torcs": run.torcs_end, "end_madsim": run.madsim_end, "seconds": run.seconds}
    for col, key in (("speedX", "v_rms"), ("trackPos", "pos_rms"), ("z", "z_rms")):
        out[key] = float(np.sqrt(np.mean((_by_distance(m, col, grid) - _by_distance(t, col, grid)) ** 2)))
    out["z_rms"] *= 100.0
    spin = []
    for w in range(4):
        col = f"wheelSpinVel_{w}"
        a, b = _by_distance(m, col, grid), _by_distance(t, col, grid)
        spin.append(100.0 * np.sqrt(np.mean((a - b) ** 2)) / max(np.sqrt(np.mean(b ** 2)), 1e-9))
    out["spin_err"] = float(max(spin))
    out["spin_wheels"] = spin
    # each axle's right-minus-left spin (the turns, the differentials): RMS difference over
    # TORCS's RMS, the worse axle (nan where TORCS's wheels never differ)
    split = []
    for right, left in ((0, 1), (2, 3)):
        a, b = (_by_distance(r, f"wheelSpinVel_{right}", grid) - _by_distance(r, f"wheelSpinVel_{left}", grid)
                for r in (m, t))
        ref = np.sqrt(np.mean(b ** 2))
        split.append(100.0 * np.sqrt(np.mean((a - b) ** 2)) / ref if ref > 1e-9 else math.nan)
    out["split_err"] = float(np.nanmax(split)) if not np.all(np.isnan(split)) else math.nan
    out["dmg_torcs"], out["dmg_madsim"] = float(t["damage"].max()), float(m["damage"].max())
    for who, rec in (("torcs", t), ("madsim", m)):
        off = np.nonzero(np.abs(rec["trackPos"]) > 1.0)[0]
        out[f"off_{who}"] = float(rec["distRaced"][off[0]]) if off.size else math.nan
        if run.mode == "full":
            out[f"t100_{who}"] = _first_crossing(rec["curLapTime"], rec["speedX"], 100.0)
            out[f"v10_{who}"] = float(np.interp(10.0, rec["curLapTime"], rec["speedX"]))
    return out


def _first_crossing(t: np.ndarray, v: np.ndarray, level: float) -> float:
    k = np.nonzero(v >= level)[0]
    if not k.size or k[0] == 0:
        return math.nan
    j = k[0]
    return float(t[j - 1] + (level - v[j - 1]) / (v[j] - v[j - 1]) * (t[j] - t[j - 1]))


def _pct(a: float, b: float) -> float:
    return 100.0 * (a - b) / b


def print_table(rows: list[dict]) -> None:
    print("| run | lap2 TORCS s | lap2 madsim s | lap2 % | v rms km/h | pos rms | z rms cm | spin % | R-L % | "
          "dmg T/m | off at T/m (m) | end T/m |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        off = "/".join("-" if math.isnan(r[k]) else f"{r[k]:.0f}" for k in ("off_torcs", "off_madsim"))
        print(f"| {r['name']} | {r['lap2_torcs']:.3f} | {r['lap2_madsim']:.3f} | {r['lap2_err']:+.2f} | "
              f"{r['v_rms']:.2f} | {r['pos_rms']:.3f} | {r['z_rms']:.2f} | {r['spin_err']:.1f} | {r['split_err']:.0f} | "
              f"{r['dmg_torcs']:.0f}/{r['dmg_madsim']:.0f} | {off} | {r['end_torcs']}/{r['end_madsim']} |")
    straight = [r for r in rows if "t100_torcs" in r]
    if straight:
        print()
        print("| straight line | 0-100 TORCS s | madsim s | error % | v(10 s) TORCS km/h | madsim | error % |")
        print("|---|---|---|---|---|---|---|")
        for r in straight:
            print(f"| {r['name']} | {r['t100_torcs']:.2f} | {r['t100_madsim']:.2f} | "
                  f"{_pct(r['t100_madsim'], r['t100_torcs']):+.1f} | {r['v10_torcs']:.1f} | {r['v10_madsim']:.1f} | "
                  f"{_pct(r['v10_madsim'], r['v10_torcs']):+.1f} |")


def _job(args: tuple) -> dict:
    path, schedule = args
    return compare(replay(Path(path), schedule))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--all", action="store_true", help="every trace (default: a quick subset)")
    ap.add_argument("--runs", default="", help="comma-separated parts of trace names, e.g. forza,alpine-2")
    ap.add_argument("--jobs", type=int, default=1, help="processes (2 uses both cores)")
    ap.add_argument("--tick-schedule", default="torcs", choices=("torcs", "fixed"),
                    help="driver calls as TORCS makes them (20/22 ms) or madsim's fixed 20 ms")
    ap.add_argument("--traces", default=str(TRACES), help="folder of the real-TORCS traces")
    a = ap.parse_args(argv)
    folder = Path(a.traces)
    paths = sorted(folder.glob("*.csv.gz"))
    if not paths:
        print(f"no traces in {folder}", file=sys.stderr)
        return 2
    keys = [k for k in a.runs.split(",") if k] or (None if a.all else list(QUICK))
    if keys is not None:
        paths = [p for p in paths if any(k in p.name for k in keys)]
        if not paths:
            print(f"no trace matches {a.runs!r}", file=sys.stderr)
            return 2
    t0 = time.perf_counter()
    jobs = [(str(p), a.tick_schedule) for p in paths]
    if a.jobs > 1:
        with multiprocessing.get_context("spawn").Pool(a.jobs) as pool:
            rows = pool.map(_job, jobs, chunksize=1)
    else:
        rows = [_job(j) for j in jobs]
    print_table(rows)
    print(f"\n{len(rows)} runs, tick schedule {a.tick_schedule}, {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
