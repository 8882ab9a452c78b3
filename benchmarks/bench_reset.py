"""reset() onto another track and traffic count through MadrasEnv, as users run it.

Run: python benchmarks/bench_reset.py [--resets 120] [--steps 40] [--seed 0]

One learner (lane keeper) and 0-4 ConstVel traffic cars; each episode draws its track and
traffic count at random (`order: random`) from bundled, TORCS and generated tracks, with the
backend's default World cache (16 worlds), so some resets reuse a cached World and some build
one. Between resets the cars drive --steps env steps (untimed), so contacts happen. Prints the
median and 90th percentile of the env.reset() wall time over resets onto a track used before
(the first reset onto each track is excluded: track loading and numba compilation), and the
first-use figures separately.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from madsim.envs.madras_env import MadrasEnv

TRACKS = ["madsim-road", "madsim-oval", "madsim-street", "g-track-1", "e-track-2", "alpine-1",
          "generated:7"]


def config(seed: int) -> dict:
    agent = {"observation": {"mode": "SingleAgentInTrafficObs"},
             "action": {"space": "SAB", "normalised": True}, "target_speed": 16.0,
             "dones": ["TimeOut", "OutOfTrack", "TurnBackward"]}
    traffic = [{"behaviour": "ConstVel", "target_speed": 11.1,
                "initial_distance": [15.0 + 15 * i, 15.0 + 15 * i]} for i in range(4)]
    return {"server": {"tracks": TRACKS, "traffic_count": [0, 4], "order": "random",
                       "max_steps": 5000},
            "agents": [agent], "traffic": traffic}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--resets", type=int, default=120)
    p.add_argument("--steps", type=int, default=40)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args()
    env = MadrasEnv(config(args.seed))
    seen, first, again = set(), [], []
    obs, info = env.reset(seed=args.seed)
    for _ in range(args.resets):
        for _ in range(args.steps):
            steer = max(-1.0, min(1.0, 3.0 * float(obs[0]) - 0.4 * float(obs[20])))
            obs, _, term, trunc, info = env.step(np.array([steer, 0.3, -1.0]))
            if term or trunc:
                break
        t0 = time.perf_counter()
        obs, info = env.reset()
        dt = time.perf_counter() - t0
        track = env.core.track.name
        (again if track in seen else first).append(dt * 1e3)
        seen.add(track)
    worlds = env.core.backend.worlds_built
    env.close()
    a, f = np.array(again), np.array(first)
    print(f"reset onto a track used before: median {np.median(a):.2f} ms, 90th percentile "
          f"{np.percentile(a, 90):.2f} ms, max {a.max():.1f} ms over {a.size} resets")
    print(f"first reset onto a track: median {np.median(f):.1f} ms over {f.size} tracks; "
          f"worlds built: {worlds}")


if __name__ == "__main__":
    main()
