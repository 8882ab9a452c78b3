"""Evaluation of a driving policy with the figures MADRaS reports.

MADRaS's evaluation helpers (spec madras-features.md, section 10) score an episode by the
fraction of the track covered, the average speed, the return and whether the race was
completed (distRaced >= laps x track length). Here:

- `trajectory_metrics` turns one recorded episode (per-step distRaced, speeds, rewards) into
  those figures; it is pure arithmetic, so it is tested on hand-made trajectories.
- `run_episode` drives one `MadrasEnv` episode with a policy and records that trajectory.
- `evaluate_policy` runs several seeded episodes and `summarise` averages them.

Definitions (one episode, one learning car, `laps` laps of a track of length L metres):
  lap_fraction  = min(1, max(0, d_end) / (laps L)), d_end the final distRaced (m);
  completed     = d_end >= laps L, or a LapCompleted/RaceOver done fired;
  avg_speed_kmh = mean over the episode's steps of sqrt(speedX^2 + speedY^2) (km/h), as
                  MADRaS's helper averages the observed planar speed;
  return        = sum of the step rewards; steps = env steps; sim_time_s = ticks x 0.02 s.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

__all__ = ["EVAL_FIELDS", "evaluate_policy", "format_table", "run_episode", "summarise",
           "trajectory_metrics"]

TICK_S = 0.02
EVAL_FIELDS = ("lap_fraction", "avg_speed_kmh", "completion_rate", "mean_return", "mean_steps")
_COMPLETING_DONES = frozenset({"LapCompleted", "RaceOver"})


def trajectory_metrics(dist_raced_m: Sequence[float], speed_x_kmh: Sequence[float],
                       speed_y_kmh: Sequence[float], rewards: Sequence[float], *,
                       track_length_m: float, laps: int = 1, ticks: int | None = None,
                       dones: Sequence[str] = ()) -> dict:
    """Figures of one episode from its per-step records (arrays of equal length T >= 1:
    distRaced in m after each step, speedX and speedY in km/h after each step, rewards).
    `ticks`: 0.02 s ticks simulated (default T); `dones`: names of the dones that ended it."""
    d = np.asarray(dist_raced_m, dtype=np.float64)
    vx = np.asarray(speed_x_kmh, dtype=np.float64)
    vy = np.asarray(speed_y_kmh, dtype=np.float64)
    r = np.asarray(rewards, dtype=np.float64)
    if d.ndim != 1 or d.size == 0 or not (d.shape == vx.shape == vy.shape == r.shape):
        raise ValueError(f"trajectory arrays must be 1-D, non-empty and of equal length, got "
                         f"shapes {d.shape}, {vx.shape}, {vy.shape}, {r.shape}")
    if not track_length_m > 0:
        raise ValueError(f"track_length_m must be > 0, got {track_length_m}")
    if isinstance(laps, bool) or int(laps) != laps or laps < 1:
        raise ValueError(f"laps must be an int >= 1, got {laps!r}")
    race_m = laps * float(track_length_m)
    d_end = float(d[-1])
    completed = d_end >= race_m or bool(_COMPLETING_DONES.intersection(dones))
    ticks = int(d.size if ticks is None else ticks)
    return {
        "lap_fraction": min(1.0, max(0.0, d_end) / race_m),
        "completed": completed,
        "avg_speed_kmh": float(np.mean(np.hypot(vx, vy))),
        "return": float(r.sum()),
        "steps": int(d.size),
        "sim_time_s": ticks * TICK_S,
        "distance_m": d_end,
    }


def summarise(episodes: Sequence[dict]) -> dict:
    """Mean figures over episodes (dicts of `trajectory_metrics`): lap_fraction,
    avg_speed_kmh, completion_rate (fraction completed), mean_return, mean_steps, episodes."""
    if not episodes:
        raise ValueError("summarise needs at least one episode")
    return {
        "lap_fraction": float(np.mean([e["lap_fraction"] for e in episodes])),
        "avg_speed_kmh": float(np.mean([e["avg_speed_kmh"] for e in episodes])),
        "completion_rate": float(np.mean([1.0 if e["completed"] else 0.0 for e in episodes])),
        "mean_return": float(np.mean([e["return"] for e in episodes])),
        "mean_steps": float(np.mean([e["steps"] for e in episodes])),
        "episodes": len(episodes),
    }


def _agent_row(env):
    """The learning car's SCR sensors after the last step (a read-only mapping)."""
    core = env.unwrapped.core
    return core.rows[core.agent_rows[env.unwrapped.agent]]


def run_episode(env, policy: Callable[[np.ndarray], np.ndarray], seed: int,
                max_steps: int | None = None) -> dict:
    """Drive one episode of a MadrasEnv (`env`) from `reset(seed=seed)` with `policy(obs) ->
    action` and return its `trajectory_metrics` (plus `seed`, `dones`). `max_steps` cuts the
    episode short (None: until it ends by itself)."""
    obs, info = env.reset(seed=int(seed))
    track_length = float(info["track_length"])
    laps = int(env.unwrapped.config.server.laps)
    dist, vx, vy, rewards = [], [], [], []
    ticks, fired = 0, ()
    while max_steps is None or len(rewards) < max_steps:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        row = _agent_row(env)
        dist.append(row["distRaced"])
        vx.append(row["speedX"])
        vy.append(row["speedY"])
        rewards.append(reward)
        ticks += int(info.get("ticks", 1))
        if terminated or truncated:
            fired = tuple(info.get("dones", ()))
            break
    out = trajectory_metrics(dist, vx, vy, rewards, track_length_m=track_length, laps=laps,
                             ticks=ticks, dones=fired)
    out.update(seed=int(seed), dones=fired)
    return out


def evaluate_policy(policy: Callable[[np.ndarray], np.ndarray], config, *, episodes: int = 3,
                    seed: int = 1_000_000, env=None) -> tuple[dict, list[dict]]:
    """Run `episodes` episodes of `config` (a single-learner scenario) with seeds seed,
    seed + 1, ... and return (summary, per-episode figures). `env`: reuse this MadrasEnv
    instead of building one from `config` (it is not closed)."""
    if isinstance(episodes, bool) or int(episodes) != episodes or episodes < 1:
        raise ValueError(f"episodes must be an int >= 1, got {episodes!r}")
    own = env is None
    if own:
        from madsim.envs.madras_env import MadrasEnv

        env = MadrasEnv(config)
    try:
        per_episode = [run_episode(env, policy, seed + k) for k in range(int(episodes))]
    finally:
        if own:
            env.close()
    return summarise(per_episode), per_episode


def format_table(rows: Sequence[dict]) -> str:
    """A plain-text table of evaluation rows (dicts with `timesteps` and EVAL_FIELDS)."""
    head = f"{'timesteps':>10s} {'lap frac':>8s} {'km/h':>7s} {'laps done':>9s} {'return':>9s} {'steps':>7s}"
    lines = [head]
    for r in rows:
        lines.append(f"{int(r['timesteps']):>10d} {r['lap_fraction']:8.3f} {r['avg_speed_kmh']:7.1f} "
                     f"{r['completion_rate']:9.2f} {r['mean_return']:9.1f} {r['mean_steps']:7.0f}")
    return "\n".join(lines)
