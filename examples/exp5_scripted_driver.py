"""A scripted T-S driver for Experiment 5 (driving through traffic): is the scenario solvable?

The driver sees only what the PPO agent sees (the scenario's observation: angle, track,
trackPos, speedX/Y/Z, opponents, with gym_torcs's scaling) and answers T-S actions
[track position, speed], both normalised to [-1, 1]. Rule:
- it drives in one of two lanes at +-lane_m, just clear of the innermost parking spot; from
  there every spot lies on a known side of its line along the road, so the sector of the next
  car ahead (opponents: 36 sectors of 10 degrees, turned by `angle` onto the road) tells its
  side, and the driver takes the other lane;
- it keeps clear of a car beside it until that car is a car length behind, then changes lanes
  aiming at the road's edge (the T-S PID turns in proportion to the lane error), at half the
  target speed;
- it follows a car in its own path, brakes 5 m behind it, and waits at the start until the
  traffic has pulled away.

It is evaluated as the experiment evaluates PPO (madsim.experiments.evaluate.evaluate_single:
100 episodes per traffic count, seeds 1,000,000 + k, the scenario's time limit):

    PYTHONPATH=. python examples/exp5_scripted_driver.py               # 3..9 cars, 100 episodes
    PYTHONPATH=. python examples/exp5_scripted_driver.py --counts 4 5 --episodes 20
    PYTHONPATH=. python examples/exp5_scripted_driver.py --spot-lane 0.225 0.275   # +-1.25 m
    PYTHONPATH=. python examples/exp5_scripted_driver.py --reverse-traffic   # the old order

Prints the distance of road the T-S learner needs to change lanes, then per traffic count the
success rate (Rank1 with no Collision) and how the episodes ended.
"""

from __future__ import annotations

import argparse
import collections
import copy
import math
import time

import numpy as np
import yaml

from madsim.experiments.evaluate import evaluate_single, with_distance_field
from madsim.experiments.registry import SCENARIO_DIR

HALF_WIDTHS_M = 0.96 + 0.97   # half the learner's width (car1-stock1) + half a traffic car's (m)
LANE_MARGIN_M = 0.2     # the lane beside a parked car clears it by this (m)
CLEAR_M = 2.0           # lateral distance (centres, m) kept to a car beside
PATH_M = 1.6            # a car ahead less than this to the side (centres, m) is in the own path
BESIDE_M = 4.6          # a car less than this behind and less than NEXT_M ahead is beside (m)
NEXT_M = 5.0            # the next car: the nearest at least this far ahead (m) ...
SEEN_AHEAD_M = 40.0     # ... and less than this (m)
SLOW_M = 25.0           # change sides at SLOW_SPEED when the next car is this close (m)
SLOW_SPEED = 0.5        # of the target speed
FOLLOW_M = (6.0, 16.0)  # speed from 0 to the target over this gap to a car in the own path (m)
STOP_M = 5.0            # brake fully closer than this to a car in the own path (m)
START_M = 15.0          # below START_KMH, wait while a car is less than this ahead (m): at the
START_KMH = 3.0         # start the traffic pulls away and crosses the road before parking
OVERSHOOT = 3.0         # aim at target + OVERSHOOT x (target - n) ...
AIM_MAX_M = 2.45        # ... within +-AIM_MAX_M (m): the T-S PID turns in proportion to the error


def scripted_policy(columns: dict, half_width_m: float, limit: float, lane_m: float):
    """Batch policy obs (n, d) -> T-S actions (n, 2) for the exp5 observation layout.

    columns: {field: first column} of the observation; half_width_m: half the physical road
    width (trackPos = n / half_width_m); limit: the track limit (action 1 = trackPos limit);
    lane_m: |n| of the lane driven beside a parked car (m): it must clear the innermost spot and
    lie inside it, so that every spot is on a known side of the own line along the road."""
    k = np.arange(36)
    lo = np.radians(-180.0 + 10.0 * k)          # sector edges, clockwise (right) positive
    hi = lo + np.radians(10.0)

    def policy(obs: np.ndarray) -> np.ndarray:
        angle = obs[:, columns["angle"]] * math.pi            # rad, track axis vs heading
        n_own = obs[:, columns["trackPos"]] * half_width_m    # m, left +
        opp = obs[:, columns["opponents"]:columns["opponents"] + 36] * 200.0
        # bearing from the track axis (clockwise +): sector bearing + the car's yaw to the right
        b_lo, b_hi = lo[None, :] + angle[:, None], hi[None, :] + angle[:, None]
        b_mid = 0.5 * (b_lo + b_hi)
        ahead = opp * np.cos(b_mid)                           # m along the road
        mid = n_own[:, None] - opp * np.sin(b_mid)            # m, the car's n (+- half a sector)
        valid = opp < 199.0
        rows = np.arange(len(obs))
        nxt = np.where(valid & (ahead >= NEXT_M) & (ahead < SEEN_AHEAD_M), ahead, np.inf)
        j = np.argmin(nxt, axis=1)
        any_next = np.isfinite(nxt[rows, j])
        # which side of the own line along the road: sector entirely left (right) of it, else
        # the sector's middle; with |n| <= lane_m every parking spot is off that line
        left = np.where(b_hi[rows, j] <= 0.0, True,
                        np.where(b_lo[rows, j] >= 0.0, False, b_mid[rows, j] < 0.0))
        side = np.where(left, 1.0, -1.0)                      # +1: the next car is to the left
        target = np.where(any_next, -side * lane_m, np.sign(n_own) * lane_m)
        # a car beside: keep clear of it whatever the next car asks
        beside = valid & (ahead > -BESIDE_M) & (ahead < NEXT_M)
        left_of_me = beside & (mid > n_own[:, None])
        cap = np.min(np.where(left_of_me, mid - CLEAR_M, np.inf), axis=1)
        floor = np.max(np.where(beside & ~left_of_me, mid + CLEAR_M, -np.inf), axis=1)
        target = np.minimum(np.maximum(target, floor), cap)
        # change sides at SLOW_SPEED
        c_ahead, c_mid = nxt[rows, j], mid[rows, j]
        crossing = any_next & (np.sign(target) != np.sign(n_own)) & (c_ahead < SLOW_M)
        # follow a car in the own path unless the target lane is clear of it (then steer away)
        in_path = valid & (ahead > 0.0) & (np.abs(mid - n_own[:, None]) < PATH_M)
        stays = np.abs(mid - target[:, None]) < CLEAR_M
        gap = np.min(np.where(in_path & stays, ahead, np.inf), axis=1)
        follow = np.clip((gap - FOLLOW_M[0]) / (FOLLOW_M[1] - FOLLOW_M[0]), 0.0, 1.0)
        gap = np.min(np.where(in_path, ahead, np.inf), axis=1)
        follow = np.where(gap < STOP_M, -1.0, follow)
        speed = np.minimum(follow, np.where(crossing, SLOW_SPEED, 1.0))
        near = np.min(np.where(valid & (ahead > 0.0) & ~in_path, opp, np.inf), axis=1)
        slow = obs[:, columns["speedX"]] * 50.0 < START_KMH
        speed = np.where(slow & (near < START_M), -1.0, speed)
        aim = np.clip(target + OVERSHOOT * (target - n_own), -AIM_MAX_M, AIM_MAX_M)
        lane = np.clip(aim / half_width_m / limit, -1.0, 1.0)
        return np.stack([lane, speed], axis=1).astype(np.float32)

    return policy


