"""Gymnasium wrappers for madsim envs."""

from __future__ import annotations

import gymnasium


class CurriculumWrapper(gymnasium.Wrapper):
    """Moves a MadrasEnv through its YAML curriculum from training code.

    The env counts curriculum progress itself (episodes or steps, the curriculum's `unit`); a
    training callback can instead set it from the learner's own count, e.g. with
    stable-baselines3: `vec_env.env_method("set_progress", model.num_timesteps)`. A new stage
    takes effect at the next reset. Reset and step infos carry `curriculum_stage` and
    `curriculum_progress`.
    """

    def __init__(self, env: gymnasium.Env):
        if not hasattr(env.unwrapped, "curriculum_progress"):
            raise TypeError("CurriculumWrapper needs a madsim env (MadrasEnv)")
        super().__init__(env)

    @property
    def progress(self) -> int:
        return int(self.env.unwrapped.curriculum_progress)

    def set_progress(self, value: int) -> None:
        """Set progress (episodes or steps, the curriculum's unit); applies at the next reset."""
        if isinstance(value, bool) or int(value) != value or value < 0:
            raise ValueError(f"curriculum progress must be an int >= 0, got {value!r}")
        self.env.unwrapped.curriculum_progress = int(value)

    def advance(self, amount: int = 1) -> None:
        """Add `amount` to the progress."""
        self.set_progress(self.progress + int(amount))

    @property
    def stage(self) -> int:
        """Index of the stage in force at the current progress (0 without a curriculum)."""
        return int(self.env.unwrapped.core.stage_index())

    def _tag(self, info: dict) -> dict:
        info["curriculum_stage"] = self.stage
        info["curriculum_progress"] = self.progress
        return info

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        return obs, self._tag(info)

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        return obs, reward, terminated, truncated, self._tag(info)
