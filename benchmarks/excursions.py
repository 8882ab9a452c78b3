"""Every off-road excursion of the real-TORCS traces, replayed from TORCS's own state (issue 12, session 14).

A single run's slide on sand or grass cannot tell a bias of the model from a coin toss: the
runs part and never meet again. This script gathers every excursion of every lap trace in
../shared/torcs-traces/ (a wheel of TORCS's car moving from the road onto another material:
a curb, a border, a side's grass, sand, gravel or dirt), puts madsim's car on TORCS's state a
few messages before it (`World.place` at TORCS's distFromStart, trackPos, `angle` and speedX,
then its speedY, its yaw rate estimated from `angle` and the track's heading, its four wheel
spins, gear, engine speed and fuel) and drives it open loop with the commands TORCS's
controller sent (the trace's accel, brake, gear, steer, on TORCS's message times). Over the
next 0.5 s and 1 s it compares both runs by the same estimates: the heading change (yaw), the
speedX change, speedY, the trackPos, the front and rear wheel spins. What the trace does not
carry (the suspension's travel and the body's roll and pitch, the tyres' force averages) starts
static: each excursion is replayed from several leads (`--leads`, messages before its start)
and madsim's figures are their mean, their spread (max - min) a measure of how much that
unknown state decides. The same replay on windows that stay on the road (`control`, one lead)
measures what the replay itself leaves. A window in which TORCS's car meets a wall (its damage
rises or its velocity jumps, `touches_wall`) is kept apart: contact is not the ground's doing.

Where a car's wheels are: TORCS's pose per message (distFromStart, trackPos x half the width,
heading = the track's minus `angle`) and the car's wheel positions (car table), located on the
track; a wheel is off when its material is not the road's at that distance. An excursion starts
at a message with a wheel off after `QUIET` messages with none, at over `MIN_KMH`.

Run: python benchmarks/excursions.py [--runs wheel-2,street-1] [--leads 3,6,10,15] [--windows]
     [--csv out.csv] [--scale-surface "sand:friction=0.9,grass:roughness=0"]
     (--scale-surface: an experiment, a material's surf column scaled in this replay only)
     python benchmarks/excursions.py --table g-track-2__car1-trb1__150:2246:3:50
     (one replay message by message: both runs' heading, speeds, trackPos, z, wheel spins and
     the materials under TORCS's wheels, to see at which message and on what they part)
     python benchmarks/excursions.py --sweep forza__car1-stock2__100:20415:20454,20474,20499 --leads 1-10,15,20,40
     (one replay per lead, madsim minus TORCS at the probe messages: whether TORCS's run lies
     inside madsim's spread over the placements or to one side of all of them; session 15)
Prints (with --windows) one line per window, then per material class, per class and car and per
class by the share of wheel-messages off: the means of TORCS's and madsim's heading and speed
changes, the slope of madsim's heading change on TORCS's (least squares through 0), their
correlation, the mean errors, madsim's spread over the leads and how often TORCS's figure lies
within it; and the regression over the excursions without a wall: madsim's turn and speed
errors and their correlations with the banking, grade, throttle, friction, roughness, speed.
"""

from __future__ import annotations

import argparse
import csv
import gzip
import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from slide_window import fidelity, yaw_rate  # noqa: E402,F401  (benchmarks/fidelity.py beside this file)

QUIET = 10
"""Messages with every wheel on the road before an excursion's start."""
MIN_KMH = 20.0
"""Slowest speedX (km/h) at an excursion's start."""
HORIZONS = (25, 50)
"""Messages after the start at which the runs are compared (0.5 s and about 1 s)."""
WALL_KMH = 3.0
"""A velocity change per message (km/h) above which a window counts as touching a wall."""
REGRESS_OFF = 0.2
"""Smallest share of off-road wheel-messages of an excursion in the regression."""
REGRESS_DPSI = 0.1
"""Smallest heading change of TORCS's car (rad) of an excursion in the regression."""
CONTROL_EVERY = 400
"""Messages between two on-road control windows of one trace."""
COLUMNS = ("curLapTime", "lastLapTime", "damage", "distFromStart", "speedX", "speedY", "angle", "trackPos", "fuel",
           "gear", "rpm", "wheelSpinVel_0", "wheelSpinVel_1", "wheelSpinVel_2", "wheelSpinVel_3", "z",
           "accel", "brake", "gear_cmd", "steer", "clutch")
SURF_COLUMNS = {"friction": 0, "rolling": 1, "roughness": 2, "wavenumber": 3}


