"""make_vec speed: env-steps per second (one env-step = one episode advanced one 0.02 s tick),
and where the time goes.

Run: python benchmarks/bench_vector.py [--sizes 1 64 1024] [--seconds 4] [--threads]
     [--cases solo traffic] [--no-contact] [--baseline]

Cases (one line per case and size):
- `solo`: one learner per episode, no traffic: SingleAgentSimpleLapObs, normalised S-A-B,
  madsim-road, the default rewards and dones (episodes end and autoreset, resets included);
- `traffic`: the same learner among 4 traffic cars per episode (madsim.agents.traffic's
  ConstVel at 40 km/h in two lanes, starting 30-120 m ahead), SingleAgentInTrafficObs;
- `random` (not run by default): `solo` with random steering (uniform on [-1, 1]) and
  throttle (accel >= 0.5, no brake), so that episodes end within seconds (off the road, into
  a barrier): resets and contact resolution included.
The learners' policy (solo, traffic) is a lane keeper on the observations (numpy over all
episodes), so cars stay on the road; its cost is inside the figure. Each run steps for --seconds of wall time
after a warm-up (numba compiled, every episode started). The time split comes from timers
around the batch's compiled calls (physics sub-steps + contact broad phase; sensors), the
contact solver's Python side, the traffic behaviours and the autoresets; "agent side" is the
rest of the vector env's step (actions, PID, observations, rewards, dones, infos).
Wall figures depend on what else runs on the machine; "per CPU-s" divides by this process's
CPU time (all threads) and is less sensitive to other load. --baseline adds, per case and
size, gymnasium's SyncVectorEnv over N MadrasEnvs (what make_vec replaces).
Threads: numba's OpenMP layer spins while waiting; on a machine shared with other work, run
with OMP_WAIT_POLICY=passive.
"""

from __future__ import annotations

import argparse
import time
from collections import defaultdict

import numpy as np
from gymnasium.vector import SyncVectorEnv

from madsim.envs.madras_env import MadrasEnv
from madsim.envs.vector import make_vec


def config(case: str) -> dict:
    agent = {"name": "learner", "target_speed": 16.0,
             "observation": {"mode": "SingleAgentInTrafficObs" if case == "traffic"
                             else "SingleAgentSimpleLapObs"}}
    cfg = {"server": {"tracks": ["madsim-road"], "cars": ["madsim-sedan"], "max_steps": 20000},
           "agents": [agent]}
    if case == "traffic":
        cfg["traffic"] = [{"behaviour": "ConstVel", "target_speed": 11.1,
                           "lane": -0.5 if i % 2 else 0.5,
                           "initial_distance": [30.0 + 30 * i, 30.0 + 30 * i],
                           "initial_trackpos": [-0.5 if i % 2 else 0.5] * 2} for i in range(4)]
    return cfg


def lane_keeper(obs: np.ndarray) -> np.ndarray:
    """Normalised S-A-B from observations: steer to the centre line, hold ~50 km/h."""
    a = np.empty((obs.shape[0], 3), dtype=np.float32)
    angle, tpos, speed_kmh = obs[:, 0] * np.pi, obs[:, 20], obs[:, 21] * 50.0
    a[:, 0] = np.clip(angle * 2.0 - tpos * 0.5, -1.0, 1.0)
    a[:, 1] = np.where(speed_kmh < 50.0, 0.2, -1.0)
    a[:, 2] = -1.0
    return a


class Timers:
    """Wall time spent in wrapped callables, by label; a call inside another timed call counts
    for the outer one only (a reset's sensors count as reset time)."""

    def __init__(self):
        self.spent = defaultdict(float)
        self.depth = 0

    def wrap(self, obj, name: str, label: str) -> None:
        fn = getattr(obj, name)

        def timed(*args, **kwargs):
            if self.depth:
                return fn(*args, **kwargs)
            self.depth += 1
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                self.spent[label] += time.perf_counter() - t0
                self.depth -= 1
        setattr(obj, name, timed)


