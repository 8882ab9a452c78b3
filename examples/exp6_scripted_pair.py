"""A scripted cooperative pair for Experiment 6 (two learners, one bottleneck): is it solvable?

Each learner sees only what the RLlib learners see (the scenario's observation: angle, track,
trackPos, opponents, speedX/Y/Z with gym_torcs's scaling, then peerActions, the other's action
of the previous step) and answers T-S actions [track position, speed], both normalised to
[-1, 1]. Rule (one convention, no negotiation):
- the learner on the right of the centre line (trackPos < 0) goes first: it aims at the centre
  line (the middle of the gap) at the target speed;
- the learner on the left waits, stopped, while the peer is within WAIT_M (it starts 3 m beside
  it), then also aims at the centre line, at FOLLOW_SPEED of the target speed;
- both slow down behind a car on their path (from FOLLOW_M[1] m, stopped at FOLLOW_M[0] m): once
  both are on the centre line their sides, hence their roles, may swap;
- both keep CLEAR_M (centres) to the side of a car beside them whatever the lane asks.
`--no-wait` drops the waiting (both go at once): the control that shows the bottleneck bites.

Evaluated as the experiment evaluates the RLlib pair (madsim.experiments.evaluate.evaluate_pair:
joint passage 5 m beyond the farthest parking spot with no collision before, 100 episodes,
seeds 1,000,000 + k), at both curriculum stages:

    PYTHONPATH=. python examples/exp6_scripted_pair.py                  # 100 episodes per stage
    PYTHONPATH=. python examples/exp6_scripted_pair.py --episodes 20 --no-wait
    PYTHONPATH=. python examples/exp6_scripted_pair.py --wait-m 6      # a shorter wait
"""

from __future__ import annotations

import argparse
import collections
import math
import time

import numpy as np
from madsim.experiments.evaluate import evaluate_pair, with_distance_field
from madsim.experiments.registry import experiment
from madsim.experiments.runner import load_scenario

HALF_WIDTH_M = 6.0      # Corkscrew is 12 m wide: trackPos = n / 6 m
CLEAR_M = 2.4           # lateral distance (centres, m) kept to a car beside (cars are 1.95 m wide)
BESIDE_M = 5.0          # a car less than this behind or ahead is beside (m)
PATH_M = 1.2            # a car ahead less than this to the side (centres, m) is on the own path
WAIT_M = 12.0           # the second learner waits while a car is this close (m) ...
WAIT_KMH = 3.0          # ... and it is slower than this (the start)
FOLLOW_SPEED = 0.6      # the second learner's speed, of the target speed
FOLLOW_M = (6.0, 14.0)  # speed from 0 to FOLLOW_SPEED over this gap to a car on the path (m)
OVERSHOOT = 2.0         # aim at target + OVERSHOOT x (target - n): the PID turns in proportion


def scripted_pair_policy(columns: dict, limit: float, *, wait: bool = True,
                         wait_m: float = WAIT_M):
    """obs (d,) -> T-S action (2,) for the exp6 observation layout ({field: first column});
    limit: the track limit (action +-1 = trackPos +-limit); wait_m: the second learner waits
    while a car is this close (m)."""
    k = np.arange(36)
    lo = np.radians(-180.0 + 10.0 * k)          # sector edges, clockwise (right) positive
    mid_sector = lo + np.radians(5.0)

    def policy(obs: np.ndarray) -> np.ndarray:
        angle = float(obs[columns["angle"]]) * math.pi            # rad, track axis vs heading
        n_own = float(obs[columns["trackPos"]]) * HALF_WIDTH_M    # m, left +
        speed_kmh = float(obs[columns["speedX"]]) * 50.0
        opp = obs[columns["opponents"]:columns["opponents"] + 36].astype(np.float64) * 200.0
        bearing = mid_sector + angle                              # from the track axis
        valid = opp < 199.0
        ahead = opp * np.cos(bearing)                             # m along the road
        n_car = n_own - opp * np.sin(bearing)                     # m, the car's n
        first = n_own < 0.0 or not wait
        target = 0.0
        beside = valid & (ahead > -BESIDE_M) & (ahead < BESIDE_M)
        for a, n in zip(ahead[beside], n_car[beside]):
            target = min(target, n - CLEAR_M) if n > n_own else max(target, n + CLEAR_M)
        on_path = valid & (ahead > 0.0) & (np.abs(n_car - n_own) < PATH_M)
        gap = float(np.min(np.where(on_path, ahead, np.inf)))
        speed = (1.0 if first else FOLLOW_SPEED) * float(
            np.clip((gap - FOLLOW_M[0]) / (FOLLOW_M[1] - FOLLOW_M[0]), 0.0, 1.0))
        if not first and speed_kmh < WAIT_KMH and np.any(valid & (opp < wait_m)):
            speed, target = -1.0, n_own
        aim = target + OVERSHOOT * (target - n_own)
        lane = float(np.clip(aim / HALF_WIDTH_M / limit, -1.0, 1.0))
        return np.array([lane, speed], dtype=np.float32)

    return policy


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=100)
    ap.add_argument("--no-wait", action="store_true", help="both learners go at once")
    ap.add_argument("--wait-m", type=float, default=WAIT_M,
                    help="the second learner waits while a car is this close (m)")
    ap.add_argument("--stages", type=int, nargs="+", default=[0, 1])
    args = ap.parse_args()
    exp = experiment("exp6")
    sub, final = exp.subruns[0], exp.conditions[0]
    base = load_scenario(sub)
    _, _, columns = with_distance_field(base)
    limit = float(base["server"]["track_limits"][1])
    policy = scripted_pair_policy(columns, limit, wait=not args.no_wait, wait_m=args.wait_m)
    names = [a["name"] for a in base["agents"]]
    print("stage | joint success | per learner: passed, how the episodes end | wall s")
    for stage in args.stages:
        # stage 1: the scenario as trained first (the runner never reaches stage 2's start
        # here); stage 2: the experiment's evaluation condition (the curriculum's last stage)
        cfg = load_scenario(sub, final.overrides if stage else {"curriculum": None})
        t0 = time.perf_counter()
        summary, per = evaluate_pair({a: policy for a in names}, cfg, episodes=args.episodes)
        ends = {a: dict(collections.Counter("+".join(e[f"{a}_dones"]) or "none" for e in per))
                for a in names}
        learners = "; ".join(f"{a}: {100 * summary[f'{a}_pass_rate']:.0f} % {ends[a]}"
                             for a in names)
        print(f"{stage + 1} | {100 * summary['joint_success_rate']:.0f} % | {learners} | "
              f"{time.perf_counter() - t0:.0f}")


if __name__ == "__main__":
    main()