@dataclass
class Window:
    """One compared window: where it starts, what is under the wheels, both runs' figures."""
    trace: str
    car: str
    start: int             # message of the excursion's start (the first wheel off)
    kind: str              # material class of the first wheel off ("control": none)
    material: str
    kmh: float             # TORCS's speedX at the start
    off_share: float       # share of wheel-messages off the road over the longest horizon, TORCS
    torcs: dict
    madsim: dict
    shares: str = ""       # the materials under TORCS's wheels over the longest horizon: name front%/rear%
    bank: float = 0.0      # mean banking (rad, left up +) under TORCS's car over the longest horizon
    grade: float = 0.0     # mean grade (rise over run) likewise
    contact: bool = False  # TORCS's car meets a wall in the window (`touches_wall`)
    spread: dict = field(default_factory=dict)   # per horizon and figure: madsim's max - min over the leads
    accel: float = 0.0     # mean accel command over the longest horizon
    friction: float = 0.0  # mean surface friction under TORCS's wheels over the longest horizon
    rough: float = 0.0     # mean roughness (m) likewise


def message_times(rec: dict) -> np.ndarray:
    """Race time of each message (s) from curLapTime, across the line's resets."""
    cur, last = rec["curLapTime"], rec["lastLapTime"]
    dt = np.diff(cur)
    wrap = dt < 0.0
    dt[wrap] = cur[1:][wrap] + last[1:][wrap] - cur[:-1][wrap]
    return np.concatenate([[cur[0]], cur[0] + np.cumsum(dt)])


def substeps_of(t: np.ndarray) -> np.ndarray:
    """Sub-steps of 2 ms between consecutive messages (TORCS's 10 or 11)."""
    return np.clip(np.rint(np.diff(t) / 0.002), 1, 100).astype(np.int64)


