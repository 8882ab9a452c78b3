"""The cost of one car sub-step (`kernel.advance`, 0.002 s): a component figure, warmed up.

1000 cars (sedan, GT, buggy in turn) follow their lanes on madsim-speedway with contact off, at
speed (the explicit spin step) and starting from rest (the implicit one, below 3 m/s). Only
`kernel.advance` is timed, in CPU seconds (`time.process_time`: comparable on a loaded machine);
the controller runs between the timed calls. Prints ns per car sub-step, best of `--repeats`
runs of `--ticks` ticks of 10 sub-steps.
Run: python benchmarks/bench_substep.py [--ticks 30] [--repeats 5]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from madsim.cars import load_car
from madsim.physics import kernel
from madsim.physics.world import DT, SUBSTEPS, World
from madsim.tracks import load_track

N_CARS = 1000


def _world(speed_ms: float) -> tuple[World, np.ndarray, np.ndarray]:
    track = load_track("madsim-speedway")
    names = ("madsim-sedan", "madsim-gt", "madsim-buggy")
    cars = [load_car(names[i % 3]) for i in range(N_CARS)]
    w = World(track, cars, np.random.default_rng(0), contact=False)
    lane = np.arange(N_CARS) % 3
    s = (np.arange(N_CARS) // 3) * (track.length / math.ceil(N_CARS / 3))
    w.reset(np.column_stack([s, (lane - 1) * 5.0, np.full(N_CARS, speed_ms)]),
            gears=4 if speed_ms > 5.0 else 1)
    return w, np.zeros((N_CARS, 5)), (lane - 1) * 5.0


def ns_per_substep(speed_ms: float, target_ms: float, ticks: int, repeats: int) -> float:
    """Best CPU ns per car sub-step of `kernel.advance` over `repeats` fresh runs."""
    best = math.inf
    for _ in range(repeats):
        w, u, lane_n = _world(speed_ms)
        u[:, 3] = 4 if speed_ms > 5.0 else 1
        args = (w._cp, w._curve_w, w._curve_t, w._pt, w._surf, w._tsc)
        total = 0.0
        for _ in range(ticks):
            angle = (w.track_heading - w.yaw + math.pi) % (2 * math.pi) - math.pi
            u[:, 0] = np.clip((angle - 0.5 * (w.n - lane_n) / (w.track.width / 2)) / 0.366519, -1, 1)
            u[:, 1] = np.clip((target_ms - w.vx) / 3.0, 0, 1)
            u[:, 2] = np.clip((w.vx - target_ms) / 3.0, 0, 1)
            t0 = time.process_time()
            kernel.advance(w.state, *args, u, SUBSTEPS, DT, w.fuel_on)
            total += time.process_time() - t0
        best = min(best, total / (ticks * SUBSTEPS * N_CARS))
    return best * 1e9


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ticks", type=int, default=30)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    ns_per_substep(25.0, 25.0, 2, 1)       # compile
    fast = ns_per_substep(25.0, 25.0, args.ticks, args.repeats)
    print(f"car sub-step at speed (25 m/s, explicit spin step): {fast:.0f} ns (CPU, component figure)")
    slow = ns_per_substep(0.0, 2.0, args.ticks, args.repeats)
    print(f"car sub-step from rest (< 3 m/s, implicit spin step): {slow:.0f} ns (CPU, component figure)")


if __name__ == "__main__":
    main()
