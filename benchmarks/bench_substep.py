"""The cost of one car sub-step (`kernel.advance`, 0.002 s): a component figure, warmed up.

1000 cars follow their lanes with contact off, at speed (the explicit spin step) and starting
from rest (the implicit one, below 3 m/s). By default two cases: madsim-speedway with the
sedan, GT and buggy in turn (smooth tarmac), and g-track-1 with car1-trb1 (a real TORCS track
and car: road roughness under every wheel, what `madsim serve` pays); `--track` / `--car`
(repeatable) time one case of your own. Only `kernel.advance` is timed, in CPU seconds
(`time.process_time`: comparable on a loaded machine); the controller runs between the timed
calls. Prints ns per car sub-step, best of `--repeats` runs of `--ticks` ticks of 10 sub-steps.
Run: python benchmarks/bench_substep.py [--ticks 30] [--repeats 5] [--track T --car C ...]
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
CASES = (("madsim-speedway", ("madsim-sedan", "madsim-gt", "madsim-buggy")),
         ("g-track-1", ("car1-trb1",)))
"""(track, cars taken in turn) of the default run."""


def _world(track_name: str, car_names: tuple[str, ...],
           speed_ms: float) -> tuple[World, np.ndarray, np.ndarray]:
    track = load_track(track_name)
    specs = {name: load_car(name) for name in car_names}
    cars = [specs[car_names[i % len(car_names)]] for i in range(N_CARS)]
    w = World(track, cars, np.random.default_rng(0), contact=False)
    lane = np.arange(N_CARS) % 3
    lane_m = min(5.0, track.width / 4)
    s = (np.arange(N_CARS) // 3) * (track.length / math.ceil(N_CARS / 3))
    w.reset(np.column_stack([s, (lane - 1) * lane_m, np.full(N_CARS, speed_ms)]),
            gears=4 if speed_ms > 5.0 else 1)
    return w, np.zeros((N_CARS, 5)), (lane - 1) * lane_m


def ns_per_substep(track_name: str, car_names: tuple[str, ...], speed_ms: float,
                   target_ms: float, ticks: int, repeats: int) -> float:
    """Best CPU ns per car sub-step of `kernel.advance` over `repeats` fresh runs."""
    best = math.inf
    for _ in range(repeats):
        w, u, lane_n = _world(track_name, car_names, speed_ms)
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
    ap.add_argument("--track", help="time this track only (with --car)")
    ap.add_argument("--car", action="append", help="car(s) taken in turn (repeatable; with --track)")
    args = ap.parse_args()
    if (args.track is None) != (args.car is None):
        ap.error("--track and --car go together")
    cases = ((args.track, tuple(args.car)),) if args.track else CASES
    for track_name, car_names in cases:
        ns_per_substep(track_name, car_names, 25.0, 25.0, 2, 1)       # compile, load the track
        label = f"{track_name}, {'/'.join(car_names)}"
        fast = ns_per_substep(track_name, car_names, 25.0, 25.0, args.ticks, args.repeats)
        print(f"car sub-step at speed (25 m/s, explicit spin step), {label}: {fast:.0f} ns "
              "(CPU, component figure)")
        slow = ns_per_substep(track_name, car_names, 0.0, 2.0, args.ticks, args.repeats)
        print(f"car sub-step from rest (< 3 m/s, implicit spin step), {label}: {slow:.0f} ns "
              "(CPU, component figure)")


if __name__ == "__main__":
    main()
