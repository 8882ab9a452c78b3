"""`madsim train`: PPO (stable-baselines3) on a single-learner scenario, and `load_policy`.

A run writes into its folder DIR:
  config.yml          the fully resolved scenario config (every default filled in)
  run.json            settings, versions, seed, wall time, final evaluation
  progress.csv        SB3's training log (rollout/ep_rew_mean, train/loss, ... per rollout)
  eval.csv            periodic evaluation: timesteps, wall_s, lap_fraction, avg_speed_kmh,
                      completion_rate, mean_return, mean_steps (see madsim.train.evaluate)
  checkpoints/        step_<timesteps>.zip at every evaluation
  best_policy.zip     the checkpoint with the best (completion rate, lap fraction, speed)
  policy.zip          the final policy: `load_policy(DIR / "policy.zip")`
  tb/                 tensorboard events, when tensorboard is installed

Needs the `train` extra (torch 2.13.0 CPU, stable-baselines3); importing this module without
it raises TrainError naming the extra.
"""

from __future__ import annotations

import csv
import dataclasses
import importlib.util
import json
import pickle
import platform
import time
import warnings
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from madsim.train.evaluate import EVAL_FIELDS, evaluate_policy, format_table
from madsim.train.threads import TRAINING_THREADS, torch_threads

__all__ = ["Policy", "TrainError", "TrainSettings", "load_policy", "train"]


class TrainError(ValueError):
    """A training run cannot start (missing extra, bad settings, occupied run folder); a
    ValueError so the CLI prints it as one line."""


def _require_sb3():
    try:
        import stable_baselines3
        import torch
    except ImportError as exc:
        raise TrainError(f"training needs the 'train' extra (torch 2.13.0 CPU and "
                         f"stable-baselines3): pip install 'madsim[train]' ({exc})") from None
    return stable_baselines3, torch


