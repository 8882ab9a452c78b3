"""A scripted T-S driver for Experiment 5 (driving through traffic): is the scenario solvable?

The driver sees only what the PPO agent sees (the scenario's observation: angle, track,
trackPos, speedX/Y/Z, opponents, with gym_torcs's scaling) and answers T-S actions
[track position, speed], both normalised to [-1, 1]. Rule: find the nearest car ahead in the
opponents sensor (36 sectors of 10 degrees), bound its track position from the sector's two
edges, and drive in the half of the road away from it (the parked cars stand at +-1.25 m);
while its side cannot be told yet, drive on the centre line, where the sector edge at 0
degrees tells left from right; slow down when a car is close ahead in the own path.

It is evaluated as the experiment evaluates PPO (madsim.experiments.evaluate.evaluate_single:
100 episodes per traffic count, seeds 1,000,000 + k, the scenario's time limit):

    PYTHONPATH=. python examples/exp5_scripted_driver.py               # 3..9 cars, 100 episodes
    PYTHONPATH=. python examples/exp5_scripted_driver.py --counts 4 5 --episodes 20
    PYTHONPATH=. python examples/exp5_scripted_driver.py --reverse-traffic   # entries reversed

Prints, per traffic count, the success rate (Rank1 with no Collision) and how the episodes
ended.
"""

from __future__ import annotations

import argparse
import collections
import copy
import math
import time

import numpy as np
import yaml

from madsim.experiments.evaluate import evaluate_single
from madsim.experiments.registry import SCENARIO_DIR

LANE_M = 1.2            # |n| of the lane aimed at beside a parked car (m; the road is +-2.5 m)
OVERSHOOT = 4.0         # aim at target + OVERSHOOT x (target - n) ...
AIM_MAX_M = 2.3         # ... within +-AIM_MAX_M (m)
SPOT_TOL_M = 0.4        # a car within this of a parking spot's n may be parked there (m)
PARKED_M = 1.25         # |n| of the parking spots (m, the scenario's +-0.25 of the 10 m road)
SEEN_AHEAD_M = 35.0     # cars farther ahead than this are ignored (m)
CLOSE_M = 9.0           # a car in the own path closer than this: crawl (m)
NEXT_M = 2.0            # a car this far ahead of the own car (m, centres) is the next one
BESIDE_M = 4.6          # ... less far ahead and less than this behind: beside (m)
CLEAR_M = 2.3           # lateral distance kept to a car beside (m, centres)
SLOW_M = 30.0           # change sides at SLOW_SPEED when the next car is this close (m)
SLOW_SPEED = 0.5        # of the target speed


