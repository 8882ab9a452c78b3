"""Agent components over many slots at once (episodes of make_vec, agents of one episode).

Rewards and dones: `ComponentBatch` evaluates a set of them (the built-ins compiled, see
`Builtin`); the T-S controller over episodes: `BatchedTS`. Rows are (m, 79) SCR sensor rows in
wire order, per-slot state lives in arrays indexed by slot.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any

import numpy as np

from madsim.agents import component_kernel as ck
from madsim.agents.action_kernel import (begin_actions, clip_actions, fill_controls, speed_gears,
                                        take_actions)
from madsim.agents.pid import (
    CTRL_STATE,
    PIDController,
    observe,
    ts_act,
)
from madsim.agents.sensor_row import SensorRow
from madsim.physics.sensors import N_VALUES, O_ANGLE, O_SX, O_TPOS, SENSOR_OFFSETS



def speed_gear_many(speed_kmh: np.ndarray) -> np.ndarray:
    """madsim.agents.pid.speed_gear over an array (float gears)."""
    out = np.empty(speed_kmh.shape[0])
    speed_gears(np.ascontiguousarray(speed_kmh, dtype=np.float64), out)
    return out


# --- rewards and dones over many slots -----------------------------------------------------------


class Builtin:
    """A built-in reward or done: its formula is compiled (madsim.agents.component_kernel,
    selected by `code`); the object holds the configured parameters. Calling it with one car's
    rows (the component API of madsim.agents.rewards) evaluates a batch of one."""

    code = 0
    initial_state = (0.0, 0.0, 0.0)
    _cast = float

    def kernel_params(self, length: float) -> tuple:
        """The kernel's per-slot parameters for an episode on a track of `length` m."""
        return ()

    def reset(self) -> None:
        self._one = None

    def __call__(self, prev: Mapping, cur: Mapping, action: Any, info: Mapping):
        length = float(info["track_length"])
        one = getattr(self, "_one", None)
        if one is None:
            one = self._one = ComponentBatch([self], 1)
            one.start(0, [self], length)
        rows = np.zeros((2, N_VALUES))
        for k, row in enumerate((prev, cur)):
            for name, (o, w) in SENSOR_OFFSETS.items():
                if name in row:
                    rows[k, o:o + w] = row[name]
        out = one.evaluate(_SLOT0, rows[:1], rows[1:], np.array([length]),
                           np.array([bool(info.get("collision", False))]))
        return self._cast(out[0, 0])


_SLOT0 = np.zeros(1, dtype=np.int64)


class ComponentBatch:
    """The components of a reward or done set (built-ins and user-registered Python ones) over
    n slots (episodes, or the agents of one episode): `start(e, components, length)` at an
    episode start with the components of e's curriculum stage (same names, same order);
    `evaluate(slots, prev, cur, length, collision, actions)` -> (components, m) float64 values
    (dones 1.0 / 0.0) from the rows (m, 79) before and after the tick, length (m,) m and
    collision (m,) bool. Built-ins take one compiled call; a Python component is one deep copy
    per slot, called row by row with SensorRows (actions: the slots' checked actions, for them)."""

    def __init__(self, components, n: int):
        k = len(components)
        self.codes = np.array([c.code if isinstance(c, Builtin) else 0 for c in components],
                              dtype=np.int64)
        self.par = np.zeros((k, n, ck.NPAR))
        self.state = np.zeros((k, n, ck.NSTATE))
        self.python = [i for i, code in enumerate(self.codes.tolist()) if code == 0]
        self.objects = {i: [None] * n for i in self.python}

    def start(self, e: int, components, length: float) -> None:
        for i, c in enumerate(components):
            if i in self.objects:
                obj = copy.deepcopy(c)
                obj.reset()
                self.objects[i][e] = obj
            else:
                p = c.kernel_params(length)
                self.par[i, e, :len(p)] = p
                self.state[i, e] = c.initial_state

    def evaluate(self, slots, prev, cur, length, collision, actions=None) -> np.ndarray:
        out = np.zeros((self.codes.shape[0], slots.shape[0]))
        ck.evaluate(self.codes, self.par, self.state, slots, prev, cur, length, collision, out)
        for i in self.python:
            objects = self.objects[i]
            for j, e in enumerate(slots.tolist()):
                info = {"track_length": float(length[j]), "collision": bool(collision[j])}
                out[i, j] = objects[e](SensorRow(prev[j]), SensorRow(cur[j]),
                                       None if actions is None else actions[j], info)
        return out


