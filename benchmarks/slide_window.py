"""Where a replay parts from its real-TORCS trace, message by message (issue 12's sand2 round).

Replays one trace with `fidelity.py`'s controller, start and tick schedule and prints, for each
message in a window, TORCS's and madsim's speedX, speedY (km/h), angle, trackPos, yaw rate and
the four wheel spins (rad/s), with madsim's wheel loads (kN) and the surface friction under
each wheel. The traces carry no yaw rate: both columns estimate it the same way, from `angle`
and the track's heading at `distFromStart`, differenced over the message times (`yaw_rate`);
madsim's true one follows in brackets, as a check of the estimate. `--phases` prints the mean
yaw rates over windows of messages (docs/physics.md, "Where the contact runs part").
`--diff` prints instead, per message and for both runs, the driven rear axle's differential:
gear, engine "rpm", the torque into the differential (engine torque at that engine speed and
the message's accel command, times the overall ratio: TORCS's `in.Tq`, N m) against the
limited-slip locking torques, the speed ratio the clamp allows and the rear wheels' ratio
(docs/physics.md, "Drive line": the limited-slip lock under throttle).

Run: python benchmarks/slide_window.py wheel-2__car1-trb1__100 --from 4960 --to 5040
     [--every 2] [--phases 4960:4975,4976:4980,4981:4992,4993:5036] [--diff]
Messages count from the first racing message (0), as the trace's rows after the countdown.
"""

from __future__ import annotations

import argparse
import csv
import gzip
import importlib.util
import sys
from pathlib import Path

import numpy as np


def _load_fidelity():
    """benchmarks/fidelity.py (the replay and the controller), loaded from beside this file."""
    spec = importlib.util.spec_from_file_location("madsim_fidelity_bench", Path(__file__).with_name("fidelity.py"))
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod          # its dataclass looks its module up there
    spec.loader.exec_module(mod)
    return mod


fidelity = _load_fidelity()

TRACE_COLUMNS = ("distFromStart", "speedX", "speedY", "angle", "trackPos", "wheelSpinVel_0", "wheelSpinVel_1",
                 "wheelSpinVel_2", "wheelSpinVel_3", "gear", "rpm")


