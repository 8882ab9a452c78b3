"""Contact solver cost per resolve() call (one call per 0.002 s sub-step), one line per figure.

Cars move along the track at 50 m/s (poses precomputed; only resolve() is timed):
- nothing close: 1 car, 10 cars spread, 1,000 cars spread over a long track;
- 10 cars in a 2 x 5 block 1 cm apart (within reach: pymunk consulted, no contact), and the same
  block with boxes overlapping by 1 cm every call (every car in contact: 21 pairs).
Each figure is the best of several rounds (the machine is shared).

Run: python benchmarks/bench_contact.py [TRACK]   (default: madsim-speedway, 4.2 km, 20 m wide)
"""

from __future__ import annotations

import sys
import time

import numba
import numpy as np

from madsim.physics.contact import ContactSolver
from madsim.tracks import load_track

DT = 0.002
HL, HW, MASS, IZZ = 2.35, 0.95, 1200.0, 2000.0


def trajectories(track, s0, n0, speed, calls):
    """(calls, N) x, y, yaw of cars driving along the track at constant lateral offsets."""
    s = (s0[None, :] + speed * DT * np.arange(1, calls + 1)[:, None]) % track.length
    x, y, _, yaw = track.pose(s, np.broadcast_to(n0, s.shape))
    return x, y, yaw, track.piece_at(s).astype(np.int64)


def straight_middle(track) -> float:
    """s in the middle of the longest run of straight pieces."""
    geo = track.geo
    best, best_len, start = 0.0, 0.0, None
    for i in range(geo.shape[0] + 1):
        straight = i < geo.shape[0] and geo[i, 0] == 0.0
        if straight and start is None:
            start = i
        elif not straight and start is not None:
            length = geo[start:i, 2].sum()
            if length > best_len:
                best, best_len = geo[start, 1] + length / 2, length
            start = None
    return best


def best_chunk(times: list[float], chunks: int = 5) -> float:
    """Mean time per call of the fastest of `chunks` consecutive chunks of calls."""
    parts = np.array_split(np.asarray(times), chunks)
    return float(min(p.mean() for p in parts))


def time_spread(track, n_cars, calls, rng) -> tuple[float, dict]:
    if n_cars == 1:
        s0, n0 = np.array([track.length / 3]), np.zeros(1)
    else:
        s0 = np.arange(n_cars) * track.length / n_cars + rng.uniform(0, 0.2, n_cars)
        n0 = np.array([-6.0, -2.0, 2.0, 6.0])[np.arange(n_cars) % 4]   # 1000 % 4 == 0: no wrap clash
    xs, ys, yaws, pieces = trajectories(track, s0, n0, 50.0, calls)
    solver = ContactSolver(track, np.full(n_cars, HL), np.full(n_cars, HW), np.full(n_cars, MASS),
                           np.full(n_cars, IZZ))
    vx = 50.0 * np.cos(yaws[0])
    vy = 50.0 * np.sin(yaws[0])
    w = np.zeros(n_cars)
    times = []
    for k in range(calls):
        x, y, yaw = xs[k].copy(), ys[k].copy(), yaws[k].copy()
        t0 = time.perf_counter()
        solver.resolve(x, y, yaw, vx, vy, w, pieces[k], DT)
        times.append(time.perf_counter() - t0)
    return best_chunk(times), solver.stats


@numba.njit
def _drive_kernel(kernel, xs, ys, yaws, pieces, args):
    near = 0
    for k in range(xs.shape[0]):
        near += kernel(xs[k], ys[k], yaws[k], pieces[k], *args)
    return near


def time_kernel(track, n_cars, calls, rng) -> float:
    """The compiled broad phase alone, called from compiled code (as World's sub-step loop
    does): seconds per call."""
    s0 = np.arange(n_cars) * track.length / n_cars + rng.uniform(0, 0.2, n_cars)
    n0 = np.array([-6.0, -2.0, 2.0, 6.0])[np.arange(n_cars) % 4]
    xs, ys, yaws, pieces = trajectories(track, s0, n0, 50.0, calls)
    solver = ContactSolver(track, np.full(n_cars, HL), np.full(n_cars, HW), np.full(n_cars, MASS),
                           np.full(n_cars, IZZ))
    kernel, args = solver.broad_phase_kernel, solver.broad_phase_args
    _drive_kernel(kernel, xs[:2], ys[:2], yaws[:2], pieces[:2], args)
    t0 = time.perf_counter()
    near = _drive_kernel(kernel, xs, ys, yaws, pieces, args)
    assert near == 0
    return (time.perf_counter() - t0) / calls


def time_packed(track, calls, rng, gap) -> tuple[float, dict]:
    n_cars = 10
    col = np.arange(n_cars) // 2
    side = np.arange(n_cars) % 2
    ds = col * (2 * HL + gap)                    # gap < 0: overlap
    dn = (side - 0.5) * (2 * HW + gap)
    base = straight_middle(track) - 20.0 + 50.0 * DT * (np.arange(calls) % 200)   # stays on the straight
    s = (base[:, None] + ds[None, :]) % track.length
    xs, ys, _, yaws = track.pose(s, np.broadcast_to(dn, s.shape))
    pieces = track.piece_at(s).astype(np.int64)
    solver = ContactSolver(track, np.full(n_cars, HL), np.full(n_cars, HW), np.full(n_cars, MASS),
                           np.full(n_cars, IZZ))
    times = []
    for k in range(calls):
        x, y, yaw = xs[k].copy(), ys[k].copy(), yaws[k].copy()
        vx = 50.0 * np.cos(yaw) + rng.normal(0, 1, n_cars)
        vy = 50.0 * np.sin(yaw) + rng.normal(0, 1, n_cars)
        w = rng.normal(0, 0.1, n_cars)
        t0 = time.perf_counter()
        solver.resolve(x, y, yaw, vx, vy, w, pieces[k], DT)
        times.append(time.perf_counter() - t0)
    return best_chunk(times), solver.stats


def main() -> None:
    name = sys.argv[1] if len(sys.argv) > 1 else "madsim-speedway"
    track = load_track(name)
    rng = np.random.default_rng(0)
    time_spread(track, 2, 10, rng)           # compile / load the numba cache
    time_packed(track, 10, rng, -0.01)
    print(f"track: {track.name} length {track.length:.0f} m, width {track.width:.0f} m")
    for n_cars, calls in ((1, 20_000), (10, 20_000), (1000, 1_000)):
        per_call, stats = time_spread(track, n_cars, calls, rng)
        print(f"nothing close, {n_cars:>4} car(s): {per_call * 1e6:8.2f} us per call "
              f"({per_call * 1e9 / n_cars:7.1f} ns per car; pymunk consulted {stats['consults']} of "
              f"{stats['calls']} calls, neighbour list rebuilt {stats['list_rebuilds']} times)")
    for n_cars, calls in ((1, 200_000), (1000, 2_000)):
        per_call = time_kernel(track, n_cars, calls, rng)
        print(f"broad phase alone, called from compiled code, {n_cars:>4} car(s): {per_call * 1e9:8.0f} ns "
              f"per call ({per_call * 1e9 / n_cars:6.1f} ns per car)")
    for gap, what in ((0.01, "1 cm apart, no contact"), (-0.01, "overlapping 1 cm, 21 pairs in contact")):
        per_call, stats = time_packed(track, 5_000, rng, gap)
        print(f"10 cars packed, {what}: {per_call * 1e6:8.2f} us per call "
              f"(pymunk consulted {stats['consults']} of {stats['calls']} calls)")


if __name__ == "__main__":
    main()