def heading_change(heading: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """The car's heading (rad, unwrapped, relative to the first) from SCR's `angle` and the
    track's heading at its distance: track minus angle."""
    yaw = np.unwrap(np.asarray(heading) - np.asarray(angle))
    return yaw - yaw[0]


def classify(material: str, friction: float) -> str:
    """A material class from its name (TORCS's names: grass, sand, gravel, dirt, curb, ...)."""
    name = material.lower()
    for key in ("curb", "sand", "grass", "gravel", "dirt", "snow", "barrier", "wall", "tar", "asphalt",
                "concrete", "mud"):
        if key in name:
            return key
    return f"mu {friction:.1f}"


def wheel_surfaces(track, cp_row: np.ndarray, rec: dict) -> np.ndarray:
    """(M, 4) material index under each wheel at each message of a TORCS record."""
    from madsim.physics import layout as L

    s, half = rec["distFromStart"], track.width / 2.0
    x, y, _, th = track.pose(s, rec["trackPos"] * half)
    yaw = th - rec["angle"]
    c, sn = np.cos(yaw), np.sin(yaw)
    out = np.empty((s.shape[0], 4), dtype=np.int64)
    for k in range(4):
        wx, wy = cp_row[L.C_WX + k], cp_row[L.C_WY + k]
        ws, wn = track.locate(x + wx * c - wy * sn, y + wx * sn + wy * c, s_hint=s)
        out[:, k] = track.surface_at(ws, wn)
    return out


def find_windows(track, surf_idx: np.ndarray, rec: dict, horizon: int) -> list[tuple[int, int]]:
    """(start message, material index) of each excursion, and (start, -1) of on-road control windows."""
    road = track.surface_at(rec["distFromStart"], 0.0)
    off = surf_idx != road[:, None]
    n_off = off.sum(axis=1)
    m = n_off.shape[0]
    out = []
    quiet = 0
    for j in range(m):
        if n_off[j] == 0:
            quiet += 1
            continue
        if quiet >= QUIET and rec["speedX"][j] > MIN_KMH and j + horizon < m:
            first = int(surf_idx[j][off[j]][0])
            out.append((j, first))
        quiet = 0
    # control windows: on the road from 5 messages before to the horizon, at speed
    clean = np.convolve((n_off == 0).astype(int), np.ones(horizon + 6, dtype=int), "valid") == horizon + 6
    j = 50
    while j + horizon < m:
        if clean[j - 5] and rec["speedX"][j] > MIN_KMH:
            out.append((j, -1))
            j += CONTROL_EVERY
        else:
            j += 1
    return out


def read_trace(path: Path) -> dict[str, np.ndarray]:
    with gzip.open(path, "rt", newline="") as f:
        rows = list(csv.reader(f))
    head = rows[0]
    idx = [head.index(c) for c in COLUMNS]
    data = np.array([[float(r[k]) for k in idx] for r in rows[1 + fidelity.COUNTDOWN_MESSAGES:]])
    return {c: data[:, j] for j, c in enumerate(COLUMNS)}


def place_on(world, track, cp_row, rec: dict, j: int, t: np.ndarray) -> None:
    """Put car 0 on TORCS's state at message j (see the module docstring)."""
    from madsim.physics import layout as L

    half = track.width / 2.0
    world.place(0, float(rec["distFromStart"][j]), float(rec["trackPos"][j] * half),
                yaw_rel=float(-rec["angle"][j]), speed=float(rec["speedX"][j] / 3.6), gear=int(rec["gear"][j]))
    st = world.state
    yaw = st[0, L.S_YAW]
    vx, vy = rec["speedX"][j] / 3.6, rec["speedY"][j] / 3.6
    st[0, L.S_VXG] = vx * math.cos(yaw) - vy * math.sin(yaw)
    st[0, L.S_VYG] = vx * math.sin(yaw) + vy * math.cos(yaw)
    st[0, L.S_VX], st[0, L.S_VY] = vx, vy
    lo, hi = max(j - 2, 0), j + 3
    r = yaw_rate(track.heading_at(rec["distFromStart"][lo:hi]), rec["angle"][lo:hi], t[lo:hi])
    st[0, L.S_R] = r[j - lo]
    for k in range(4):
        w = rec[f"wheelSpinVel_{k}"][j]
        st[0, L.S_SPIN + k] = st[0, L.S_SPINRAW + k] = w
    st[0, L.S_WE] = rec["rpm"][j] / 10.0
    st[0, L.S_FUEL] = rec["fuel"][j]
    st[0, L.S_STEER] = rec["steer"][max(j - 1, 0)] * cp_row[L.C["steer_lock"]]


def drive(world, suite, rec: dict, j0: int, j1: int, steps: np.ndarray) -> dict[str, np.ndarray]:
    """Open loop from message j0 to j1 with TORCS's commands; madsim's sensors per message."""
    keep = {c: [] for c in ("distFromStart", "speedX", "speedY", "angle", "trackPos", "z",
                            "wheelSpinVel_0", "wheelSpinVel_1", "wheelSpinVel_2", "wheelSpinVel_3")}
    u = np.zeros((1, 5))
    for j in range(j0, j1 + 1):
        f = suite.frame()
        for c in keep:
            v = getattr(f, c) if not c.startswith("wheelSpinVel") else f.wheelSpinVel[:, int(c[-1])]
            keep[c].append(float(v[0]))
        if j == j1:
            break
        u[0] = (rec["steer"][j], rec["accel"][j], rec["brake"][j], rec["gear_cmd"][j], rec["clutch"][j])
        world.step(u, int(steps[j]))
    return {c: np.array(v) for c, v in keep.items()}


def figures(track, run: dict, lead: int) -> dict[str, np.ndarray]:
    """Per horizon h (HORIZONS, after the excursion's start): heading change (rad) and speedX
    change (km/h) since the start, speedY (km/h) and trackPos at h, mean front and rear spin
    (rad/s) over the start..h."""
    psi = heading_change(track.heading_at(run["distFromStart"]), run["angle"])
    out = {}
    for h in HORIZONS:
        a, b = lead, lead + h
        out[h] = {"dpsi": psi[b] - psi[a], "dv": run["speedX"][b] - run["speedX"][a],
                  "vy": run["speedY"][b], "pos": run["trackPos"][b],
                  "front": float(np.mean(run["wheelSpinVel_0"][a:b + 1] + run["wheelSpinVel_1"][a:b + 1]) / 2),
                  "rear": float(np.mean(run["wheelSpinVel_2"][a:b + 1] + run["wheelSpinVel_3"][a:b + 1]) / 2)}
    return out


def replay_setup(path: Path, scale: list[tuple[str, str, float]]):
    """(track, car name, World with the trace's car and TORCS's grid, its SensorSuite, the record,
    message times, sub-steps per message) of one trace; `scale` ((material part, surf column,
    factor), ...) scales the surf table of this World only."""
    from madsim.cars import load_car
    from madsim.physics.sensors import SensorSuite
    from madsim.physics.world import World
    from madsim.tracks import load_track

    track_name, car_name, mode = path.name.removesuffix(".csv.gz").split("__")
    track, car = load_track(track_name), load_car(car_name)
    world = World(track, [car], np.random.default_rng(0), fuel=True, damage=True)
    world.reset(grid=fidelity.TRACE_GRID)
    for material, col, factor in scale:
        for i, sf in enumerate(track.surfaces):
            if material in sf.name.lower():
                world._surf[i, SURF_COLUMNS[col]] *= factor
    suite = SensorSuite(world)
    rec = read_trace(path)
    t = message_times(rec)
    return track, car_name, world, suite, rec, t, substeps_of(t)


def message_table(path: Path, start: int, lead: int, horizon: int,
                  scale: list[tuple[str, str, float]]) -> list[dict]:
    """One replay, message by message: madsim's car placed `lead` messages before message
    `start` of the trace and driven open loop to `start + horizon`. Per message from the
    placement on: TORCS's and madsim's heading change since the placement (rad), speedX,
    speedY (km/h), trackPos, z (m), the four wheel spins (rad/s), and the materials under
    TORCS's four wheels (FR, FL, RR, RL)."""
    track, _, world, suite, rec, t, steps = replay_setup(path, scale)
    j0, j1 = start - lead, start + horizon
    place_on(world, track, world._cp[0], rec, j0, t)
    suite.reset()
    m = drive(world, suite, rec, j0, j1, steps)
    torcs = {c: rec[c][j0:j1 + 1] for c in m}
    psi_t = heading_change(track.heading_at(torcs["distFromStart"]), torcs["angle"])
    psi_m = heading_change(track.heading_at(m["distFromStart"]), m["angle"])
    under = wheel_surfaces(track, world._cp[0],
                           {c: rec[c][j0:j1 + 1] for c in ("distFromStart", "trackPos", "angle")})
    rows = []
    for k in range(j1 - j0 + 1):
        row = {"msg": j0 + k, "under": [track.surfaces[i].name for i in under[k]],
               "steer": float(rec["steer"][j0 + k]), "accel": float(rec["accel"][j0 + k])}
        for who, d, psi in (("torcs", torcs, psi_t), ("madsim", m, psi_m)):
            row[who] = {"dpsi": float(psi[k]), "speedX": float(d["speedX"][k]), "speedY": float(d["speedY"][k]),
                        "trackPos": float(d["trackPos"][k]), "z": float(d["z"][k]),
                        "spins": [float(d[f"wheelSpinVel_{q}"][k]) for q in range(4)]}
        rows.append(row)
    return rows


def parse_leads(text: str) -> list[int]:
    """'1-4,10,20' -> [1, 2, 3, 4, 10, 20]."""
    out: list[int] = []
    for part in filter(None, text.split(",")):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b) + 1)) if b else [int(a)]
    return out


