"""Evaluation as the paper does it, over many episodes at once.

Single-learner policies are evaluated on `madsim.make_vec` with one slot per episode
(episode k reset with seed `seed + k`, deterministic actions). The fraction of the lap
covered needs distRaced, which the policy does not observe: the evaluation scenario is the
training scenario with `distRaced` appended to the observation's field list (mode Fields),
and the policy is fed the observation without that column - every other value is computed
exactly as in training. Two-learner policies (Experiment 6) are evaluated the same way on
`MadrasParallelEnv`, one episode after the other.

Per-episode figures are those of `madsim.train.evaluate.trajectory_metrics` (lap fraction,
mean of hypot(speedX, speedY) in km/h, completion, return, steps) plus `dones` and
`success` (exp5: Rank1 without Collision).
"""

from __future__ import annotations

import copy
from collections.abc import Callable

import numpy as np

from madsim.agents.observations import FIELD_SCALE, FIELD_WIDTH
from madsim.train.evaluate import summarise, trajectory_metrics

__all__ = ["evaluate_pair", "evaluate_single", "with_distance_field"]

EVAL_SEED = 1_000_000          # evaluation episode k: seed EVAL_SEED + k (as madsim.train.evaluate)
PASS_MARGIN_M = 5.0            # exp6: a learner has passed 5 m beyond the farthest parking spot


def with_distance_field(cfg: dict, agent: int = 0) -> tuple[dict, int, dict]:
    """(scenario with distRaced appended to agent's Fields, its column, {field: column})."""
    out = copy.deepcopy(cfg)
    obs = out["agents"][agent]["observation"]
    if obs.get("mode") != "Fields":
        raise ValueError("experiment scenarios observe through mode Fields (the paper's lists)")
    fields = list(obs["fields"])
    columns, col = {}, 0
    for name in fields:
        columns[name] = col
        col += FIELD_WIDTH[name]
    obs["fields"] = fields + ["distRaced"]
    return out, col, columns


def _speed_kmh(obs: np.ndarray, columns: dict, name: str) -> np.ndarray:
    return obs[:, columns[name]] / FIELD_SCALE[name]


def evaluate_single(policy: Callable[[np.ndarray], np.ndarray], cfg: dict, *, episodes: int = 100,
                    seed: int = EVAL_SEED, max_ticks: int | None = None) -> tuple[dict, list[dict]]:
    """Evaluate a one-learner policy (batch obs (n, d) -> actions (n, a)) on scenario `cfg` (a
    dict as loaded from YAML) over `episodes` episodes side by side; max_ticks cuts episodes
    (server.max_steps). Returns (summary with success_rate, per-episode figures)."""
    import madsim

    ecfg, dcol, columns = with_distance_field(cfg)
    if max_ticks is not None:
        ecfg["server"]["max_steps"] = int(max_ticks)
    venv = madsim.make_vec(ecfg, num_envs=int(episodes), autoreset_mode="NextStep")
    try:
        obs, infos = venv.reset(seed=int(seed))
        length = np.asarray(infos["track_length"], dtype=np.float64)
        laps = int(venv.config.server.laps)
        n = int(episodes)
        live = np.ones(n, dtype=bool)
        dist, vx, vy, rew = ([[] for _ in range(n)] for _ in range(4))
        ticks = np.zeros(n, dtype=np.int64)
        fired: list[tuple] = [()] * n
        while live.any():
            obs, rewards, terminated, truncated, infos = venv.step(policy(np.delete(obs, dcol, axis=1)))
            sx, sy = _speed_kmh(obs, columns, "speedX"), _speed_kmh(obs, columns, "speedY")
            step_ticks = infos.get("ticks")
            for e in np.flatnonzero(live).tolist():
                dist[e].append(float(obs[e, dcol]))
                vx[e].append(float(sx[e]))
                vy[e].append(float(sy[e]))
                rew[e].append(float(rewards[e]))
                ticks[e] += int(step_ticks[e]) if step_ticks is not None else 1
                if terminated[e] or truncated[e]:
                    live[e] = False
                    fired[e] = tuple(infos["dones"][e])
    finally:
        venv.close()
    per = []
    for e in range(n):
        m = trajectory_metrics(dist[e], vx[e], vy[e], rew[e], track_length_m=float(length[e]),
                               laps=laps, ticks=int(ticks[e]), dones=fired[e])
        m.update(seed=int(seed) + e, dones=fired[e],
                 success="Rank1" in fired[e] and "Collision" not in fired[e])
        per.append(m)
    return _summary(per), per