def lane_change_m(cfg: dict, speed: float, from_m: float, to_m: float) -> tuple[float, float]:
    """(metres of road, n where it started) the scenario's T-S learner needs to move from the
    lane from_m to n = to_m (m, left +) at `speed` (normalised T-S speed action), aiming at the
    road's edge beyond to_m, on the empty straight after 6 s in the lane from_m."""
    from madsim.envs.madras_env import MadrasEnv

    cfg = copy.deepcopy(cfg)
    cfg["server"]["traffic_count"] = [0, 0]
    cfg["agents"][0]["dones"] = ["TimeOut"]
    env = MadrasEnv(cfg)
    env.reset(seed=0)
    world, limit_m = env.core.backend.world, 5.0 * float(cfg["server"]["track_limits"][1])
    for _ in range(60):
        env.step(np.array([from_m / limit_m, speed], dtype=np.float32))
    s0, n0 = float(world.s[-1]), float(world.n[-1])
    for _ in range(300):
        env.step(np.array([math.copysign(0.98, to_m - from_m), speed], dtype=np.float32))
        if (world.n[-1] - to_m) * math.copysign(1.0, to_m - from_m) >= 0.0:
            break
    return float(world.s[-1]) - s0, n0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--counts", type=int, nargs="+", default=list(range(3, 10)))
    ap.add_argument("--episodes", type=int, default=100)
    ap.add_argument("--reverse-traffic", action="store_true",
                    help="reverse the traffic entries (nearest spot first: the traffic jams)")
    ap.add_argument("--spot-lane", type=float, nargs=2, metavar=("LOW", "HIGH"),
                    help="parking lanes [LOW, HIGH] / [-HIGH, -LOW] (trackPos of the full road) "
                         "instead of the scenario's")
    ap.add_argument("--lane-m", type=float,
                    help="|n| of the lane driven beside a parked car (m; default: clears the "
                         f"innermost spot by {LANE_MARGIN_M} m)")
    args = ap.parse_args()
    base = yaml.safe_load((SCENARIO_DIR / "exp5.yml").read_text())
    if args.reverse_traffic:
        base["traffic"] = base["traffic"][::-1]
    if args.spot_lane:
        low, high = args.spot_lane
        for t in base["traffic"]:
            t["parking_lane"] = [low, high] if t["parking_lane"][0] > 0 else [-high, -low]
    _, _, columns = with_distance_field(base)            # {field: first column}
    limit = float(base["server"]["track_limits"][1])
    half_width_m = 5.0                                                  # Aalborg: 10 m wide
    inner_m = min(min(abs(x) for x in t["parking_lane"]) for t in base["traffic"]) * half_width_m
    lane_m = args.lane_m if args.lane_m is not None else HALF_WIDTHS_M - inner_m + LANE_MARGIN_M
    print(f"parking spots from {inner_m:.2f} m out; lane beside them at +-{lane_m:.2f} m")
    need_m = HALF_WIDTHS_M - inner_m                 # |n| clearing the innermost spot exactly
    for speed in (1.0, 0.5):
        road_m, n0 = lane_change_m(base, speed, -need_m, need_m)
        print(f"T-S lane change from n = {n0:.2f} to {need_m:.2f} m at {speed * 50:.0f} km/h "
              f"(aiming at the road's edge): {road_m:.1f} m of road")
    policy = scripted_policy(columns, half_width_m=half_width_m, limit=limit, lane_m=lane_m)
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
