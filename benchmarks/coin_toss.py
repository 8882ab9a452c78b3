"""Is a parting from real TORCS a coin toss? (issue 12, session 12)

Replays one trace with `fidelity.py`'s controller, start and tick schedule, and

* `--events`: lists both runs' damage events side by side (message, distance raced, points,
  speedX, trackPos) and the first message where the runs part by speed, trackPos and `angle`
  beyond the given thresholds;
* `--nudge M`: replays again with madsim's car nudged at message M, once per size in
  `--sizes` (the yaw by that many rad, `--what yaw`; or the car moved sideways by that many
  metres, `lateral`; or its velocity scaled by 1 + size, `speed`), to message `--to`, and
  prints each variant's speedX, trackPos, `angle` and damage at the `--probe` messages and how
  it ends there (moving, or at rest: below 2 km/h). If nudges far larger than the two runs'
  difference at M leave the outcome as it was, madsim's parting is systematic (a difference of
  model, or of something before M); if nudges of the size of that difference flip it (e.g. the
  sign of `angle` near +-pi, where the reference controller's full lock changes side), it is a
  coin toss that neither simulator decides by its physics;
* `--nudge M --end`: the same nudges, each variant replayed to the end of the run, and prints
  how each run ends: lap 2 (s, and its error against TORCS's), laps done or DNF, damage, and
  how many variants end as TORCS's run does (issue 12, session 15).

Run: python benchmarks/coin_toss.py wheel-2__car1-trb1__100 --events
     python benchmarks/coin_toss.py g-track-2__car1-trb1__150 --nudge 2200 --end --sizes 0,1e-4,-1e-4
     python benchmarks/coin_toss.py dirt-2__car1-trb1__100 --nudge 1100 --to 1500 \
         --probe 1180,1300,1499 --sizes 0,1e-3,-1e-3,1e-2,-1e-2
Messages count from the first racing message (0), as the trace's rows after the countdown.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

AT_REST_KMH = 2.0
"""A variant "ends at rest" when its speedX at the last probe is below this (km/h)."""


sys.path.insert(0, str(Path(__file__).resolve().parent))
from slide_window import fidelity  # noqa: E402  (benchmarks/fidelity.py, loaded beside this file)


def damage_events(rec: dict[str, np.ndarray]) -> list[tuple[int, float, float, float, float]]:
    """(message, distance raced m, points added, speedX km/h, trackPos) of each message whose
    damage is above the previous message's."""
    d = np.asarray(rec["damage"])
    k = np.flatnonzero(np.diff(d) > 0) + 1
    return [(int(j), float(rec["distRaced"][j]), float(d[j] - d[j - 1]), float(rec["speedX"][j]),
             float(rec["trackPos"][j])) for j in k]


def first_parting(t: dict[str, np.ndarray], m: dict[str, np.ndarray], dv_kmh: float = 2.0, dpos: float = 0.1,
                  dangle: float = 0.05) -> dict[str, int]:
    """The first message (-1: none) at which |speedX| differs by more than dv_kmh, trackPos by
    more than dpos, and `angle` by more than dangle rad (wrapped to [-pi, pi]), over the
    messages both runs have."""
    n = min(len(t["speedX"]), len(m["speedX"]))
    out = {}
    for key, col, lim in (("speedX", "speedX", dv_kmh), ("trackPos", "trackPos", dpos), ("angle", "angle", dangle)):
        if col not in t or col not in m:
            continue
        diff = np.asarray(m[col][:n]) - np.asarray(t[col][:n])
        if col == "angle":
            diff = (diff + math.pi) % (2.0 * math.pi) - math.pi
        hit = np.flatnonzero(np.abs(diff) > lim)
        out[key] = int(hit[0]) if hit.size else -1
    return out


def nudge_state(world, what: str, size: float) -> None:
    """Nudge car 0 of a World in place: its yaw by `size` rad (`yaw`), its position by `size` m
    to its left (`lateral`), or its velocity by the factor 1 + size (`speed`)."""
    from madsim.physics import layout as L

    st = world.state
    if what == "yaw":
        st[0, L.S["yaw"]] = (st[0, L.S["yaw"]] + size + math.pi) % (2.0 * math.pi) - math.pi
    elif what == "lateral":
        yaw = st[0, L.S["yaw"]]
        st[0, L.S["x"]] -= size * math.sin(yaw)
        st[0, L.S["y"]] += size * math.cos(yaw)
    elif what == "speed":
        for c in ("vx_g", "vy_g", "vx", "vy"):
            st[0, L.S[c]] *= 1.0 + size
    else:
        raise ValueError(f"unknown nudge {what!r}")


def _with_angle(run, path: Path) -> tuple[dict, dict]:
    """(TORCS's record, madsim's record) of a replay with `angle` added to both."""
    import csv
    import gzip

    with gzip.open(path, "rt", newline="") as f:
        rows = list(csv.reader(f))
    k = rows[0].index("angle")
    t = dict(run.torcs)
    n = len(t["speedX"])
    t["angle"] = np.array([float(r[k]) for r in rows[1 + fidelity.COUNTDOWN_MESSAGES:]])[:n]
    return t, run.madsim


