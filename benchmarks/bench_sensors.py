"""One car with every SCR sensor, in process: World.step + SensorSuite.frame per tick.

The car is kept on the road by the SCR sample steering rule (so the contact solver has nothing to
do, as on a normal lap). Prints ticks/s with contact on and off, and the frame alone.
Run: python benchmarks/bench_sensors.py [TRACK]
"""

from __future__ import annotations

import sys
import time

import numpy as np

from madsim.cars import load_car
from madsim.physics.sensors import O_ANGLE, O_SX, O_TPOS, SensorSuite
from madsim.physics.world import World
from madsim.tracks import load_track


def run(track, contact: bool, ticks: int = 5000, repeat: int = 5) -> tuple[float, float]:
    world = World(track, [load_car("madsim-sedan")], np.random.default_rng(0), contact=contact)
    world.reset([[100.0, 0.0, 15.0]], gears=2)
    suite = SensorSuite(world)
    u = np.array([[0.0, 0.3, 0.0, 2.0, 0.0]])

    def drive(n):
        for _ in range(n):
            row = suite.frame().flat[0]
            u[0, 0] = min(1.0, max(-1.0, (row[O_ANGLE] - 0.5 * row[O_TPOS]) / 0.5))
            u[0, 1] = 0.4 if row[O_SX] < 60.0 else 0.0
            world.step(u)

    drive(300)
    best = min(_timed(drive, ticks) for _ in range(repeat)) / ticks
    frame_only = min(_timed(lambda n: [suite.frame() for _ in range(n)], ticks) for _ in range(repeat)) / ticks
    return best, frame_only


def _timed(fn, n) -> float:
    t0 = time.perf_counter()
    fn(n)
    return time.perf_counter() - t0


def main() -> None:
    track = load_track(sys.argv[1] if len(sys.argv) > 1 else "madsim-road")
    for contact in (True, False):
        tick, frame = run(track, contact)
        print(f"contact {'on ' if contact else 'off'}: step + every sensor {tick * 1e6:6.1f} us/tick "
              f"= {1 / tick:8.0f} ticks/s; sensor frame alone {frame * 1e6:5.1f} us")


if __name__ == "__main__":
    main()
