"""Where a replay parts from its real-TORCS trace, message by message (issue 12's sand2 round).

Replays one trace with `fidelity.py`'s controller, start and tick schedule and prints, for each
message in a window, TORCS's and madsim's speedX, speedY (km/h), angle, trackPos, yaw rate and
the four wheel spins (rad/s), with madsim's wheel loads (kN) and the surface friction under
each wheel. The traces carry no yaw rate: both columns estimate it the same way, from `angle`
and the track's heading at `distFromStart`, differenced over the message times (`yaw_rate`);
madsim's true one follows in brackets, as a check of the estimate. `--phases` prints the mean
yaw rates over windows of messages (docs/physics.md, "Where the contact runs part").

Run: python benchmarks/slide_window.py wheel-2__car1-trb1__100 --from 4960 --to 5040
     [--every 2] [--phases 4960:4975,4976:4980,4981:4992,4993:5036]
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
                 "wheelSpinVel_2", "wheelSpinVel_3")


def yaw_rate(heading: np.ndarray, angle: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Yaw rate, rad/s, from SCR's `angle` (rad, track direction minus heading) and the track's
    heading (rad) at the car's distance from the start, at times t (s): the heading is the
    track's minus `angle`, unwrapped, and differenced (central differences inside)."""
    yaw = np.unwrap(np.asarray(heading) - np.asarray(angle))
    return np.gradient(yaw, np.asarray(t))


def read_window(path: Path, first: int, last: int) -> dict[str, np.ndarray]:
    """TORCS's racing messages first..last (inclusive) of a trace: TRACE_COLUMNS by name."""
    with gzip.open(path, "rt", newline="") as f:
        rows = list(csv.reader(f))
    head = rows[0]
    idx = [head.index(c) for c in TRACE_COLUMNS]
    body = rows[1 + fidelity.COUNTDOWN_MESSAGES + first:1 + fidelity.COUNTDOWN_MESSAGES + last + 1]
    data = np.array([[float(r[k]) for k in idx] for r in body])
    return {c: data[:, j] for j, c in enumerate(TRACE_COLUMNS)}


def madsim_window(path: Path, first: int, last: int) -> dict[str, np.ndarray]:
    """madsim's readings at messages first..last of the same replay (sensor names as TORCS's,
    plus time, the true yaw rate, wheel loads and frictions)."""
    from madsim.physics import layout as L

    keep: dict[str, list] = {c: [] for c in (*TRACE_COLUMNS, "time", "yaw_rate", "fz", "fric")}

    def watch(msg, world, f):
        if first <= msg <= last:
            st = world.state[0]
            vals = (f.distFromStart[0], f.speedX[0], f.speedY[0], f.angle[0], f.trackPos[0], *f.wheelSpinVel[0],
                    world.time, st[L.S_R], st[L.S_FZ:L.S_FZ + 4].copy(), st[L.S_FRIC:L.S_FRIC + 4].copy())
            for c, v in zip(keep, vals):
                keep[c].append(v)

    fidelity.replay(path, until_s=None, watch=watch, until_message=last)
    return {c: np.array(v) for c, v in keep.items()}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("trace", help="trace name, e.g. wheel-2__car1-trb1__100")
    ap.add_argument("--from", dest="first", type=int, required=True, help="first message")
    ap.add_argument("--to", dest="last", type=int, required=True, help="last message")
    ap.add_argument("--every", type=int, default=1, help="print every n-th message")
    ap.add_argument("--phases", default="", help="windows first:last,... for mean yaw rates")
    ap.add_argument("--traces", default=str(fidelity.TRACES), help="folder of the real-TORCS traces")
    a = ap.parse_args(argv)
    path = Path(a.traces) / f"{a.trace}.csv.gz"
    if not path.is_file() or a.last < a.first:
        print(f"no trace {path}, or an empty window", file=sys.stderr)
        return 2
    from madsim.tracks import load_track

    track = load_track(a.trace.split("__")[0])
    m = madsim_window(path, a.first, a.last)
    t = read_window(path, a.first, a.first + len(m["time"]) - 1)
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