def events(path: Path) -> int:
    angles: list[float] = []
    run = fidelity.replay(path, watch=lambda msg, world, f: angles.append(float(f.angle[0])))
    t, m = _with_angle(run, path)
    m = dict(m)
    m["angle"] = np.array(angles[:len(m["speedX"])])
    for who, rec in (("TORCS", t), ("madsim", m)):
        print(f"{who}: damage events (message, distance raced m, points, speedX km/h, trackPos)")
        for e in damage_events(rec):
            print(f"  {e[0]:6d} {e[1]:9.1f} {e[2]:+6.0f} {e[3]:7.1f} {e[4]:6.2f}")
        print(f"  ends at message {len(rec['speedX']) - 1}, {rec['distRaced'][-1]:.1f} m, damage {rec['damage'][-1]:.0f}")
    print(f"lap 2 TORCS {run.torcs_lap2:.3f} s, madsim {run.madsim_lap2:.3f} s ({run.madsim_end})")
    part = first_parting(t, m)
    print("first parting (message, distance raced by TORCS): "
          + ", ".join(f"{k} {v} ({t['distRaced'][v]:.1f} m)" if v >= 0 else f"{k} never" for k, v in part.items()))
    return 0


def nudges(path: Path, at: int, to: int, probes: list[int], sizes: list[float], what: str) -> int:
    probes = sorted(p for p in probes if at <= p <= to) or [to]
    rest = []
    print(f"nudge {what} at message {at}; speedX km/h / trackPos / angle / damage at messages "
          + ", ".join(map(str, probes)))
    for size in sizes:
        got: dict[int, tuple] = {}

        def watch(msg, world, f, size=size, got=got):
            if msg == at and size != 0.0:
                nudge_state(world, what, size)
            if msg in probes:
                got[msg] = (float(f.speedX[0]), float(f.trackPos[0]), float(f.angle[0]), float(f.damage[0]))

        fidelity.replay(path, watch=watch, until_message=to)
        last = got.get(probes[-1])
        at_rest = last is not None and abs(last[0]) < AT_REST_KMH
        rest.append(at_rest)
        cells = "  ".join(f"{v[0]:6.1f} {v[1]:+5.2f} {v[2]:+6.3f} {v[3]:5.0f}" if (v := got.get(p)) else "   (ended)"
                          for p in probes)
        print(f"{size:+9.1e}  {cells}  {'at rest' if at_rest else 'moving'}")
    print(f"{sum(rest)} of {len(sizes)} variants end at rest at message {probes[-1]}")
    return 0


def outcome(torcs_lap2: float, madsim_lap2: float, end: str, damage: float) -> tuple[float, float, str, float]:
    """(madsim's lap 2 s, its error against TORCS's in %, how it ends, damage): nan where a lap 2
    is missing on either side."""
    both = math.isfinite(torcs_lap2) and math.isfinite(madsim_lap2)
    err = 100.0 * (madsim_lap2 - torcs_lap2) / torcs_lap2 if both else float("nan")
    return float(madsim_lap2), err, end, float(damage)


def nudges_to_end(path: Path, at: int, sizes: list[float], what: str) -> int:
    """Each nudged variant replayed to the end of the run: its lap 2, end and damage."""
    same = 0
    t_end = None
    print(f"nudge {what} at message {at}, each variant to the end of the run")
    for size in sizes:
        def watch(msg, world, f, size=size):
            if msg == at and size != 0.0:
                nudge_state(world, what, size)

        run = fidelity.replay(path, watch=watch)
        t_end = run.torcs_end
        lap2, err, end, dmg = outcome(run.torcs_lap2, run.madsim_lap2, run.madsim_end, run.madsim["damage"][-1])
        same += end == run.torcs_end
        print(f"{size:+9.1e}  lap 2 {lap2:8.3f} s  {err:+6.2f} %  {end:8s}  damage {dmg:5.0f}")
        sys.stdout.flush()
    print(f"TORCS: {t_end}; {same} of {len(sizes)} variants end as TORCS's run does")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("trace", help="trace name, e.g. wheel-2__car1-trb1__100")
    ap.add_argument("--events", action="store_true", help="damage events and the first parting")
    ap.add_argument("--nudge", type=int, default=None, help="message at which madsim's car is nudged")
    ap.add_argument("--to", type=int, default=None, help="last message of the nudged replays")
    ap.add_argument("--end", action="store_true", help="with --nudge: each variant to the end of the run "
                    "(lap 2, end, damage) instead of --to and --probe")
    ap.add_argument("--probe", default="", help="messages to print, comma-separated (default: --to)")
    ap.add_argument("--sizes", default="0,1e-4,-1e-4,1e-3,-1e-3,1e-2,-1e-2", help="nudge sizes, comma-separated")
    ap.add_argument("--what", default="yaw", choices=("yaw", "lateral", "speed"), help="what to nudge")
    ap.add_argument("--traces", default=str(fidelity.TRACES), help="folder of the real-TORCS traces")
    a = ap.parse_args(argv)
    path = Path(a.traces) / f"{a.trace}.csv.gz"
    if not path.is_file():
        print(f"no trace {path}", file=sys.stderr)
        return 2
    if a.events:
        return events(path)
    sizes = [float(x) for x in a.sizes.split(",")]
    if a.nudge is not None and a.end:
        return nudges_to_end(path, a.nudge, sizes, a.what)
    if a.nudge is None or a.to is None or a.to < a.nudge:
        print("give --events, --nudge M --end, or --nudge M --to N (N >= M)", file=sys.stderr)
        return 2
    probes = [int(x) for x in a.probe.split(",") if x]
    return nudges(path, a.nudge, a.to, probes, sizes, a.what)


if __name__ == "__main__":
    raise SystemExit(main())