class BatchedTS:
    """madsim.agents.pid.TrackSpeedController over slots: the same compiled controller
    (pid.ts_act), per-slot state in arrays."""

    def __init__(self, pid: PIDController, track_limits, normalised: bool, n: int):
        self.compat = pid.compat
        self.params = pid.params.copy()
        self.state = np.zeros((n, CTRL_STATE))
        self.low, self.high = float(track_limits[0]), float(track_limits[1])
        self.normalised = normalised
        self.target_speed = np.zeros(n)
        self.lane_des, self.speed_des_kmh = np.zeros(n), np.zeros(n)
        self.fresh = np.ones(n, dtype=bool)

    def reset(self, e: int, row: np.ndarray, target_speed: float) -> None:
        """Start slot e's episode from its first sensor row (79,)."""
        PIDController.initial_state(self.state[e])
        if not self.compat:
            observe(self.state[e], 0, row[O_TPOS], row[O_ANGLE], row[O_SX])
        self.lane_des[e] = self.speed_des_kmh[e] = 0.0
        self.fresh[e] = True
        self.target_speed[e] = target_speed

    def set_action(self, slots, action) -> None:
        """Take the T-S actions (m, 2) of slots (m,)."""
        take_actions(slots, action, True, self.normalised, self.compat, self.low, self.high,
                     self.target_speed, _NO_SAB, self.lane_des, self.speed_des_kmh)

    def act(self, slots, rows) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(steer, accel, brake) of the coming tick from the latest sensor rows (m, 79)."""
        out = np.empty((slots.shape[0], 3))
        ts_act(self.state, self.params, self.fresh, self.lane_des, self.speed_des_kmh, slots,
               rows, out)
        return out[:, 0], out[:, 1], out[:, 2]


_NO_SAB = np.zeros((0, 3))
_STOP = (0.0, 0.0, 1.0)           # steer, accel, brake: MADRaS's "stop" action


class ActionMap:
    """A learner's actions over slots -> the controls of every tick of the step.

    low, high (dim,): the action Box; ts: T-S actions through `BatchedTS` (pid: its
    PIDController, track_limits), else S-A-B (normalised: accel and brake from [-1, 1]);
    manual: the last action component is the gear. Per step: `begin(slots, actions, rngs)`
    (checked actions (m, dim); Gaussian noise of each slot's std from its generator, clipped
    again), then per tick `controls(slots, rows)` from the latest sensor rows (m, 79).
    """

    def __init__(self, low, high, *, ts: bool, normalised: bool, manual: bool, pid, track_limits,
                 n: int):
        self.low = np.asarray(low, dtype=np.float64)
        self.high = np.asarray(high, dtype=np.float64)
        self.dim = self.low.shape[0]
        self.ts, self.normalised, self.manual = ts, normalised, manual
        self.pid = BatchedTS(pid, track_limits, normalised, n) if ts else None
        self._no_ts = BatchedTS(pid, track_limits, normalised, 0)     # typed stand-in arrays
        self.noise_std = np.zeros(n)
        self._noisy = False                    # some slot has had noise: look for it
        self.sab = np.tile(_STOP, (n, 1))
        self.gear = np.ones(n)

    @property
    def controller(self) -> BatchedTS:
        """The T-S controller's arrays (for S-A-B a stand-in of 0 slots: the kernels' types)."""
        return self.pid if self.ts else self._no_ts

    def clip(self, actions: np.ndarray) -> np.ndarray:
        """Actions (m, dim) or (dim,) clipped into the Box."""
        return self.check(actions)[0]

    def check(self, actions: np.ndarray) -> tuple[np.ndarray, int]:
        """(actions (m, dim) or (dim,) clipped into the Box, float64; the flat index of the
        first non-finite value, or -1): one compiled call."""
        a = np.ascontiguousarray(actions, dtype=np.float64)
        out = np.empty_like(a)
        bad = clip_actions(a.reshape(-1, self.dim), self.low, self.high, out.reshape(-1, self.dim))
        return out, bad

    def start(self, e: int, row: np.ndarray, target_speed: float, noise_std: float) -> None:
        """Slot e's episode starts: first sensor row (79,), target speed m/s, noise std."""
        if self.pid is not None:
            self.pid.reset(e, row, target_speed)
        self.sab[e] = _STOP
        self.noise_std[e] = noise_std
        self._noisy |= noise_std > 0.0

    def noised(self, slots: np.ndarray, chosen: np.ndarray, rngs) -> np.ndarray:
        """This step's checked actions (m, dim) of slots with each slot's Gaussian noise (from
        rngs[e], slot e's generator) added and clipped again (a copy), or `chosen` itself."""
        noisy = np.flatnonzero(self.noise_std[slots] > 0.0) if self._noisy else ()
        if len(noisy):
            chosen = chosen.copy()
            for i in noisy.tolist():                            # in slot order
                e = slots[i]
                noise = rngs[e].normal(0.0, self.noise_std[e], self.dim)
                chosen[i] = self.clip(chosen[i] + noise)
        return chosen

    def begin(self, slots: np.ndarray, chosen: np.ndarray, rngs) -> None:
        """Take this step's checked actions (m, dim) of slots; rngs[e]: slot e's generator."""
        chosen = self.noised(slots, chosen, rngs)
        ts = self.controller
        begin_actions(slots, chosen, self.ts, self.normalised, self.manual, ts.compat, ts.low,
                      ts.high, ts.target_speed, self.sab, self.gear, ts.lane_des, ts.speed_des_kmh)

    def controls(self, slots: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Controls (m, 4: steer, accel, brake, gear) of the coming tick for slots from their
        latest sensor rows (m, 79)."""
        out = np.empty((slots.shape[0], 4))
        ts = self.controller
        fill_controls(slots, rows, self.ts, self.manual, self.sab, self.gear, ts.state, ts.params,
                      ts.fresh, ts.lane_des, ts.speed_des_kmh, out)
        return out
