"""Soak test: many ticks through MadrasEnv with random actions and resets, traffic on.

Run: python benchmarks/soak.py [--ticks 10000000] [--report-every 500000] [--seed 0]

One learner (normalised S-A-B actions drawn uniformly, so the car wanders off the road and
episodes end by OutOfTrack/TurnBackward/Collision/TimeOut) among four traffic cars of mixed
behaviours, on tracks drawn per episode; besides the dones, each step resets with probability
1/2000. Every step checks the observation, and every tick the World's whole state array, for
NaN or inf. Resident memory (VmRSS, /proc/self/status) is read every --report-every ticks and
printed as one line: ticks, episodes, ticks/s, RSS MB. The baseline is the RSS after the first
report (compile, caches and the first episodes are in); the last line gives the growth from
there and the count of non-finite values (targets: growth < 5 MB, zero non-finite).
Exit status 1 if either target is missed.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

RESET_PROBABILITY = 1 / 2000
GROWTH_LIMIT_MB = 5.0

CONFIG = {
    "server": {"tracks": ["madsim-road", "madsim-street", "madsim-oval"], "order": "random",
               "traffic_count": [2, 4], "max_steps": 5000},
    "agents": [{"name": "driver", "action": {"space": "SAB", "normalised": True},
                "observation": {"mode": "SingleAgentInTrafficObs"},
                "rewards": {"Progress2": {"scale": 1.0}, "Collision": {"scale": 10.0}},
                "dones": ["TimeOut", "OutOfTrack", "TurnBackward", "Collision"]}],
    "traffic": [
        {"behaviour": "ConstVel", "target_speed": 15.0, "lane": 0.4},
        {"behaviour": "SinusoidalSpeed", "mean_speed": 14.0, "speed_amplitude": 4.0, "lane": 0.0},
        {"behaviour": "RandomLaneSwitch", "target_speed": 16.0, "lanes": [-0.4, 0.4]},
        {"behaviour": "Parked", "initial_trackpos": [-0.85, -0.75]},
    ],
}


def rss_mb() -> float:
    """Resident set size of this process, MB (Linux /proc)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def soak(ticks: int, report_every: int, seed: int, log=print, config=None) -> dict:
    """Run `ticks` ticks of `config` (default CONFIG); returns {ticks, episodes, nonfinite,
    rss_mb: [(ticks, MB), ...], growth_mb, wall_s}. The growth is measured from the first report."""
    from madsim.envs import MadrasEnv

    rng = np.random.default_rng(seed)
    env = MadrasEnv(CONFIG if config is None else config)
    world_of = lambda: env.unwrapped.core.backend.world  # noqa: E731 (the World is rebuilt per track)
    obs, _ = env.reset(seed=seed)
    done_ticks = episodes = nonfinite = 0
    next_report = report_every
    curve: list[tuple[int, float]] = []
    start = time.perf_counter()
    block = rng.uniform(-1.0, 1.0, size=(4096, 3)).astype(np.float32)
    i = 0
    while done_ticks < ticks:
        if i == len(block):
            block = rng.uniform(-1.0, 1.0, size=(4096, 3)).astype(np.float32)
            i = 0
        obs, _, terminated, truncated, info = env.step(block[i])
        i += 1
        done_ticks += info.get("ticks", 1)
        if not np.isfinite(obs).all():
            nonfinite += int((~np.isfinite(obs)).sum())
        state = world_of().state
        if not np.isfinite(state).all():
            nonfinite += int((~np.isfinite(state)).sum())
        if terminated or truncated or rng.random() < RESET_PROBABILITY:
            obs, _ = env.reset()
            episodes += 1
        if done_ticks >= next_report:
            next_report += report_every
            mb = rss_mb()
            curve.append((done_ticks, mb))
            wall = time.perf_counter() - start
            log(f"{done_ticks:>10d} ticks  {episodes:>7d} episodes  {done_ticks / wall:>8.0f} ticks/s  "
                f"RSS {mb:8.2f} MB  non-finite {nonfinite}", flush=True)
    env.close()
    growth = curve[-1][1] - curve[0][1] if curve else 0.0
    return {"ticks": done_ticks, "episodes": episodes, "nonfinite": nonfinite, "rss_mb": curve,
            "growth_mb": growth, "wall_s": time.perf_counter() - start}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ticks", type=int, default=10_000_000)
    ap.add_argument("--report-every", type=int, default=500_000)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    r = soak(args.ticks, args.report_every, args.seed)
    ok = r["growth_mb"] < GROWTH_LIMIT_MB and r["nonfinite"] == 0
    print(f"soak: {r['ticks']} ticks, {r['episodes']} episodes in {r['wall_s']:.0f} s; RSS growth after the "
          f"first report {r['growth_mb']:+.2f} MB (limit {GROWTH_LIMIT_MB}); non-finite values {r['nonfinite']}: "
          f"{'PASS' if ok else 'FAIL'}", flush=True)
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
