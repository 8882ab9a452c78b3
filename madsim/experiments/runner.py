"""`madsim experiment run`: train an experiment's sub-runs, evaluate them as the paper does and
write a self-contained result folder.

OUT/
  experiment.json     name, budget, seed, command, package versions, machine, wall times,
                      env steps/s of each sub-run's training, the experiment's notes
  SUBRUN/             one training run folder per sub-run (config.yml as run, run.json with
                      seeds and versions, progress.csv or rllib.csv, checkpoints, policy)
  evaluation.csv      one row per evaluation episode (sub-run, condition, seed, figures)
  results.csv         one row per (sub-run, condition): the means over its episodes
  eval_configs/       each evaluation scenario as run (training scenario + condition)
  table.md, NAME.png  the paper's table with madsim's numbers beside the paper's, and the
                      learning curves (written by madsim.experiments.report)

Single-learner sub-runs train with PPO (stable-baselines3) on the batched vector env; Experiment
6 trains two policies with RLlib on Ray (`address` joins an existing Ray cluster; None starts
Ray locally). Training seed: `seed` for every sub-run; evaluation episode k: seed 1,000,000 + k;
an experiment with `sampled_actions` (exp6) draws its actions with a Generator seeded `seed`.
"""

from __future__ import annotations

import copy
import csv
import dataclasses
import json
import platform
import os
import sys
import time
from pathlib import Path

import yaml

from madsim.experiments.registry import BUDGETS, PAPER_NET, SCENARIO_DIR, Experiment, SubRun, experiment

__all__ = ["load_scenario", "rllib_policies", "run_experiment", "set_path", "subrun_steps"]


def set_path(cfg: dict, dotted: str, value) -> None:
    """Set cfg[a][b]... for "a.b..." (integer parts index lists); value None deletes the key."""
    parts = dotted.split(".")
    node = cfg
    for part in parts[:-1]:
        node = node[int(part)] if isinstance(node, list) else node.setdefault(part, {})
    last = parts[-1]
    if isinstance(node, list):
        node[int(last)] = value
    elif value is None:
        node.pop(last, None)
    else:
        node[last] = value


def load_scenario(sub: SubRun, overrides: dict | None = None) -> dict:
    """The sub-run's scenario (YAML of SCENARIO_DIR) with its overrides, then `overrides`."""
    with open(SCENARIO_DIR / sub.scenario, encoding="utf-8") as f:
        cfg = yaml.safe_load(f)
    for key, value in {**sub.overrides, **(overrides or {})}.items():
        set_path(cfg, key, copy.deepcopy(value))
    return cfg


def subrun_steps(exp: Experiment, sub: SubRun, budget) -> int:
    """Env steps of one sub-run: the budget's steps for the experiment x its share, in whole
    PPO rollouts (num_envs x n_steps)."""
    rollout = budget.num_envs * budget.n_steps
    base = exp.name.split("-")[0]
    return max(rollout, int(round(budget.steps[base] * sub.steps_share / rollout)) * rollout)


def _versions() -> dict:
    import numba
    import numpy

    import madsim

    out = {"python": platform.python_version(), "madsim": madsim.__version__,
           "numpy": numpy.__version__, "numba": numba.__version__}
    for mod in ("torch", "stable_baselines3", "ray", "gymnasium", "pettingzoo"):
        m = sys.modules.get(mod)
        if m is None:
            try:
                m = __import__(mod)
            except ImportError:
                continue
        out[mod] = getattr(m, "__version__", "?")
    return out


def _write_csv(path: Path, rows: list[dict]) -> None:
    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow({k: (";".join(v) if isinstance(v, tuple) else v) for k, v in r.items()})