def scripted_policy(columns: dict, half_width_m: float, limit: float):
    """Batch policy obs (n, d) -> T-S actions (n, 2) for the exp5 observation layout.

    columns: {field: first column} of the observation; half_width_m: half the physical road
    width (trackPos = n / half_width_m); limit: the track limit (action 1 = trackPos limit)."""
    k = np.arange(36)
    lo = np.radians(-180.0 + 10.0 * k)          # sector edges, clockwise (right) positive
    hi = lo + np.radians(10.0)

    def policy(obs: np.ndarray) -> np.ndarray:
        angle = obs[:, columns["angle"]] * math.pi            # rad, track axis vs heading
        n_own = obs[:, columns["trackPos"]] * half_width_m    # m, left +
        opp = obs[:, columns["opponents"]:columns["opponents"] + 36] * 200.0
        # bearing from the track axis (clockwise +): sector bearing + the car's yaw to the right
        b_lo, b_hi = lo[None, :] + angle[:, None], hi[None, :] + angle[:, None]
        ahead = opp * np.cos(0.5 * (b_lo + b_hi))             # m along the road
        # the car's n lies between the two edges' lateral positions (right of the heading: -)
        n_a = n_own[:, None] - opp * np.sin(b_lo)
        n_b = n_own[:, None] - opp * np.sin(b_hi)
        n_min, n_max = np.minimum(n_a, n_b), np.maximum(n_a, n_b)
        rows = np.arange(len(obs))
        valid = opp < 199.0
        # the next car: the nearest at least NEXT_M ahead; beside: within a car length
        nxt = np.where(valid & (ahead >= NEXT_M) & (ahead < SEEN_AHEAD_M), ahead, np.inf)
        j = np.argmin(nxt, axis=1)
        any_next = np.isfinite(nxt[rows, j])
        c_min, c_max, c_ahead = n_min[rows, j], n_max[rows, j], nxt[rows, j]
        # is it consistent with the left spot, the right spot?
        left_ok = (c_max > PARKED_M - SPOT_TOL_M) & (c_min < PARKED_M + SPOT_TOL_M)
        right_ok = (c_max > -PARKED_M - SPOT_TOL_M) & (c_min < -PARKED_M + SPOT_TOL_M)
        centre = 0.5 * (c_min + c_max)
        guess = -np.sign(centre) * LANE_M                               # away from the middle
        target = np.where(left_ok & right_ok, guess,
                          np.where(left_ok, -LANE_M, np.where(right_ok, LANE_M, guess)))
        # nothing ahead: stay on the own side of the road
        target = np.where(any_next, target, np.sign(n_own) * LANE_M)
        # a car beside: keep clear of it whatever the next car asks
        beside = valid & (ahead > -BESIDE_M) & (ahead < NEXT_M)
        mid = 0.5 * (n_min + n_max)
        left_of_me = beside & (mid > n_own[:, None])
        right_of_me = beside & (mid <= n_own[:, None])
        cap = np.min(np.where(left_of_me, mid - CLEAR_M, np.inf), axis=1)
        floor = np.max(np.where(right_of_me, mid + CLEAR_M, -np.inf), axis=1)
        target = np.minimum(np.maximum(target, floor), cap)
        # slow down to change sides before the next car, and behind a car in the own path
        crossing = any_next & (np.sign(target) != np.sign(n_own)) & (c_ahead < SLOW_M)
        in_path = any_next & (c_ahead < CLOSE_M) & (np.abs(centre - n_own) < 1.9)
        speed = np.where(in_path, 0.1, np.where(crossing, SLOW_SPEED, 1.0))
        # aim beyond the lane while far from it: the T-S PID turns in proportion to the error
        aim = np.clip(target + OVERSHOOT * (target - n_own), -AIM_MAX_M, AIM_MAX_M)
        lane = np.clip(aim / half_width_m / limit, -1.0, 1.0)
        return np.stack([lane, speed], axis=1).astype(np.float32)

    return policy


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--counts", type=int, nargs="+", default=list(range(3, 10)))
    ap.add_argument("--episodes", type=int, default=100)
    ap.add_argument("--reverse-traffic", action="store_true",
                    help="reverse the scenario's traffic entries (first entry: the nearest spot)")
    args = ap.parse_args()
    base = yaml.safe_load((SCENARIO_DIR / "exp5.yml").read_text())
    if args.reverse_traffic:
        base["traffic"] = base["traffic"][::-1]
    fields = base["agents"][0]["observation"]["fields"]
    widths = {"track": 19, "opponents": 36}
    columns, col = {}, 0
    for name in fields:
        columns[name] = col
        col += widths.get(name, 1)
    limit = float(base["server"]["track_limits"][1])
    policy = scripted_policy(columns, half_width_m=5.0, limit=limit)   # Aalborg: 10 m wide
    print("cars | success | how the episodes end (dones: count) | mean lap fraction | wall s")
    for n in args.counts:
        cfg = copy.deepcopy(base)
        cfg["server"]["traffic_count"] = [n, n]
        t0 = time.perf_counter()
        summary, per = evaluate_single(policy, cfg, episodes=args.episodes)
        ends = collections.Counter("+".join(e["dones"]) or "none" for e in per)
        lap = np.mean([e["lap_fraction"] for e in per])
        print(f"{n} | {100 * summary['success_rate']:.0f} % | {dict(ends)} | {lap:.3f} | "
              f"{time.perf_counter() - t0:.0f}")


if __name__ == "__main__":
    main()