def _summary(per: list[dict]) -> dict:
    out = summarise(per)
    out["success_rate"] = float(np.mean([1.0 if e["success"] else 0.0 for e in per]))
    return out


def evaluate_pair(policies: dict, cfg: dict, *, episodes: int = 100, seed: int = EVAL_SEED,
                  max_ticks: int | None = None) -> tuple[dict, list[dict]]:
    """Evaluate learners of a MadrasParallelEnv scenario, `policies[agent](obs (d,)) -> action`,
    over `episodes` episodes (seeds seed + k). Joint success: every learner got PASS_MARGIN_M
    beyond the farthest parking spot (traffic initial_distance high) with no Collision done
    before the last of them passed. Summary: joint_success_rate, and per agent the lap
    fraction, speed and return means."""
    from madsim.envs.parallel_env import MadrasParallelEnv

    ecfg = copy.deepcopy(cfg)
    names = [a["name"] for a in ecfg["agents"]]
    cols = {}
    for i, name in enumerate(names):
        ecfg, cols[name], columns = with_distance_field(ecfg, i)
    if max_ticks is not None:
        ecfg["server"]["max_steps"] = int(max_ticks)
    farthest_m = max(float(t["initial_distance"][1]) for t in ecfg.get("traffic", []))
    env = MadrasParallelEnv(ecfg)
    per = []
    try:
        for k in range(int(episodes)):
            obs, infos = env.reset(seed=int(seed) + k)
            length = float(infos[names[0]]["track_length"])
            # signed distance from each car's start to the line (the grid is behind it)
            start_gap = {a: (length - infos[a]["placement"][0]) % length for a in names}
            start_gap = {a: g - length if g > length / 2 else g for a, g in start_gap.items()}
            rec = {a: {"d": [], "vx": [], "vy": [], "r": [], "dones": (), "passed": None,
                       "end": None} for a in names}
            step = 0
            while env.agents:
                actions = {a: policies[a](np.delete(obs[a], cols[a])) for a in env.agents}
                obs, rewards, terminated, truncated, infos = env.step(actions)
                step += 1
                for a in list(obs):
                    r = rec[a]
                    if r["end"] is not None:
                        continue
                    d = float(obs[a][cols[a]])
                    r["d"].append(d)
                    r["vx"].append(float(obs[a][columns["speedX"]] / FIELD_SCALE["speedX"]))
                    r["vy"].append(float(obs[a][columns["speedY"]] / FIELD_SCALE["speedY"]))
                    r["r"].append(float(rewards[a]))
                    if r["passed"] is None and d >= start_gap[a] + farthest_m + PASS_MARGIN_M:
                        r["passed"] = step
                    if terminated.get(a) or truncated.get(a):
                        r["end"] = step
                        r["dones"] = tuple(infos[a].get("dones", ()))
            last_pass = max((rec[a]["passed"] or 10**9) for a in names)
            crashed = any("Collision" in rec[a]["dones"] and rec[a]["end"] <= last_pass for a in names)
            joint = all(rec[a]["passed"] is not None for a in names) and not crashed
            ep = {"seed": int(seed) + k, "joint_success": joint}
            for a in names:
                r = rec[a]
                m = trajectory_metrics(r["d"], r["vx"], r["vy"], r["r"], track_length_m=length,
                                       dones=r["dones"])
                ep.update({f"{a}_{key}": m[key] for key in ("lap_fraction", "avg_speed_kmh",
                                                             "return", "steps")})
                ep[f"{a}_passed"] = r["passed"] is not None
                ep[f"{a}_dones"] = r["dones"]
            per.append(ep)
    finally:
        env.close()
    summary = {"joint_success_rate": float(np.mean([e["joint_success"] for e in per])),
               "episodes": len(per)}
    for a in names:
        for key in ("lap_fraction", "avg_speed_kmh", "return"):
            summary[f"{a}_{key}"] = float(np.mean([e[f"{a}_{key}"] for e in per]))
        summary[f"{a}_pass_rate"] = float(np.mean([e[f"{a}_passed"] for e in per]))
    return summary, per