def lead_sweep(path: Path, start: int, leads: list[int], probes: list[int],
               scale: list[tuple[str, str, float]]) -> list[dict]:
    """One open-loop replay per lead (`message_table`), and at each probe message madsim minus
    TORCS: the heading (rad, both from the same placement), speedX and speedY (km/h), and
    TORCS's heading change since the placement (rad, to tell the turn's direction)."""
    out = []
    for lead in leads:
        rows = {r["msg"]: r for r in message_table(path, start, lead, max(probes) - start, scale)}
        at = {}
        for p in probes:
            if p in rows:
                t, m = rows[p]["torcs"], rows[p]["madsim"]
                at[p] = {"dpsi": m["dpsi"] - t["dpsi"], "speedX": m["speedX"] - t["speedX"],
                         "speedY": m["speedY"] - t["speedY"], "turn": t["dpsi"]}
        out.append({"lead": lead, "at": at})
    return out


def sweep_summary(errs: np.ndarray, turns: np.ndarray) -> dict:
    """Over the leads at one probe: the mean, min and max of madsim's heading error, and in how
    many leads madsim turns more than TORCS (its error in the direction of TORCS's turn)."""
    errs, turns = np.asarray(errs, float), np.asarray(turns, float)
    return {"mean": float(errs.mean()), "min": float(errs.min()), "max": float(errs.max()),
            "more": int(np.sum(errs * np.sign(turns) > 0.0)), "n": int(errs.size),
            "inside": bool(errs.min() <= 0.0 <= errs.max())}


