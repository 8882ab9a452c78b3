"""Cost of the pit walls (solid wall-style borders) in `World.step`.

Prints, per track, one car driving the reference controller at 100 km/h around the lap from
the start line: ticks/s over `--ticks` ticks (compile included: a fresh process, as users run
it) and how often pymunk was consulted. e-track-2 has a 770 m pit wall along the left of its
main straight; madsim-road has none. Run: python benchmarks/bench_pit_walls.py [--ticks N]
(needs Debian's torcs-data for e-track-2).
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

from madsim.cars import load_car
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


def main() -> int:
    ticks = int(sys.argv[sys.argv.index("--ticks") + 1]) if "--ticks" in sys.argv else 3000
    for name in ("madsim-road", "e-track-2"):
        lap(name, ticks)
    return 0


if __name__ == "__main__":
    sys.exit(main())
