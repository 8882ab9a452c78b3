"""Reward and penalty components of MADRaS, registered by name (spec madras-features.md s. 7).

Every component is a small object: `reset()` at the start of an episode, then one call per
tick, `value = component(prev, cur, action, info)`, where
  prev, cur: one car's SCR sensor rows (mappings with SCR names and units: `distRaced` m,
             `angle` rad, `damage`, `racePos`, ...) before and after the tick;
  action:    the controls applied during the tick (not used by the built-in components);
  info:      per-tick facts from the env: `track_length` (m, this episode's track) and,
             optionally, `collision` (bool: the car touched a car or a barrier this tick).
A component of kind "reward" returns r, one of kind "penalty" returns p >= 0. `RewardSet` weighs
them as the paper does: total = sum_r w_r r - sum_p w_p p, and reports each weighted term.

Differences from the original, all bug fixes (spec section 11, item 17): Progress takes the
distance of the tick from the two rows; AvgSpeed pays once per completed lap, with that lap's
average; the collision penalty compares damage with the previous tick (and takes the env's
contact flag); Task pays once per episode; the angular-acceleration history starts from the
first observation and angle differences are wrapped to (-pi, pi]; SuccessfulOvertake pays
positions gained beyond the best position of the episode (so losing and regaining a place pays
nothing). AngularAcceleration follows the paper's formula (no dead zone unless `threshold`).

The built-ins are written once, batch-first and compiled (madsim.agents.component_kernel): the
envs evaluate them over all episodes or agents in one call (madsim.agents.component_batch); calling one
as above is a batch of one. A component registered with `register_reward` is plain Python
with the API above; the envs call it once per car and tick (a few us each).
"""

from __future__ import annotations

import inspect
from collections.abc import Mapping
from typing import Any

from madsim.agents import component_kernel as ck
from madsim.agents.component_batch import Builtin
from madsim.agents.registry import registrar

__all__ = [
    "REWARDS",
    "REWARD_ALIASES",
    "TICK_S",
    "RewardComponent",
    "RewardSet",
    "canonical_reward_name",
    "make_reward",
    "reward_params",
]

TICK_S = ck.TICK_S     # one World.step (ARCHITECTURE.md); MADRaS's "TORCS step"
CONTEXT_PARAMS = ("target_speed",)   # supplied by the agent's config, not by the reward entry


class RewardComponent:
    """Base class: `kind` is "reward" or "penalty"; subclasses implement `__call__`."""

    kind = "reward"

    def __init__(self):
        self.reset()

    def reset(self) -> None:
        """Forget everything about the previous episode."""

    def __call__(self, prev: Mapping, cur: Mapping, action: Any, info: Mapping) -> float:
        raise NotImplementedError


class _Reward(Builtin, RewardComponent):
    """A built-in reward: compiled over many slots (madsim.agents.component_kernel)."""


class Progress(_Reward):
    """Fraction of the track covered during the tick: (d - d_prev) / L (MADRaS ProgressReward)."""

    code = ck.C_PROGRESS


class Progress2(_Reward):
    """The paper's progress reward: min(1, d / s_target), d the metres of this tick and
    s_target = target_speed * 0.02 s the metres per tick at the target speed (m/s)."""

    code = ck.C_PROGRESS2

    def __init__(self, *, target_speed: float):
        if not target_speed > 0:
            raise ValueError(f"target_speed must be > 0 m/s, got {target_speed}")
        self.per_tick = target_speed * TICK_S
        super().__init__()

    def kernel_params(self, length):
        return (self.per_tick,)


class Progress3(Progress2):
    """Progress2 without the cap: d / s_target (MADRaS devel's ProgressReward3)."""

    code = ck.C_PROGRESS3


class AvgSpeed(_Reward):
    """Paid on the tick that completes a lap (distRaced reaching k L): s_avg / s_target, the
    average speed of that lap over the target speed (the paper's average_reward)."""

    code = ck.C_AVG_SPEED

    def __init__(self, *, target_speed: float):
        if not target_speed > 0:
            raise ValueError(f"target_speed must be > 0 m/s, got {target_speed}")
        self.target_speed = target_speed
        super().__init__()

    def kernel_params(self, length):
        return (self.target_speed,)


class Collision(_Reward):
    """1 on a tick where damage rose or the env reports a contact."""

    kind = "penalty"
    code = ck.C_COLLISION


class TurnBackward(_Reward):
    """1 while the car faces backwards: cos(angle) < 0."""

    kind = "penalty"
    code = ck.C_TURN_BACKWARD


