"""Cost of the pit walls (solid wall-style borders) in `World.step`.

Prints, per track, one car driving the reference controller at 100 km/h around the lap from
the start line: ticks/s over `--ticks` ticks (compile included: a fresh process, as users run
it) and how often pymunk was consulted. Then a component figure (warm): the contact broad
phase's full clearance check (the only per-tick code the pit walls change), ns per car, for
1000 cars spread over the track with every cached clearance dropped before each call.
e-track-2 has pit walls along the left of its main straight; madsim-road and madsim-speedway
have none. Run: python benchmarks/bench_pit_walls.py [--ticks N] (needs Debian's torcs-data
for e-track-2).
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

from madsim.cars import load_car
from madsim.physics.contact import ContactSolver
from madsim.physics.world import World
from madsim.tracks import load_track


def lap(track_name: str, ticks: int) -> None:
    track = load_track(track_name)
    world = World(track, [load_car("car1-trb1" if track_name != "madsim-road" else "madsim-sedan")],
                  np.random.default_rng(0))
    world.reset(np.array([[0.0, 0.0, 100 / 3.6]]), gears=3)
    u = np.array([[0.0, 0.0, 0.0, 3.0, 0.0]])
    t0 = time.perf_counter()
    for _ in range(ticks):
        angle = (world.track_heading[0] - world.yaw[0] + math.pi) % (2 * math.pi) - math.pi
        u[0, 0] = np.clip((angle - 0.5 * world.n[0] / (track.width / 2)) / 0.366519, -1, 1)
        e = 100 / 3.6 - world.vx[0]
        u[0, 1], u[0, 2] = np.clip(e / 3.0, 0, 1), np.clip(-e / 3.0, 0, 1)
        world.step(u)
    sec = time.perf_counter() - t0
    walls = track.pit_wall_pieces().any() if hasattr(track, "pit_wall_pieces") else "?"  # older trees
    print(f"{track_name} (pit walls: {walls}): {ticks / sec:,.0f} ticks/s over {ticks} ticks "
          f"(compile included), at {world.vx[0] * 3.6:.0f} km/h; pymunk consulted "
          f"{world._solver.stats['consults']} times")


def broad_phase(track_name: str, n: int = 1000, calls: int = 20, repeats: int = 30) -> None:
    track = load_track(track_name)
    s = np.linspace(0.0, track.length, n, endpoint=False)
    x, y, _, h = track.pose(s, np.tile([-2.0, 0.0, 2.0], n // 3 + 1)[:n])
    x, y, yaw = (np.ascontiguousarray(a, dtype=np.float64) for a in (x, y, h))
    piece = track.piece_at(s).astype(np.int64)
    solver = ContactSolver(track, np.full(n, 2.3), np.full(n, 0.95), np.full(n, 1200.0),
                           np.full(n, 2000.0))
    kernel, args = solver.broad_phase_kernel, solver.broad_phase_args
    cache = args[4]
    kernel(x, y, yaw, piece, *args)
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            cache[:, 3] = -1.0                  # every car's clearance measured again
            kernel(x, y, yaw, piece, *args)
        best = min(best, (time.perf_counter() - t0) / calls / n)
    print(f"{track_name}: broad phase, full clearance check: {best * 1e9:.0f} ns per car "
          f"(component figure, warm; best of {repeats} x {calls} calls, {n} cars)")


def main() -> int:
    ticks = int(sys.argv[sys.argv.index("--ticks") + 1]) if "--ticks" in sys.argv else 3000
    for name in ("madsim-road", "e-track-2"):
        lap(name, ticks)
    for name in ("madsim-speedway", "e-track-2"):
        broad_phase(name)
    return 0


if __name__ == "__main__":
    sys.exit(main())