def policy(case: str, seed: int = 0):
    """obs -> actions for a case (see the module docstring)."""
    if case != "random":
        return lane_keeper
    rng = np.random.default_rng(seed)

    def random_driver(obs):
        a = rng.uniform(-1.0, 1.0, (obs.shape[0], 3)).astype(np.float32)
        a[:, 1] = np.abs(a[:, 1])                          # throttle, no brake
        a[:, 2] = -1.0
        return a
    return random_driver


def run(case: str, n: int, seconds: float, threads: bool, contact: bool) -> str:
    env = make_vec(config(case), n, threads=threads, contact=contact)
    act = policy(case)
    obs, _ = env.reset(seed=0)
    for _ in range(5):                                     # warm-up (compilation)
        obs = env.step(act(obs))[0]
    timers = Timers()
    b = env.batch
    timers.wrap(b, "_advance", "physics")
    timers.wrap(b, "_sense", "sensors")
    timers.wrap(b, "_resolve", "contact")
    timers.wrap(env, "_traffic_controls", "traffic")
    timers.wrap(env, "_reset_slots", "resets")
    steps, ended = 0, 0
    c0, t0 = time.process_time(), time.perf_counter()
    while True:
        obs, _, term, trunc, _ = env.step(act(obs))
        steps += 1
        ended += int(np.sum(term | trunc))
        wall = time.perf_counter() - t0
        if wall >= seconds and steps >= 3:
            break
    cpu = time.process_time() - c0
    rate, cpu_rate = steps * n / wall, steps * n / cpu
    s = timers.spent
    split = {k: s[k] for k in ("physics", "sensors", "contact", "traffic", "resets")}
    split["agent side"] = wall - sum(split.values())
    parts = ", ".join(f"{k} {100 * v / wall:.0f}%" for k, v in split.items())
    env.close()
    return (f"{case:8s} N={n:5d}{' threads' if threads else ''}: {rate:10,.0f} env-steps/s "
            f"({cpu_rate:,.0f} per CPU-s; {1e6 / rate:.2f} us per env-step; {steps} steps, "
            f"{ended} episodes ended, {b.solvers_built} contact solvers built) | {parts}")


def baseline(case: str, n: int, seconds: float, contact: bool) -> str:
    """The same episodes as N MadrasEnvs in gymnasium's SyncVectorEnv."""
    from madsim.envs.backends import LocalBackend

    cfg = config(case)
    env = SyncVectorEnv([lambda: MadrasEnv(cfg, backend=LocalBackend(contact=contact))
                         for _ in range(n)])
    act = policy(case)
    obs, _ = env.reset(seed=0)
    for _ in range(5):
        obs = env.step(act(obs))[0]
    steps = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds or steps < 3:
        obs = env.step(act(obs))[0]
        steps += 1
    rate = steps * n / (time.perf_counter() - t0)
    env.close()
    return (f"{case:8s} N={n:5d} SyncVectorEnv(MadrasEnv): {rate:10,.0f} env-steps/s "
            f"({1e6 / rate:.2f} us per env-step; {steps} steps)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1, 64, 1024])
    ap.add_argument("--cases", nargs="+", default=["solo", "traffic"], choices=["solo", "traffic", "random"])
    ap.add_argument("--seconds", type=float, default=4.0)
    ap.add_argument("--threads", action="store_true", help="share episodes among numba threads")
    ap.add_argument("--no-contact", action="store_true")
    ap.add_argument("--baseline", action="store_true", help="also time SyncVectorEnv(MadrasEnv)")
    args = ap.parse_args()
    for case in args.cases:
        for n in args.sizes:
            print(run(case, n, args.seconds, args.threads, not args.no_contact), flush=True)
            if args.baseline:
                print(baseline(case, n, args.seconds, not args.no_contact), flush=True)


if __name__ == "__main__":
    main()