def yaw_rate(heading: np.ndarray, angle: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Yaw rate, rad/s, from SCR's `angle` (rad, track direction minus heading) and the track's
    heading (rad) at the car's distance from the start, at times t (s): the heading is the
    track's minus `angle`, unwrapped, and differenced (central differences inside)."""
    yaw = np.unwrap(np.asarray(heading) - np.asarray(angle))
    return np.gradient(yaw, np.asarray(t))


def read_window(path: Path, first: int, last: int, columns: tuple[str, ...] = TRACE_COLUMNS) -> dict[str, np.ndarray]:
    """TORCS's racing messages first..last (inclusive) of a trace: `columns` by name (the
    controls, e.g. "accel", are the reference controller's reply to each message, which
    madsim's replay sends too: the same function of the same sensors)."""
    with gzip.open(path, "rt", newline="") as f:
        rows = list(csv.reader(f))
    head = rows[0]
    idx = [head.index(c) for c in columns]
    body = rows[1 + fidelity.COUNTDOWN_MESSAGES + first:1 + fidelity.COUNTDOWN_MESSAGES + last + 1]
    data = np.array([[float(r[k]) for k in idx] for r in body])
    return {c: data[:, j] for j, c in enumerate(columns)}


def madsim_window(path: Path, first: int, last: int) -> dict[str, np.ndarray]:
    """madsim's readings at messages first..last of the same replay (sensor names as TORCS's,
    plus time, the true yaw rate, wheel loads and frictions)."""
    from madsim.physics import layout as L

    keep: dict[str, list] = {c: [] for c in (*TRACE_COLUMNS, "time", "yaw_rate", "fz", "fric")}

    def watch(msg, world, f):
        if first <= msg <= last:
            st = world.state[0]
            vals = (f.distFromStart[0], f.speedX[0], f.speedY[0], f.angle[0], f.trackPos[0], *f.wheelSpinVel[0],
                    f.gear[0], f.rpm[0], world.time, st[L.S_R], st[L.S_FZ:L.S_FZ + 4].copy(),
                    st[L.S_FRIC:L.S_FRIC + 4].copy())
            for c, v in zip(keep, vals):
                keep[c].append(v)

    fidelity.replay(path, until_s=None, watch=watch, until_message=last)
    return {c: np.array(v) for c, v in keep.items()}


def rear_differential(car, run: dict[str, np.ndarray], accel: np.ndarray) -> dict[str, np.ndarray]:
    """Per message of one run: the torque into the rear differential, N m (the kernel's engine
    torque at the engine speed `rpm` / 10 rad/s (SCR's unit) and the accel command, times the
    gear's overall ratio; 0 in neutral; a shift's throttle cap and the clutch are not applied),
    the speed ratio the limited-slip clamp allows there, and the rear wheels' |w2 - w3| / (|w2|
    + |w3|)."""
    from madsim.physics import layout as L
    from madsim.physics.kernel import engine_torque
    from madsim.physics.tables import car_table

    cp, curve_w, curve_t = car_table([car], ["semi-pro"])
    gears = run["gear"].astype(int)
    ratio = np.array([cp[0, L.C_RATIO + g + 1] for g in gears])
    d_in = np.array([engine_torque(cp, curve_w, curve_t, 0, w, a) for w, a in zip(run["rpm"] / 10.0, accel)]) * ratio
    lock, lock_brake, slip = cp[0, L.C_DLOCK + 1], cp[0, L.C_DLOCKB + 1], cp[0, L.C_DSLIP + 1]
    allowed = slip * (1.0 - d_in / np.where(d_in >= 0.0, lock, -lock_brake))
    w2, w3 = run["wheelSpinVel_2"], run["wheelSpinVel_3"]
    common = np.abs(w2) + np.abs(w3)
    measured = np.abs(w2 - w3) / np.where(common > 0.0, common, 1.0)
    return {"d_in": d_in, "allowed": allowed, "ratio": measured, "lock": lock, "lock_brake": lock_brake}


def print_differential(first: int, car, t: dict, m: dict, accel: np.ndarray, every: int) -> None:
    """The `--diff` table: TORCS / madsim per message (see `rear_differential`)."""
    dt, dm = rear_differential(car, t, accel), rear_differential(car, m, accel)
    print(f"rear differential: locking torque {dt['lock']:.0f} N m, locking brake torque {dt['lock_brake']:.0f} N m "
          "(a spool beyond them: marked *)")
    print("msg   accel  gear T/M  rpm T/M      torque in T/M N m   allowed T/M    ratio T/M      rear spins rr rl T/M")
    for j in range(0, len(m["time"]), every):
        cells = []
        for d in (dt, dm):
            x = d["d_in"][j]
            cells.append(f"{x:6.0f}{'*' if x > d['lock'] or x < -d['lock_brake'] else ' '}")
        print(f"{first + j:5d} {accel[j]:5.2f}  {t['gear'][j]:2.0f} {m['gear'][j]:2.0f}  "
              f"{t['rpm'][j]:5.0f} {m['rpm'][j]:5.0f}  {cells[0]} {cells[1]}     "
              f"{dt['allowed'][j]:.3f} {dm['allowed'][j]:.3f}  {dt['ratio'][j]:.3f} {dm['ratio'][j]:.3f}  "
              f"{t['wheelSpinVel_2'][j]:5.1f} {t['wheelSpinVel_3'][j]:5.1f} / "
              f"{m['wheelSpinVel_2'][j]:5.1f} {m['wheelSpinVel_3'][j]:5.1f}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("trace", help="trace name, e.g. wheel-2__car1-trb1__100")
    ap.add_argument("--from", dest="first", type=int, required=True, help="first message")
    ap.add_argument("--to", dest="last", type=int, required=True, help="last message")
    ap.add_argument("--every", type=int, default=1, help="print every n-th message")
    ap.add_argument("--phases", default="", help="windows first:last,... for mean yaw rates")
    ap.add_argument("--diff", action="store_true", help="print the rear differential's input torque and clamp")
    ap.add_argument("--traces", default=str(fidelity.TRACES), help="folder of the real-TORCS traces")
    a = ap.parse_args(argv)
    path = Path(a.traces) / f"{a.trace}.csv.gz"
    if not path.is_file() or a.last < a.first:
        print(f"no trace {path}, or an empty window", file=sys.stderr)
        return 2
    from madsim.cars import load_car
    from madsim.tracks import load_track

    track = load_track(a.trace.split("__")[0])
    m = madsim_window(path, a.first, a.last)
    t = read_window(path, a.first, a.first + len(m["time"]) - 1)
    if a.diff:
        accel = read_window(path, a.first, a.first + len(m["time"]) - 1, ("accel",))["accel"]
        print_differential(a.first, load_car(a.trace.split("__")[1]), t, m, accel, a.every)
        return 0
    times = m["time"]                      # TORCS's messages come on the same schedule
    r_t = yaw_rate(track.heading_at(t["distFromStart"]), t["angle"], times)
    r_m = yaw_rate(track.heading_at(m["distFromStart"]), m["angle"], times)
    print("msg   speedX T/M     speedY T/M     angle T/M    trackPos T/M  yaw rate T/M (true)   "
          "spins fr fl rr rl T/M                  loads kN            friction")
    for j in range(0, len(times), a.every):
        spins = " ".join(f"{t[f'wheelSpinVel_{k}'][j]:4.0f}/{m[f'wheelSpinVel_{k}'][j]:<4.0f}" for k in range(4))
        print(f"{a.first + j:5d} {t['speedX'][j]:6.1f} {m['speedX'][j]:6.1f} {t['speedY'][j]:6.1f} {m['speedY'][j]:6.1f} "
              f"{t['angle'][j]:6.2f} {m['angle'][j]:6.2f} {t['trackPos'][j]:6.2f} {m['trackPos'][j]:6.2f} "
              f"{r_t[j]:6.2f} {r_m[j]:5.2f} ({m['yaw_rate'][j]:5.2f})  {spins}  "
              f"{' '.join(f'{x / 1000:3.1f}' for x in m['fz'][j])}  {' '.join(f'{x:.2f}' for x in m['fric'][j])}")
    for part in filter(None, a.phases.split(",")):
        lo, hi = (int(x) for x in part.split(":"))
        sel = slice(lo - a.first, hi - a.first + 1)
        print(f"messages {lo}-{hi}: mean yaw rate TORCS {r_t[sel].mean():.2f}, madsim {r_m[sel].mean():.2f} "
              f"(true {m['yaw_rate'][sel].mean():.2f}) rad/s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