@dataclass(frozen=True, kw_only=True)
class TrainSettings:
    """One PPO run. Steps count env steps over all envs (one T-S step is pid.latency ticks).

    n_steps: rollout length per env (default 2048 // num_envs, at least 64); eval_every:
    timesteps between evaluations (default steps // 10, at least one rollout; evaluations
    happen between rollouts, and once more at the end); eval_episodes
    seeded deterministic episodes per evaluation (seeds 1,000,000 + k; 0: no evaluation,
    checkpoints only); normalize_reward:
    scale rewards by a running return std during training (the saved policy is unaffected);
    torch_threads: torch's intra-op threads. 1 by default: the networks are tiny, and on a
    busy 2-core machine two threads made PPO's update 4x slower (measured: 2,048 steps in
    20.8 s with 2 threads, 5.3 s with 1).
    """

    algo: str = "ppo"
    steps: int
    num_envs: int = 1
    seed: int = 0
    n_steps: int | None = None
    batch_size: int = 256
    n_epochs: int = 10
    learning_rate: float = 3e-4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    ent_coef: float = 0.0
    net: tuple[int, ...] = (64, 64)
    normalize_reward: bool = True
    eval_every: int | None = None
    eval_episodes: int = 3
    progress: bool = True
    native_vec: bool | None = None
    torch_threads: int = TRAINING_THREADS
    verbose: bool = True
    init_policy: str | None = None     # a policy.zip whose weights the run starts from

    def __post_init__(self):
        if self.algo != "ppo":
            raise TrainError(f"algo must be 'ppo' (the only algorithm wired so far), got {self.algo!r}")
        for name in ("steps", "num_envs", "batch_size", "n_epochs", "torch_threads"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise TrainError(f"{name} must be an int >= 1, got {v!r}")
        if isinstance(self.eval_episodes, bool) or not isinstance(self.eval_episodes, int) \
                or self.eval_episodes < 0:
            raise TrainError(f"eval_episodes must be an int >= 0, got {self.eval_episodes!r}")
        for name in ("n_steps", "eval_every"):
            v = getattr(self, name)
            if v is not None and (isinstance(v, bool) or not isinstance(v, int) or v < 1):
                raise TrainError(f"{name} must be an int >= 1 or None, got {v!r}")
        if not 0.0 < self.gamma <= 1.0 or not 0.0 <= self.gae_lambda <= 1.0:
            raise TrainError(f"need 0 < gamma <= 1 and 0 <= gae_lambda <= 1, got "
                             f"{self.gamma}, {self.gae_lambda}")
        if not self.learning_rate > 0:
            raise TrainError(f"learning_rate must be > 0, got {self.learning_rate}")

    @property
    def rollout_steps_per_env(self) -> int:
        return self.n_steps if self.n_steps is not None else max(64, 2048 // self.num_envs)

    @property
    def eval_interval(self) -> int:
        rollout = self.rollout_steps_per_env * self.num_envs
        return self.eval_every if self.eval_every is not None else max(rollout, self.steps // 10)


class Policy:
    """A trained policy as a plain function: `policy(obs) -> action` (deterministic).

    obs: (obs_dim,) or (batch, obs_dim) float32; action: (act_dim,) or (batch, act_dim),
    inside the action Box. `model` is the stable-baselines3 algorithm object."""

    def __init__(self, model):
        self.model = model
        self.observation_space = model.observation_space
        self.action_space = model.action_space

    def __call__(self, obs) -> np.ndarray:
        with torch_threads():          # one thread: see madsim.train.threads
            action, _ = self.model.predict(np.asarray(obs, dtype=np.float32), deterministic=True)
        return action


def load_policy(path) -> Policy:
    """The policy saved by `madsim train` (a DIR/policy.zip, or the run folder DIR itself)."""
    _require_sb3()
    from stable_baselines3 import PPO

    p = Path(path)
    if p.is_dir():
        p = p / "policy.zip"
    if not p.is_file():
        raise FileNotFoundError(f"no policy file at {p}")
    try:
        model = PPO.load(str(p), device="cpu")
    except (ValueError, KeyError, EOFError, RuntimeError, AttributeError, AssertionError,
            zipfile.BadZipFile, pickle.UnpicklingError) as exc:     # what SB3's loader raises
        raise TrainError(f"{p}: not a policy saved by madsim train ({type(exc).__name__}: {exc})") from None
    return Policy(model)


# --- callbacks ------------------------------------------------------------------------------


class _Stopped(Exception):
    """Raised inside an evaluation when a stop was requested (leaves it at once)."""


def _callbacks(run_dir: Path, cfg, settings: TrainSettings, t0: float, stop):
    from stable_baselines3.common.callbacks import BaseCallback
    from tqdm import tqdm

    class Periodic(BaseCallback):
        """Evaluation, checkpoints, eval.csv, best policy, progress bar, curriculum progress."""

        def __init__(self):
            super().__init__()
            self.next_eval = 0
            self.rows: list[dict] = []
            self.best = None
            self.bar = None
            self.shown = 0
            self.episodes = 0
            self.eval_env = None
            self.curriculum_warned = False

        def _on_training_start(self) -> None:
            from madsim.envs.madras_env import MadrasEnv

            self.eval_env = MadrasEnv(cfg)
            if settings.progress:
                self.bar = tqdm(total=settings.steps, unit="step", desc="madsim train",
                                dynamic_ncols=True, smoothing=0.05)
            self.evaluate()

        def evaluate(self) -> None:
            if settings.eval_episodes == 0:          # checkpoints only (the caller evaluates)
                self.model.save(run_dir / "checkpoints" / f"step_{self.num_timesteps:09d}.zip")
                self.next_eval = self.num_timesteps + settings.eval_interval
                return
            policy = Policy(self.model)

            def guarded(obs):
                if stop:
                    raise _Stopped
                return policy(obs)
            try:
                summary, _ = evaluate_policy(guarded, cfg, episodes=settings.eval_episodes,
                                             env=self.eval_env)
            except _Stopped:   # interrupted: no row for a half-done evaluation
                return
            row = {"timesteps": int(self.num_timesteps), "wall_s": round(time.time() - t0, 2),
                   **{k: summary[k] for k in EVAL_FIELDS}}
            self.rows.append(row)
            with open(run_dir / "eval.csv", "a", newline="") as f:
                w = csv.DictWriter(f, fieldnames=list(row))
                if f.tell() == 0:
                    w.writeheader()
                w.writerow(row)
            for key in EVAL_FIELDS:
                self.logger.record(f"eval/{key}", row[key])
            self.model.save(run_dir / "checkpoints" / f"step_{self.num_timesteps:09d}.zip")
            score = (row["completion_rate"], row["lap_fraction"], row["avg_speed_kmh"])
            if self.best is None or score > self.best:
                self.best = score
                self.model.save(run_dir / "best_policy.zip")
            line = format_table([row]).splitlines()[1]
            if self.bar is not None:
                self.bar.set_postfix(lap=f"{row['lap_fraction']:.2f}",
                                     done=f"{row['completion_rate']:.2f}",
                                     kmh=f"{row['avg_speed_kmh']:.0f}")
                self.bar.write(line)
            elif settings.verbose:
                print(line, flush=True)
            self.next_eval = self.num_timesteps + settings.eval_interval

        def _on_step(self) -> bool:
            if self.bar is not None:
                self.bar.update(self.num_timesteps - self.shown)
                self.shown = self.num_timesteps
            dones = self.locals.get("dones")
            if dones is not None:
                self.episodes += int(np.sum(dones))
            return not stop

        def _on_rollout_start(self) -> None:
            # here the weights are those after the update on the previous rollout, so an
            # evaluation row and its checkpoint describe the same network
            if self.num_timesteps >= self.next_eval:
                self.evaluate()

        def _on_rollout_end(self) -> None:
            self._curriculum()

        def _curriculum(self) -> None:
            """Count curriculum progress over all envs (each env alone sees 1/N of it)."""
            cur = cfg.curriculum
            if cur is None:
                return
            total = self.num_timesteps if cur.unit == "steps" else self.episodes
            try:
                self.training_env.set_attr("curriculum_progress", int(total))
            except (AttributeError, NotImplementedError) as exc:
                if not self.curriculum_warned:
                    warnings.warn(f"this vector env cannot take the curriculum progress "
                                  f"({exc}); each env counts its own", stacklevel=1)
                    self.curriculum_warned = True

        def _on_training_end(self) -> None:
            if not stop and self.rows and self.rows[-1]["timesteps"] != self.num_timesteps:
                self.evaluate()
            if self.bar is not None:
                self.bar.close()
            self.eval_env.close()

    return Periodic()


# --- the run ----------------------------------------------------------------------------------


def _prepare_dir(out_dir, overwrite: bool) -> Path:
    run_dir = Path(out_dir)
    if (run_dir / "run.json").exists() and not overwrite:
        raise TrainError(f"{run_dir} already holds a training run (run.json); choose another "
                         f"--out or pass --overwrite")
    if run_dir.exists() and not run_dir.is_dir():
        raise TrainError(f"--out {run_dir} exists and is not a folder")
    (run_dir / "checkpoints").mkdir(parents=True, exist_ok=True)
    for stale in ("eval.csv", "progress.csv", "policy.zip", "best_policy.zip"):
        (run_dir / stale).unlink(missing_ok=True)
    for stale in (run_dir / "checkpoints").glob("step_*.zip"):
        stale.unlink()
    return run_dir


def train(config, out_dir, settings: TrainSettings, *, overwrite: bool = False, stop=None) -> dict:
    """Train PPO on `config` (path, mapping or ScenarioConfig; one learning agent) and write
    the run folder `out_dir` (see the module docstring). Returns the run record (run.json).
    stop: anything whose truth ends training early (a `madsim.interrupts.StopRequest`): the
    policy so far is saved and the record says `interrupted`."""
    stop = False if stop is None else stop
    sb3, torch = _require_sb3()
    import yaml
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from madsim.envs.config import ScenarioConfig, config_to_dict, load_config
    from madsim.train.vec import make_training_env, native_make_vec

    cfg = config if isinstance(config, ScenarioConfig) else load_config(config)
    if len(cfg.agents) != 1:
        raise TrainError(f"madsim train drives one learning car; this config has "
                         f"{len(cfg.agents)} ({', '.join(cfg.agent_names)}): use madsim.train.rllib "
                         f"for several")
    run_dir = _prepare_dir(out_dir, overwrite)
    (run_dir / "config.yml").write_text(
        yaml.safe_dump(config_to_dict(cfg), sort_keys=False, default_flow_style=None, width=100),
        encoding="utf-8")
    torch.set_num_threads(settings.torch_threads)
    torch.manual_seed(settings.seed)
    venv = make_training_env(cfg, settings.num_envs, seed=settings.seed, native=settings.native_vec)
    if settings.normalize_reward:
        venv = VecNormalize(venv, norm_obs=False, norm_reward=True, gamma=settings.gamma)
    n_steps = settings.rollout_steps_per_env
    batch = min(settings.batch_size, n_steps * settings.num_envs)
    model = PPO("MlpPolicy", venv, n_steps=n_steps, batch_size=batch, n_epochs=settings.n_epochs,
                learning_rate=settings.learning_rate, gamma=settings.gamma,
                gae_lambda=settings.gae_lambda, ent_coef=settings.ent_coef,
                policy_kwargs={"net_arch": list(settings.net)}, seed=settings.seed,
                device="cpu", verbose=0)
    if settings.init_policy is not None:         # fine-tuning (a curriculum's second phase)
        model.policy.load_state_dict(load_policy(settings.init_policy).model.policy.state_dict())
    with_tb = importlib.util.find_spec("tensorboard") is not None
    model.set_logger(_logger(run_dir, with_tb))
    record = {
        "algo": settings.algo, "config_source": None if not isinstance(config, (str, Path)) else str(config),
        "settings": {k: (list(v) if isinstance(v, tuple) else v)
                     for k, v in dataclasses.asdict(settings).items()},
        "vector_env": "madsim.make_vec" if (settings.native_vec is not False and native_make_vec())
        else "gymnasium.SyncVectorEnv(MadrasEnv)",
        "versions": {"python": platform.python_version(), "torch": torch.__version__,
                     "stable_baselines3": sb3.__version__, "madsim": _madsim_version()},
        "machine": {"cpus": _cpus(), "platform": platform.platform()},
        "tensorboard": with_tb,
    }
    t0 = time.time()
    periodic = _callbacks(run_dir, cfg, settings, t0, stop)
    try:
        model.learn(total_timesteps=settings.steps, callback=periodic)
    except KeyboardInterrupt:
        if not stop:     # a stop request's grace ran out (the step was held up): save what there is
            raise
    finally:
        if stop:
            stop.settle()
        venv.close()
        model.logger.close()          # progress.csv complete on disk, whatever comes next
    wall = time.time() - t0
    model.save(run_dir / "policy.zip")
    record.update(timesteps=int(model.num_timesteps), wall_s=round(wall, 1),
                  steps_per_s=round(model.num_timesteps / wall, 1),
                  final_eval=periodic.rows[-1] if periodic.rows else None, evaluations=len(periodic.rows))
    if stop:
        record["interrupted"] = getattr(stop, "signal_name", "stop")
    (run_dir / "run.json").write_text(json.dumps(record, indent=2), encoding="utf-8")
    return record


def _logger(run_dir: Path, with_tb: bool):
    """SB3 logger writing progress.csv into run_dir (and tensorboard events into run_dir/tb)."""
    from stable_baselines3.common.logger import Logger, make_output_format

    outputs = [make_output_format("csv", str(run_dir))]
    if with_tb:
        outputs.append(make_output_format("tensorboard", str(run_dir / "tb")))
    return Logger(folder=str(run_dir), output_formats=outputs)


def _madsim_version() -> str:
    import madsim

    return madsim.__version__


def _cpus() -> int:
    import os

    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