class AngularAcceleration(_Reward):
    """|a_t + a_{t-2} - 2 a_{t-1}| / max_ang_accl over the last three angles (rad, one per
    tick; the paper's alpha_reference = max_ang_accl). Below `threshold` (rad per tick^2) it is
    0; MADRaS's code used threshold = max_ang_accl, which almost never fires."""

    kind = "penalty"
    code = ck.C_ANG_ACCEL
    initial_state = (0.0, 0.0, 1.0)

    def __init__(self, *, max_ang_accl: float = 2.0, threshold: float = 0.0):
        if not max_ang_accl > 0:
            raise ValueError(f"max_ang_accl must be > 0, got {max_ang_accl}")
        if not threshold >= 0:
            raise ValueError(f"threshold must be >= 0, got {threshold}")
        self.reference = float(max_ang_accl)
        self.threshold = float(threshold)
        super().__init__()

    def kernel_params(self, length):
        return self.reference, self.threshold


class SuccessfulOvertake(_Reward):
    """Positions gained beyond the best race position held so far in the episode."""

    code = ck.C_OVERTAKE
    initial_state = (0.0, 1.0, 0.0)


class RankOne(_Reward):
    """1 on every tick the car leads the race (racePos == 1)."""

    code = ck.C_RANK_ONE


class Task(_Reward):
    """`bonus` once per episode, on the first tick with racePos <= `position` (MADRaS devel's
    TaskReward: 100 at position 2)."""

    code = ck.C_TASK

    def __init__(self, *, position: int = 2, bonus: float = 100.0):
        if isinstance(position, bool) or not isinstance(position, int) or position < 1:
            raise ValueError(f"position must be an int >= 1, got {position!r}")
        self.position = position
        self.bonus = float(bonus)
        super().__init__()

    def kernel_params(self, length):
        return float(self.position), self.bonus


REWARDS: dict[str, type[RewardComponent]] = {
    "Progress": Progress, "Progress2": Progress2, "Progress3": Progress3, "AvgSpeed": AvgSpeed,
    "Collision": Collision, "TurnBackward": TurnBackward,
    "AngularAcceleration": AngularAcceleration, "SuccessfulOvertake": SuccessfulOvertake,
    "RankOne": RankOne, "Task": Task,
}


register_reward = registrar(REWARDS, RewardComponent, "reward")

# MADRaS class names (master and devel) -> madsim names
REWARD_ALIASES = {
    "ProgressReward": "Progress", "ProgressReward2": "Progress2", "ProgressReward3": "Progress3",
    "AvgSpeedReward": "AvgSpeed", "CollisionPenalty": "Collision",
    "TurnBackwardPenalty": "TurnBackward", "AngAcclPenalty": "AngularAcceleration",
    "SuccessfulOvertakeReward": "SuccessfulOvertake", "RankOneReward": "RankOne",
    "TaskReward": "Task",
}


def canonical_reward_name(name: str) -> str:
    """madsim name of a reward given by its madsim or MADRaS name; KeyError if unknown."""
    name = REWARD_ALIASES.get(name, name)
    if name not in REWARDS:
        raise KeyError(name)
    return name


def reward_params(name: str) -> dict[str, Any]:
    """Parameters a config entry may set for reward `name`, with defaults (scale excluded)."""
    sig = inspect.signature(REWARDS[canonical_reward_name(name)].__init__)
    return {p.name: p.default for p in sig.parameters.values()
            if p.kind is p.KEYWORD_ONLY and p.name not in CONTEXT_PARAMS}


def make_reward(name: str, params: Mapping[str, Any] | None = None, *,
                target_speed: float) -> RewardComponent:
    """Build one component; `params` as in the config entry, target_speed in m/s."""
    cls = REWARDS[canonical_reward_name(name)]
    kwargs = dict(params or {})
    if "target_speed" in inspect.signature(cls.__init__).parameters:
        kwargs["target_speed"] = target_speed
    return cls(**kwargs)


class RewardSet:
    """Weighted sum of components: total = sum_r w_r r - sum_p w_p p (paper, "agent_reward").

    Call with (prev, cur, action, info); returns (total, terms) where terms maps each
    component's name to its signed weighted contribution (they add up to total).
    """

    def __init__(self, components: list[tuple[str, float, RewardComponent]]):
        self.components = [(name, (-w if c.kind == "penalty" else w), c)
                           for name, w, c in components]

    @classmethod
    def from_terms(cls, terms, *, target_speed: float) -> RewardSet:
        """From config terms (objects with `name`, `scale`, `params`); target_speed m/s."""
        return cls([(t.name, float(t.scale), make_reward(t.name, t.params,
                                                         target_speed=target_speed))
                    for t in terms])

    def reset(self) -> None:
        for _, _, c in self.components:
            c.reset()

    def __call__(self, prev: Mapping, cur: Mapping, action: Any,
                 info: Mapping) -> tuple[float, dict[str, float]]:
        terms = {}
        total = 0.0
        for name, signed_weight, c in self.components:
            value = signed_weight * c(prev, cur, action, info)
            terms[name] = value
            total += value
        return total, terms
