"""Traffic safety: episodes of 8 mixed traffic cars, no learner, on the narrow madsim-street.

Run: python benchmarks/traffic_safety.py [--episodes 200] [--seconds 60] [--first-seed 0] [--jobs 1]

The scenario (behaviours, ranges, placement by `draw_traffic_placements`) is the one of the
test suite, `tests/agents/test_traffic.py` (MIXED_STREET_YAML, `mixed_street_episode`), which
runs a few episodes; this script runs many. Episode k uses seed first_seed + k. One line per
figure: episodes with a traffic-traffic contact, ticks with one, car-ticks off the road
(|trackPos| > 1), distance driven per car, cars standing at the end outside the lane the
Parked car blocks, and the cost.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

_TESTS = Path(__file__).resolve().parents[1] / "tests" / "agents" / "test_traffic.py"


def _scenario():
    spec = importlib.util.spec_from_file_location("traffic_scenario", _TESTS)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module                 # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def _run(seeds: list[int], seconds: float) -> list[dict]:
    scenario = _scenario()
    out = []
    for seed in seeds:
        started = time.process_time()
        result = scenario.mixed_street_episode(seed, seconds)
        result["cpu_s"] = time.process_time() - started
        result["seed"] = seed
        out.append(result)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--jobs", type=int, default=1, help="worker processes")
    args = parser.parse_args()
    seeds = list(range(args.first_seed, args.first_seed + args.episodes))
    started = time.perf_counter()
    if args.jobs > 1:
        chunks = [seeds[i::args.jobs] for i in range(args.jobs)]
        with ProcessPoolExecutor(args.jobs) as pool:
            results = [r for part in pool.map(_run, chunks, [args.seconds] * args.jobs) for r in part]
    else:
        results = _run(seeds, args.seconds)
    wall = time.perf_counter() - started
    results.sort(key=lambda r: r["seed"])
    bad = [r["seed"] for r in results if r["contact_ticks"]]
    off = [r["seed"] for r in results if r["off_track"]]
    travelled = np.array([r["travelled"] for r in results])
    stuck = np.array([len(r["stuck"]) for r in results])
    cpu = np.array([r["cpu_s"] for r in results])
    ticks = round(args.seconds / 0.02)
    print(f"episodes: {len(results)} x {args.seconds:g} s ({ticks} ticks) x 8 cars on madsim-street")
    print(f"episodes with a traffic-traffic contact: {len(bad)} {bad[:20]}")
    print(f"ticks with a contact: {sum(r['contact_ticks'] for r in results)}")
    print(f"episodes with a car off the road: {len(off)} {off[:20]}; "
          f"car-ticks off the road: {sum(r['off_track'] for r in results)}")
    print("mean distance driven per car (m): " + ", ".join(f"{round(x):d}" for x in travelled.mean(axis=0)))
    print(f"cars standing at the end outside the Parked car's lane: mean {stuck.mean():.2f}, "
          f"histogram {np.bincount(stuck).tolist()}")
    print(f"cost: {cpu.mean():.2f} s CPU per episode, {1e6 * cpu.mean() / (ticks * 8):.1f} us per "
          f"car-tick (World, sensors and behaviours); wall {wall:.0f} s with {args.jobs} job(s)")


if __name__ == "__main__":
    main()
