"""Speed of `World.step` (10 sub-steps of 0.002 s, lap bookkeeping, contact broad phase).

Prints one line per figure. Only `World.step` is timed; the controllers that produce the
controls run between the timed calls. Each figure is the best of a few repeats (other processes
on a small machine only ever slow a run down). Run: python benchmarks/bench_physics.py [--quick]
"""

from __future__ import annotations

import math
import platform
import sys
import time

import numpy as np

from madsim.cars import load_car
from madsim.physics.world import World
from madsim.tracks import load_track

TARGETS = {"one": 100_000, "close": 3_000, "many": 500_000}


def follow(world: World, u: np.ndarray, target_ms: np.ndarray, noise: float = 0.0, rng=None,
           lane_n: np.ndarray | float = 0.0) -> None:
    """Reference-style controller, vectorised: hold a lateral offset (default the centre line),
    P-control the speed."""
    angle = (world.track_heading - world.yaw + math.pi) % (2 * math.pi) - math.pi
    steer = (angle - 0.5 * (world.n - lane_n) / (world.track.width / 2)) / 0.366519
    if noise:
        steer = steer + rng.normal(0.0, noise, world.n_cars)
    u[:, 0] = np.clip(steer, -1, 1)
    u[:, 1] = np.clip((target_ms - world.vx) / 3.0, 0, 1)
    u[:, 2] = np.clip((world.vx - target_ms) / 3.0, 0, 1)


def timed(world: World, u: np.ndarray, ticks: int, control, repeats: int = 3) -> float:
    """Best seconds per tick over `repeats` runs of `ticks` ticks."""
    best = math.inf
    for _ in range(repeats):
        total = 0.0
        for _ in range(ticks):
            control()
            t0 = time.perf_counter()
            world.step(u)
            total += time.perf_counter() - t0
        best = min(best, total / ticks)
    return best


def one_car(ticks: int) -> float:
    track = load_track("madsim-road")
    w = World(track, [load_car("madsim-sedan")], np.random.default_rng(0))
    w.reset(np.array([[10.0, 0.0, 20.0]]), gears=3)
    u = np.array([[0.0, 0.0, 0.0, 3.0, 0.0]])
    target = np.array([20.0])
    w.step(u)
    sec = timed(w, u, ticks, lambda: follow(w, u, target))
    print(f"1 car, contact {'on' if w.contact_active else 'off'}: {1 / sec:,.0f} ticks/s "
          f"({sec * 1e6:.1f} us/tick; target {TARGETS['one']:,}){_consults(w, 3 * ticks)}")
    return 1 / sec


def _consults(world: World, ticks: int) -> str:
    if not world.contact_active:
        return ""
    return f"; pymunk consulted {world._solver.stats['consults']} times in {ticks} ticks"


def ten_close(ticks: int) -> float:
    track = load_track("madsim-street")          # 5 m wide: the pack rubs walls and each other
    cars = [load_car(n) for n in ("madsim-sedan", "madsim-gt", "madsim-buggy")] * 3 + [load_car("madsim-sedan")]
    rng = np.random.default_rng(1)
    w = World(track, cars, np.random.default_rng(0))
    s = track.length - 30.0 - 7.0 * np.arange(10)
    w.reset(np.column_stack([s, np.where(np.arange(10) % 2, -1.2, 1.2), np.full(10, 12.0)]), gears=2)
    u = np.zeros((10, 5))
    u[:, 3] = 2
    target = 14.0 + 4.0 * rng.uniform(size=10)
    w.step(u)
    stats0 = dict(w._solver.stats) if w.contact_active else {}
    contact_ticks = [0]

    def control():
        follow(w, u, target, noise=0.4, rng=rng)
        contact_ticks[0] += int(w.contact_car.any() or w.contact_wall.any())

    sec = timed(w, u, ticks, control)
    extra = ""
    if w.contact_active:
        st = w._solver.stats
        consults = st["consults"] - stats0.get("consults", 0)
        extra = (f"; pymunk consulted {consults} times in {3 * ticks} ticks, "
                 f"contact on {contact_ticks[0]} ticks")
    print(f"10 cars close, contact {'on' if w.contact_active else 'off'}: {1 / sec:,.0f} ticks/s "
          f"({sec * 1e6:.0f} us/tick; target {TARGETS['close']:,}){extra}")
    return 1 / sec


def many(ticks: int, contact: bool, threads: bool) -> float:
    track = load_track("madsim-speedway")        # 4.2 km; three lanes of 333 cars, 12.7 m apart
    n = 1000
    names = ("madsim-sedan", "madsim-gt", "madsim-buggy")
    cars = [load_car(names[i % 3]) for i in range(n)]
    w = World(track, cars, np.random.default_rng(0), contact=contact, threads=threads)
    lane = np.arange(n) % 3
    s = (np.arange(n) // 3) * (track.length / math.ceil(n / 3))
    w.reset(np.column_stack([s, (lane - 1) * 5.0, np.full(n, 30.0)]), gears=4)
    u = np.zeros((n, 5))
    u[:, 3] = 4
    target = np.full(n, 25.0)
    w.step(u)
    lanes_n = (lane - 1) * 5.0                     # each car keeps its own lane
    sec = timed(w, u, ticks, lambda: follow(w, u, target, lane_n=lanes_n))
    rate = n / sec
    print(f"1000 cars spread, contact {'on' if w.contact_active else 'off'}, "
          f"{'threads' if threads else 'one thread'}: {rate:,.0f} car-ticks/s "
          f"({sec / n * 1e6:.2f} us per car-tick; target {TARGETS['many']:,}){_consults(w, 3 * ticks)}")
    return rate


def main() -> int:
    quick = "--quick" in sys.argv
    print(f"# {platform.processor() or platform.machine()}, python {platform.python_version()}, "
          f"numpy {np.__version__}")
    one_car(2000 if quick else 20000)
    ten_close(300 if quick else 2000)
    for contact, threads in ((False, False), (True, False), (False, True), (True, True)):
        many(20 if quick else 150, contact, threads)
    return 0


if __name__ == "__main__":
    sys.exit(main())