def _train_sb3(exp, sub, cfg, run_dir: Path, budget, seed: int, log) -> dict:
    from madsim.train.sb3 import TrainSettings, train

    steps = subrun_steps(exp, sub, budget)
    init = str(run_dir.parent / sub.init_from / "policy.zip") if sub.init_from else None
    settings = TrainSettings(steps=steps, num_envs=budget.num_envs, seed=seed,
                             n_steps=budget.n_steps, batch_size=budget.batch_size,
                             n_epochs=budget.n_epochs, learning_rate=budget.lr * sub.lr_factor,
                             net=PAPER_NET, eval_every=max(budget.num_envs * budget.n_steps, steps // 4),
                             eval_episodes=0, progress=False,
                             verbose=False, init_policy=init)
    log(f"{exp.name}/{sub.name}: PPO {steps} env steps, lr {settings.learning_rate:.3g}"
        + (f", from {sub.init_from}" if init else ""))
    record = train(cfg, run_dir, settings, overwrite=True)
    return {"env_steps": record["timesteps"], "train_wall_s": record["wall_s"],
            "steps_per_s": record["steps_per_s"], "learning_rate": settings.learning_rate}


def _train_rllib(exp, sub, cfg, run_dir: Path, budget, seed: int, address, log) -> dict:
    from madsim.train.rllib import train_rllib

    total = budget.rllib_iterations * budget.rllib_batch
    stage2 = int(total * 0.8 / max(1, budget.rllib_runners))   # each runner's env counts its own steps
    set_path(cfg, "curriculum.stages.1.start", max(1, stage2))
    log(f"{exp.name}/{sub.name}: RLlib PPO {budget.rllib_iterations} iterations of "
        f"{budget.rllib_batch} env steps, {budget.rllib_runners} env runners")
    t0 = time.time()
    rows = train_rllib(cfg, run_dir, iterations=budget.rllib_iterations, address=address,
                       checkpoint_every=budget.rllib_iterations,
                       keep_every=budget.rllib_keep_every, log=log, policies="per_agent",
                       num_env_runners=budget.rllib_runners, seed=seed,
                       train_batch_size=budget.rllib_batch, minibatch_size=budget.rllib_minibatch,
                       num_epochs=budget.rllib_epochs, hidden=PAPER_NET, lr=budget.rllib_lr)
    wall = time.time() - t0
    steps = rows[-1]["env_steps"] if rows else 0
    return {"env_steps": steps, "train_wall_s": round(wall, 1),
            "steps_per_s": round(steps / wall, 1) if wall > 0 else None,
            "learning_rate": budget.rllib_lr}


def rllib_policies(run_dir: Path, cfg: dict, checkpoint: str = "checkpoint",
                   rng=None) -> dict:
    """Policies (obs (d,) -> action in [-1, 1]) of the RLModules saved in run_dir/checkpoint
    (or another checkpoint folder of the run, e.g. a kept "checkpoint-0025"): the Gaussian's
    mean (deterministic, rng None), or an action drawn from it with the numpy Generator `rng`
    (as RLlib 0.8's `compute_action` did by default), clipped to [-1, 1]."""
    import numpy as np
    import torch
    from ray.rllib.core.rl_module.rl_module import RLModule

    from madsim.train.threads import torch_threads

    root = run_dir / checkpoint / "learner_group" / "learner" / "rl_module"
    policies = {}
    for agent in cfg["agents"]:
        module = RLModule.from_checkpoint(str((root / agent["name"]).resolve()))
        dim = 2 if agent["action"]["space"] == "TS" else 3

        def act(obs, module=module, dim=dim):
            with torch.no_grad(), torch_threads():     # one thread: see madsim.train.threads
                out = module.forward_inference({"obs": torch.as_tensor(obs[None], dtype=torch.float32)})
            inputs = out["action_dist_inputs"][0].numpy().astype(np.float64)
            action = inputs[:dim]
            if rng is not None:            # DiagGaussian inputs: means, then log standard deviations
                action = action + np.exp(inputs[dim:2 * dim]) * rng.standard_normal(dim)
            return np.clip(action, -1.0, 1.0).astype(np.float32)

        policies[agent["name"]] = act
    return policies


def _train_all(exp: Experiment, budget, out: Path, seed: int, address, log) -> dict:
    """Train every sub-run (a sub-run after the one it starts from); sub-run name -> record.
    With a Ray `address`, single-learner sub-runs train as Ray tasks on that cluster, those
    that do not wait for another at once (`out` must be on a filesystem the nodes share);
    Experiment 6's RLlib run uses the cluster's env runners."""
    if exp.trainer == "rllib":
        return {s.name: _train_rllib(exp, s, load_scenario(s), out / s.name, budget, seed,
                                     address, log) for s in exp.subruns}
    if address is None:
        return {s.name: _train_sb3(exp, s, load_scenario(s), out / s.name, budget, seed, log)
                for s in exp.subruns}
    import ray

    started = not ray.is_initialized()
    if started:
        ray.init(address=address, log_to_driver=True)
    task = ray.remote(num_cpus=1)(_train_sb3)
    done: dict = {}
    try:
        while len(done) < len(exp.subruns):
            wave = [s for s in exp.subruns if s.name not in done
                    and (s.init_from is None or s.init_from in done)]
            futures = [task.remote(exp, s, load_scenario(s), out.resolve() / s.name, budget, seed, print)
                       for s in wave]
            done.update(zip([s.name for s in wave], ray.get(futures)))
    finally:
        if started:
            ray.shutdown()
    return done


def run_experiment(name: str, *, budget: str = "smoke", out, seed: int = 0,
                   address: str | None = None, log=print) -> dict:
    """Run experiment `name` (exp1..exp6 or a sub-run selection like exp1-sab) at `budget`
    into folder `out`; returns the experiment record (experiment.json)."""
    from madsim.experiments.evaluate import evaluate_pair, evaluate_single
    from madsim.experiments.report import write_report

    exp = experiment(name)
    if budget not in BUDGETS:
        raise ValueError(f"unknown budget {budget!r}; one of {', '.join(BUDGETS)}")
    b = BUDGETS[budget]
    out = Path(out)
    (out / "eval_configs").mkdir(parents=True, exist_ok=True)
    t0 = time.time()
    hash_seed = os.environ.get("PYTHONHASHSEED")
    fixed = exp.trainer == "rllib" and hash_seed not in (None, "random")
    prefix = f"PYTHONHASHSEED={hash_seed} " if fixed else ""
    if exp.trainer == "rllib" and not prefix:
        log(f"{exp.name}: RLlib's training depends on Python's string hash seed; to reproduce "
            f"this run to the digit, run it with PYTHONHASHSEED=0")
    record = {"experiment": exp.name, "title": exp.title, "budget": dataclasses.asdict(b),
              "seed": seed, "command": f"{prefix}madsim experiment run {name} --budget {budget} "
                                       f"--seed {seed} --out {out}",
              "address": address, "notes": list(exp.notes), "subruns": {},
              "evaluation": {"episodes": b.eval_episodes, "seeds": "1000000 + k",
                             "max_ticks": b.eval_max_ticks,
                             "actions": (f"sampled (numpy Generator seeded {seed})"
                                         if exp.sampled_actions else "deterministic")},
              "started_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    conditions = {c.name: c for c in exp.conditions}
    wanted = exp.evaluations()
    episodes, results = [], []
    trained = _train_all(exp, b, out, seed, address, log)
    for sub in exp.subruns:
        cfg = load_scenario(sub)
        run_dir = out / sub.name
        info = trained[sub.name]
        evals = [c for s, c in wanted if s == sub.name] if sub.evaluate else []
        if evals:
            if exp.trainer == "rllib":
                import numpy as np

                rng = np.random.default_rng(seed) if exp.sampled_actions else None
                policies = rllib_policies(run_dir, cfg, rng=rng)
            else:
                from madsim.train.sb3 import load_policy

                policy = load_policy(run_dir / "policy.zip")
        t_eval = time.time()
        for cond in evals:
            ecfg = load_scenario(sub, conditions[cond].overrides)
            if exp.trainer == "rllib":
                summary, per = evaluate_pair(policies, ecfg, episodes=b.eval_episodes,
                                             max_ticks=b.eval_max_ticks)
            else:
                summary, per = evaluate_single(policy, ecfg, episodes=b.eval_episodes,
                                               max_ticks=b.eval_max_ticks)
            stem = f"{sub.name}__{cond}".replace(" ", "_")
            (out / "eval_configs" / f"{stem}.yml").write_text(
                yaml.safe_dump(ecfg, sort_keys=False), encoding="utf-8")
            results.append({"subrun": sub.name, "condition": cond, **summary})
            episodes += [{"subrun": sub.name, "condition": cond, **e} for e in per]
            log(f"{exp.name}/{sub.name} [{cond}]: " + ", ".join(
                f"{k} {v:.3f}" for k, v in summary.items() if isinstance(v, float)))
        info.update(eval_wall_s=round(time.time() - t_eval, 1))
        record["subruns"][sub.name] = info
    _write_csv(out / "evaluation.csv", episodes)
    _write_csv(out / "results.csv", results)
    record.update(wall_s=round(time.time() - t0, 1), versions=_versions(),
                  machine={"cpus": _cpus(), "platform": platform.platform(), "load": _load()})
    (out / "experiment.json").write_text(json.dumps(record, indent=2), encoding="utf-8")
    write_report(out)
    return record


def _cpus() -> int:
    import os

    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()


def _load() -> list[float] | None:
    import os

    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None
