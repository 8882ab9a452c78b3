"""Episode-end conditions of MADRaS, registered by name (spec madras-features.md section 8).

Same calling convention as `madsim.agents.rewards`: `reset()`, then one call per tick,
`component(prev, cur, action, info) -> bool` with SCR rows before/after the tick and
`info["track_length"]` (m) / optional `info["collision"]` (bool). A component with
`truncation = True` (TimeOut) ends the episode by time limit, not by a terminal state.
`DoneSet` evaluates all of them every tick: the episode ends when any fires.

The built-ins are compiled and batch-first like the rewards (madsim.agents.rewards); one
registered with `register_done` is plain Python.

Fixes (spec section 11, item 17): Collision compares damage with the previous tick (MADRaS
kept a stale baseline, so after one hit every later tick, or episode, was "done").
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Mapping, Sequence
from typing import Any

from madsim.agents import component_kernel as ck
from madsim.agents.component_batch import Builtin
from madsim.agents.registry import registrar
from madsim.agents.rewards import TICK_S

__all__ = ["DONES", "DoneComponent", "DoneSet", "make_done"]

CONTEXT_PARAMS = ("max_steps", "laps", "track_limits", "target_speed")


class DoneComponent:
    """Base class; `truncation` tells a time limit from a terminal state."""

    truncation = False

    def reset(self) -> None:
        """Forget everything about the previous episode."""

    def __call__(self, prev: Mapping, cur: Mapping, action: Any, info: Mapping) -> bool:
        raise NotImplementedError


class _Done(Builtin, DoneComponent):
    """A built-in done: compiled over many slots (madsim.agents.component_kernel)."""

    _cast = bool


class RaceOver(_Done):
    """The race distance is covered: distRaced >= laps * track length."""

    code = ck.C_RACE_OVER

    def __init__(self, *, laps: int = 1):
        self.laps = laps
        self.reset()

    def kernel_params(self, length):
        return (float(self.laps),)


class LapCompleted(_Done):
    """A lap was timed on this tick: lastLapTime changed to a positive value."""

    code = ck.C_LAP_COMPLETED


class TimeOut(_Done):
    """`max_steps` ticks since reset. max_steps None: the ticks one lap takes at the target
    speed, ceil(L / (target_speed * 0.02 s)) (MADRaS's rule for a missing max_steps)."""

    truncation = True
    code = ck.C_TIME_OUT

    def __init__(self, *, max_steps: int | None = None, target_speed: float = 15.0):
        self.max_steps = max_steps
        self.target_speed = target_speed
        self.reset()

    def kernel_params(self, length):
        limit = self.max_steps
        if limit is None:
            limit = math.ceil(length / (self.target_speed * TICK_S))
        return (float(limit),)


class Collision(_Done):
    """Damage rose during the tick, or the env reports a contact."""

    code = ck.C_COLLISION_DONE


class TurnBackward(_Done):
    """The car faces backwards: cos(angle) < 0."""

    code = ck.C_TURN_BACKWARD_DONE


class OutOfTrack(_Done):
    """trackPos outside `track_limits` (low, high), or off the road (a rangefinder < 0)."""

    code = ck.C_OUT_OF_TRACK

    def __init__(self, *, track_limits: Sequence[float] = (-1.0, 1.0)):
        self.low, self.high = float(track_limits[0]), float(track_limits[1])
        self.reset()

    def kernel_params(self, length):
        return self.low, self.high


class Rank1(_Done):
    """The car leads the race: racePos == 1."""

    code = ck.C_RANK1


DONES: dict[str, type[DoneComponent]] = {
    "RaceOver": RaceOver, "TimeOut": TimeOut, "Collision": Collision,
    "TurnBackward": TurnBackward, "OutOfTrack": OutOfTrack, "Rank1": Rank1,
    "LapCompleted": LapCompleted,
}


register_done = registrar(DONES, DoneComponent, "done")


def make_done(name: str, **context) -> DoneComponent:
    """Build one component, passing it those of `context` (max_steps, laps, track_limits,
    target_speed) its constructor takes."""
    cls = DONES[name]
    accepted = inspect.signature(cls.__init__).parameters
    return cls(**{k: v for k, v in context.items() if k in accepted})


class DoneSet:
    """All done components of an agent; call -> (terminated, truncated, names that fired)."""

    def __init__(self, components: list[tuple[str, DoneComponent]]):
        self.components = components

    @classmethod
    def from_names(cls, names: Sequence[str], **context) -> DoneSet:
        """From the config's list of names and the context (see `make_done`)."""
        return cls([(n, make_done(n, **context)) for n in names])

    def reset(self) -> None:
        for _, c in self.components:
            c.reset()

    def __call__(self, prev: Mapping, cur: Mapping, action: Any,
                 info: Mapping) -> tuple[bool, bool, list[str]]:
        fired = []
        terminated = truncated = False
        for name, c in self.components:
            if c(prev, cur, action, info):       # every component sees every tick
                fired.append(name)
                if c.truncation:
                    truncated = True
                else:
                    terminated = True
        return terminated, truncated, fired
