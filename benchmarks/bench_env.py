"""MadrasEnv speed: env.step calls (or ticks) per second of wall time, in process.

Run: python benchmarks/bench_env.py [--steps 20000] [--repeats 5] [--no-contact] [--profile CASE]

Each line gives the best wall-time rate and, in brackets, the best rate per CPU-second of this
process (less sensitive to other load on the machine).

Cases (one line each, best of --repeats runs after a warm-up; episode resets are included,
as in training):
- `sab`: one learner, no traffic, SingleAgentSimpleLapObs, normalised S-A-B actions, one tick
  per step, on madsim-road (target >= 15,000 steps/s, issue 5);
- `ts`: the same with T-S actions through the PID, latency 5 ticks per step: ticks/s through
  the latency loop (target >= 15,000 ticks/s);
- `traffic`: one S-A-B learner among 9 traffic cars (target >= 3,000 steps/s). The traffic
  behaviours are madsim.agents.traffic's ConstVel when that layer exists, else a stand-in of
  the same cost class (lane keeping at a fixed speed, a few float operations per tick);
- `multi2`, `multi3`: MadrasParallelEnv with two (three) S-A-B learners as in `sab`, no
  traffic, 60 m apart: parallel-env steps/s (each moves every learner one tick).
The learner's policy is a one-line lane keeper on the observation, so the car stays on the
road; its cost (~1 us) is inside the figure. --no-contact runs the World without the contact
solver (for comparison: the solver's broad phase runs every sub-step).
"""

from __future__ import annotations

import argparse
import cProfile
import importlib.util
import math
import pstats
import time

import numpy as np

from madsim.envs.backends import LocalBackend
from madsim.envs.madras_env import MadrasEnv
from madsim.envs.parallel_env import MadrasParallelEnv

CASES = ("sab", "ts", "traffic", "multi2", "multi3")


class LaneKeeper:
    """Stand-in traffic behaviour: steer to the centre line, hold ~40 km/h."""

    def __init__(self, entry):
        self.speed_kmh = 40.0

    def reset(self, rng, info):
        pass

    def act(self, row):
        steer = max(-1.0, min(1.0, row["angle"] - 0.5 * row["trackPos"]))
        accel = 0.5 if row["speedX"] < self.speed_kmh else 0.0
        return steer, accel, 0.0, 1


def config(case: str) -> dict:
    agent = {"observation": {"mode": "SingleAgentSimpleLapObs"},
             "action": {"space": "TS" if case == "ts" else "SAB", "normalised": True},
             "pid": {"latency": 5}, "target_speed": 16.0,
             "dones": ["TimeOut", "OutOfTrack", "TurnBackward"]}
    cfg = {"server": {"tracks": ["madsim-road"], "max_steps": 5000}, "agents": [agent]}
    if case.startswith("multi"):
        cfg["agents"] = [dict(agent, name=f"car{i}", initial_distance=[20.0 + 60 * i] * 2)
                         for i in range(int(case[5:]))]          # 60 m apart: no contact
    if case == "traffic":
        agent["observation"] = {"mode": "SingleAgentInTrafficObs"}
        cfg["traffic"] = [{"behaviour": "ConstVel", "target_speed": 11.1,
                           "initial_distance": [20.0 + 40 * i, 20.0 + 40 * i]} for i in range(9)]
    return cfg


def policy(case: str):
    if case == "ts":
        action = np.array([0.0, 0.9])
        return lambda obs: action

    def lane_keeper(obs):
        # obs[0] = angle / pi, obs[20] = trackPos; gentle throttle
        steer = max(-1.0, min(1.0, 3.0 * float(obs[0]) - 0.4 * float(obs[20])))
        return np.array([steer, 0.2, -1.0])
    return lane_keeper


class Learners:
    """A MadrasParallelEnv as `run` drives it: one step moves every live learner, each with the
    same policy; `info["ticks"]` is the step's ticks."""

    def __init__(self, env: MadrasParallelEnv):
        self.env = env

    def reset(self, seed=None):
        obs, infos = self.env.reset(seed=seed)
        return obs, infos

    def step(self, actions):
        obs, rewards, term, trunc, infos = self.env.step(actions)
        ticks = max(info["ticks"] for info in infos.values())
        return obs, rewards, not self.env.agents, False, {"ticks": ticks}


def run(env, act, steps: int) -> tuple[float, float, int]:
    """Wall and CPU seconds for `steps` env.step calls (resets included), and the ticks they
    drove."""
    if isinstance(env, Learners):
        one = act
        act = lambda obs: {name: one(o) for name, o in obs.items()}   # noqa: E731
    obs, _ = env.reset(seed=0)
    ticks = 0
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(steps):
        obs, _, term, trunc, info = env.step(act(obs))
        ticks += info["ticks"]
        if term or trunc:
            obs, _ = env.reset()
    return time.perf_counter() - t0, time.process_time() - c0, ticks


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=20000)
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--no-contact", action="store_true")
    p.add_argument("--profile", choices=CASES, default=None)
    p.add_argument("--cases", nargs="+", choices=CASES, default=list(CASES))
    args = p.parse_args()
    real_traffic = importlib.util.find_spec("madsim.agents.traffic") is not None
    factory = None if real_traffic else LaneKeeper
    contact = "off" if args.no_contact else "on"
    for case in args.cases:
        if args.profile and case != args.profile:
            continue
        backend = LocalBackend(contact=not args.no_contact)
        if case.startswith("multi"):
            env = Learners(MadrasParallelEnv(config(case), backend=backend))
        else:
            env = MadrasEnv(config(case), backend=backend, traffic_factory=factory)
        act = policy(case)
        steps = args.steps if case != "traffic" else max(1, args.steps // 4)
        run(env, act, min(steps, 2000))                       # warm-up: numba, caches
        if args.profile:
            prof = cProfile.Profile()
            prof.runcall(run, env, act, steps)
            pstats.Stats(prof).sort_stats("tottime").print_stats(25)
            continue
        best = best_cpu = math.inf
        for _ in range(args.repeats):
            seconds, cpu, ticks = run(env, act, steps)
            best, best_cpu = min(best, seconds), min(best_cpu, cpu)
        rate, per_cpu = steps / best, steps / best_cpu
        if case == "ts":
            rate, per_cpu = ticks / best, ticks / best_cpu
            label = "ticks/s, T-S latency 5, 1 car"
        elif case == "sab":
            label = "steps/s, S-A-B, 1 car, SingleAgentSimpleLapObs"
        elif case.startswith("multi"):
            label = f"steps/s, MadrasParallelEnv, {case[5:]} S-A-B learners"
        else:
            label = (f"steps/s, S-A-B, 1 learner + 9 traffic "
                     f"({'ConstVel' if real_traffic else 'stand-in lane keeper'})")
        print(f"env {case:8s} {rate:10,.0f} {label}, contact {contact} "
              f"({per_cpu:,.0f} per CPU-s)", flush=True)


if __name__ == "__main__":
    main()