def print_sweep(sweep: list[dict], probes: list[int]) -> None:
    print("| lead | " + " | ".join(f"{p}: heading m-T rad, speedX m-T, speedY m-T km/h" for p in probes) + " |")
    print("|---|" + "---|" * len(probes))
    for r in sweep:
        cells = [(f"{d['dpsi']:+.3f}, {d['speedX']:+.1f}, {d['speedY']:+.1f}" if (d := r["at"].get(p)) else "")
                 for p in probes]
        print(f"| {r['lead']} | " + " | ".join(cells) + " |")
    cells = []
    for p in probes:
        got = [r["at"][p] for r in sweep if p in r["at"]]
        if not got:
            cells.append("")
            continue
        s = sweep_summary(np.array([d["dpsi"] for d in got]), np.array([d["turn"] for d in got]))
        cells.append(f"mean {s['mean']:+.3f} ({s['min']:+.3f}..{s['max']:+.3f}), turns more in {s['more']} of "
                     f"{s['n']}, TORCS {'inside' if s['inside'] else 'outside'}")
    print("| all | " + " | ".join(cells) + " |")


def print_table(rows: list[dict]) -> None:
    print("| msg | steer | dpsi T / m rad | speedX T / m km/h | speedY T / m | trackPos T / m | z T / m m | "
          "spins FR FL RR RL, T / m rad/s | under TORCS's wheels (FR, FL, RR, RL) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        t, m = r["torcs"], r["madsim"]
        print(f"| {r['msg']} | {r['steer']:+.2f} | {t['dpsi']:+.4f} / {m['dpsi']:+.4f} | "
              f"{t['speedX']:.1f} / {m['speedX']:.1f} | "
              f"{t['speedY']:+.1f} / {m['speedY']:+.1f} | {t['trackPos']:.3f} / {m['trackPos']:.3f} | "
              f"{t['z']:.3f} / {m['z']:.3f} | {' '.join(f'{w:.1f}' for w in t['spins'])} / "
              f"{' '.join(f'{w:.1f}' for w in m['spins'])} | {', '.join(r['under'])} |")


def trace_windows(path: Path, leads: tuple[int, ...], scale: list[tuple[str, str, float]]) -> list[Window]:
    """Every window of one trace, madsim's figures averaged over replays placed `leads`
    messages before the start (control windows: the first lead only); their spread in
    `Window.spread`."""
    track, car_name, world, suite, rec, t, steps = replay_setup(path, scale)
    cp_row = world._cp[0]
    surf_idx = wheel_surfaces(track, cp_row, rec)
    yaw = heading_change(track.heading_at(rec["distFromStart"]), rec["angle"])
    horizon = max(HORIZONS)
    out = []
    for j, material in find_windows(track, surf_idx, rec, horizon):
        if j - max(leads) < 1:
            continue
        runs = []
        for lead in (leads[:1] if material < 0 else leads):
            place_on(world, track, cp_row, rec, j - lead, t)
            suite.reset()
            m = drive(world, suite, rec, j - lead, j + horizon, steps)
            runs.append(figures(track, m, lead))
        mean = {h: {k: float(np.mean([r[h][k] for r in runs])) for k in runs[0][h]} for h in HORIZONS}
        spread = {h: {k: float(np.ptp([r[h][k] for r in runs])) for k in runs[0][h]} for h in HORIZONS}
        torcs = figures(track, {c: rec[c][j:j + horizon + 1] for c in m}, 0)
        for h in HORIZONS:       # whether TORCS's figure lies within madsim's replays' range
            for k in ("dpsi", "dv"):
                got = [r[h][k] for r in runs]
                spread[h][f"{k}_in"] = float(min(got) <= torcs[h][k] <= max(got))
        road = track.surface_at(rec["distFromStart"][j:j + horizon + 1], 0.0)
        under = surf_idx[j:j + horizon + 1]
        share = float(np.mean(under != road[:, None]))
        shares = " ".join(f"{track.surfaces[i].name} {100 * np.mean(under[:, :2] == i):.0f}/{100 * np.mean(under[:, 2:] == i):.0f}"
                          for i in np.unique(under))
        if material < 0:
            kind, name = "control", "road"
        else:
            sf = track.surfaces[material]
            kind, name = classify(sf.name, sf.friction), sf.name
        out.append(Window(path.name.removesuffix(".csv.gz"), car_name, j, kind, name, float(rec["speedX"][j]), share,
                          torcs, mean, shares,
                          float(np.mean(track.banking_at(rec["distFromStart"][j:j + horizon + 1]))),
                          float(np.mean(track.grade_at(rec["distFromStart"][j:j + horizon + 1]))),
                          touches_wall(rec, yaw, j - max(leads), j + horizon), spread,
                          float(np.mean(rec["accel"][j:j + horizon + 1])),
                          float(np.mean([track.surfaces[i].friction for i in under.ravel()])),
                          float(np.mean([track.surfaces[i].roughness for i in under.ravel()]))))
    return out


def touches_wall(rec: dict, yaw: np.ndarray, j0: int, j1: int) -> bool:
    """Whether TORCS's car meets a wall over messages j0..j1: its damage rises, or its velocity
    (speedX, speedY turned by the car's heading `yaw`, rad) changes by more than `WALL_KMH` from
    one message to the next (tyres take at most about 1 km/h per message; a glancing hit can
    turn the velocity without slowing it)."""
    sl = slice(j0, j1 + 1)
    c, s = np.cos(yaw[sl]), np.sin(yaw[sl])
    vx, vy = rec["speedX"][sl], rec["speedY"][sl]
    gx, gy = vx * c - vy * s, vx * s + vy * c
    jump = np.hypot(np.diff(gx), np.diff(gy))
    return bool(np.any(np.diff(rec["damage"][sl]) > 0) or np.any(jump > WALL_KMH))


def slope(x: np.ndarray, y: np.ndarray) -> float:
    """Least-squares slope of y on x through the origin (nan without spread)."""
    d = float(np.dot(x, x))
    return float(np.dot(x, y) / d) if d > 0.0 else math.nan


def summary(windows: list[Window], h: int, key) -> list[dict]:
    """Rows per group (`key(window)`): count, mean TORCS / madsim heading change and speed change,
    slope and correlation of madsim's heading change on TORCS's, mean |heading error|."""
    groups: dict[str, list[Window]] = {}
    for w in windows:
        groups.setdefault(key(w), []).append(w)
    rows = []
    for g, ws in sorted(groups.items()):
        pt = np.array([w.torcs[h]["dpsi"] for w in ws])
        pm = np.array([w.madsim[h]["dpsi"] for w in ws])
        vt = np.array([w.torcs[h]["dv"] for w in ws])
        vm = np.array([w.madsim[h]["dv"] for w in ws])
        yt = np.array([w.torcs[h]["vy"] for w in ws])
        ym = np.array([w.madsim[h]["vy"] for w in ws])
        corr = float(np.corrcoef(pt, pm)[0, 1]) if len(ws) > 2 and pt.std() > 0 and pm.std() > 0 else math.nan
        rows.append({"group": g, "n": len(ws), "psi_t": pt.mean(), "psi_m": pm.mean(), "slope": slope(pt, pm),
                     "corr": corr, "psi_err": float(np.mean(np.abs(pm - pt))), "dv_t": vt.mean(), "dv_m": vm.mean(),
                     "dv_err": float(np.mean(vm - vt)), "vy_err": float(np.mean(np.abs(ym - yt))),
                     "psi_spread": float(np.mean([w.spread[h]["dpsi"] for w in ws])),
                     "dv_spread": float(np.mean([w.spread[h]["dv"] for w in ws])),
                     "psi_in": float(np.mean([w.spread[h]["dpsi_in"] for w in ws]))})
    return rows


def regression(windows: list[Window], h: int) -> dict:
    """Over the off-road excursions without a wall (a wheel off for at least `REGRESS_OFF` of
    the wheel-messages, TORCS's heading change above `REGRESS_DPSI` rad): madsim's turn error
    in TORCS's direction (rad; + = madsim turns more) and speed-change error (km/h), their mean
    and median, and their correlations with what the window's ground and driving were."""
    ws = [w for w in windows if w.kind != "control" and not w.contact and w.off_share >= REGRESS_OFF
          and abs(w.torcs[h]["dpsi"]) > REGRESS_DPSI]
    if len(ws) < 3:
        return {"n": len(ws)}
    sign = np.array([math.copysign(1.0, w.torcs[h]["dpsi"]) for w in ws])
    turn = np.array([w.madsim[h]["dpsi"] - w.torcs[h]["dpsi"] for w in ws]) * sign
    dv = np.array([w.madsim[h]["dv"] - w.torcs[h]["dv"] for w in ws])
    feats = {"banked into the turn (rad)": -np.array([w.bank for w in ws]) * sign,
             "grade": np.array([w.grade for w in ws]), "accel": np.array([w.accel for w in ws]),
             "friction": np.array([w.friction for w in ws]), "roughness": np.array([w.rough for w in ws]),
             "speed": np.array([w.kmh for w in ws]), "off share": np.array([w.off_share for w in ws]),
             "|TORCS's turn|": np.array([abs(w.torcs[h]["dpsi"]) for w in ws])}
    corr = {}
    for name, x in feats.items():
        ok = x.std() > 0.0
        corr[name] = (float(np.corrcoef(x, turn)[0, 1]) if ok else math.nan,
                      float(np.corrcoef(x, dv)[0, 1]) if ok else math.nan)
    return {"n": len(ws), "turn_mean": float(turn.mean()), "turn_median": float(np.median(turn)),
            "less": float(np.mean(turn < 0.0)), "turn_rel": float(np.median(turn / np.abs([w.torcs[h]["dpsi"] for w in ws]))),
            "dv_mean": float(dv.mean()), "dv_median": float(np.median(dv)), "corr": corr}


def print_regression(windows: list[Window]) -> None:
    for h in HORIZONS:
        r = regression(windows, h)
        print(f"\nafter {h} messages: {r['n']} off-road excursions without a wall (a wheel off >= "
              f"{100 * REGRESS_OFF:.0f} % of the wheel-messages, TORCS's turn > {REGRESS_DPSI} rad)")
        if r["n"] < 3:
            continue
        print(f"madsim's turn minus TORCS's, in TORCS's direction: mean {r['turn_mean']:+.3f} rad, median "
              f"{r['turn_median']:+.3f} (relative: median {100 * r['turn_rel']:+.1f} %), madsim turns less in "
              f"{100 * r['less']:.0f} %; speed change error: mean {r['dv_mean']:+.2f} km/h, median {r['dv_median']:+.2f}")
        print("| correlation with | turn error | speed change error |")
        print("|---|---|---|")
        for name, (a, b) in r["corr"].items():
            print(f"| {name} | {a:+.2f} | {b:+.2f} |")


def print_windows(windows: list[Window]) -> None:
    h = max(HORIZONS)
    print(f"| trace | msg | class | material | km/h | off % | dpsi T/m rad ({h}; spread) | dv T/m km/h (spread) | vy T/m km/h | "
          "rear T/m rad/s | front T/m | bank rad | grade | under the wheels (front % / rear %) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for w in windows:
        t, m = w.torcs[h], w.madsim[h]
        print(f"| {w.trace} | {w.start} | {w.kind} | {w.material} | {w.kmh:.0f} | {100 * w.off_share:.0f} | "
              f"{t['dpsi']:+.3f} / {m['dpsi']:+.3f} ({w.spread[h]['dpsi']:.3f}) | {t['dv']:+.1f} / {m['dv']:+.1f} ({w.spread[h]['dv']:.1f}) | {t['vy']:+.1f} / {m['vy']:+.1f} | "
              f"{t['rear']:.1f} / {m['rear']:.1f} | {t['front']:.1f} / {m['front']:.1f} | {w.bank:+.3f} | {w.grade:+.3f} | "
              f"{w.shares}{' (wall)' if w.contact else ''} |")


def print_summary(windows: list[Window]) -> None:
    for h in HORIZONS:
        for title, key in (("class (wall: TORCS's car touches a wall in the window)",
                            lambda w: f"{w.kind}{', wall' if w.contact else ''}"),
                           ("class, car", lambda w: f"{w.kind}, {w.car}"),
                           ("class, mostly off (>= 50 % of wheel-messages)",
                            lambda w: f"{w.kind} {'off' if w.off_share >= 0.5 else 'edge'}")):
            if "wall" not in title:
                key = (lambda k: (lambda w: "wall" if w.contact else k(w)))(key)
            print(f"\nafter {h} messages, by {title}")
            print("| group | n | dpsi T / m rad | slope m on T | corr | mean abs dpsi err | dpsi spread | "
                  "dv T / m km/h | mean dv err | dv spread | mean abs vy err km/h |")
            print("|---|---|---|---|---|---|---|---|---|---|---|---|")
            for r in summary(windows, h, key):
                print(f"| {r['group']} | {r['n']} | {r['psi_t']:+.3f} / {r['psi_m']:+.3f} | {r['slope']:.3f} | "
                      f"{r['corr']:.3f} | {r['psi_err']:.3f} | {r['psi_spread']:.3f} | {100 * r['psi_in']:.0f} % | {r['dv_t']:+.2f} / {r['dv_m']:+.2f} | "
                      f"{r['dv_err']:+.2f} | {r['dv_spread']:.2f} | {r['vy_err']:.2f} |")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", default="", help="comma-separated parts of trace names (default: every lap run)")
    ap.add_argument("--leads", default="3,6,10,15", help="messages before an excursion's start to place the car "
                    "(one replay each; madsim's figures are their mean; ranges as 1-10)")
    ap.add_argument("--scale-surface", default="", help="experiment: 'name:column=factor,...' on the surf table "
                    "(columns: friction, rolling, roughness, wavenumber)")
    ap.add_argument("--windows", action="store_true", help="print every window, not only the summary")
    ap.add_argument("--csv", default="", help="write every window's figures to this file")
    ap.add_argument("--traces", default=str(fidelity.TRACES), help="folder of the real-TORCS traces")
    ap.add_argument("--table", default="", help="one replay message by message instead: 'TRACE:MSG[:LEAD[:HORIZON]]' "
                    "(TRACE a part of a trace's name; LEAD 3, HORIZON 50 unless given)")
    ap.add_argument("--sweep", default="", help="one replay per lead of --leads: 'TRACE:MSG:PROBE,PROBE,...', "
                    "madsim minus TORCS at each probe message")
    a = ap.parse_args(argv)
    paths = sorted(p for p in Path(a.traces).glob("*.csv.gz") if "__full" not in p.name)
    keys = [k for k in a.runs.split(",") if k]
    if keys:
        paths = [p for p in paths if any(k in p.name for k in keys)]
    if not paths:
        print(f"no traces in {a.traces}", file=sys.stderr)
        return 2
    scale = []
    for part in filter(None, a.scale_surface.split(",")):
        name, rest = part.split(":")
        col, factor = rest.split("=")
        scale.append((name.lower(), col, float(factor)))
    if a.sweep:
        parts = a.sweep.split(":")
        found = [p for p in paths if parts[0] in p.name]
        if len(parts) != 3 or len(found) != 1:
            print(f"--sweep: TRACE:MSG:PROBE,... naming one trace ({len(found)} match {parts[0]!r})", file=sys.stderr)
            return 2
        probes = [int(x) for x in parts[2].split(",") if x]
        print_sweep(lead_sweep(found[0], int(parts[1]), parse_leads(a.leads), probes, scale), probes)
        return 0
    if a.table:
        key, *nums = a.table.split(":")
        found = [p for p in paths if key in p.name]
        if len(found) != 1:
            print(f"--table: {len(found)} traces match {key!r}", file=sys.stderr)
            return 2
        if not 1 <= len(nums) <= 3:
            print("--table: TRACE:MSG[:LEAD[:HORIZON]]", file=sys.stderr)
            return 2
        start, lead, horizon = [int(x) for x in nums] + [3, 50][len(nums) - 1:]
        print_table(message_table(found[0], start, lead, horizon, scale))
        return 0
    windows: list[Window] = []
    for p in paths:
        ws = trace_windows(p, tuple(parse_leads(a.leads)), scale)
        print(f"{p.name}: {sum(w.kind != 'control' for w in ws)} excursions, "
              f"{sum(w.kind == 'control' for w in ws)} control windows", file=sys.stderr)
        windows += ws
    if a.windows:
        print_windows(windows)
    print_summary(windows)
    print_regression(windows)
    if a.csv:
        with open(a.csv, "w", newline="") as f:
            wr = csv.writer(f)
            wr.writerow(["trace", "car", "start", "class", "material", "kmh", "off_share", "bank", "grade", "wall",
                         "accel", "friction", "roughness", "h", "who", "dpsi", "dv", "vy", "pos", "front", "rear",
                         "dpsi_spread", "dv_spread"])
            for w in windows:
                for h in HORIZONS:
                    for who, d in (("torcs", w.torcs[h]), ("madsim", w.madsim[h])):
                        wr.writerow([w.trace, w.car, w.start, w.kind, w.material, f"{w.kmh:.2f}", f"{w.off_share:.3f}",
                                     f"{w.bank:.4f}", f"{w.grade:.4f}", int(w.contact), f"{w.accel:.3f}",
                                     f"{w.friction:.3f}", f"{w.rough:.4f}", h, who,
                                     *(f"{d[k]:.5f}" for k in ("dpsi", "dv", "vy", "pos", "front", "rear")),
                                     f"{w.spread[h]['dpsi']:.5f}", f"{w.spread[h]['dv']:.5f}"])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
