"""Agent components over many episodes at once, for the batched vector env.

Each class mirrors one component of `madsim.agents.rewards` / `dones` / `pid` float for float
(the vector env's tests compare against separate MadrasEnvs bit for bit): per-episode parameters
are copied from the scalar component built for the episode's curriculum stage, per-episode state
lives in (n,) arrays indexed by episode slot. Rows are (m, 79) SCR sensor rows in wire order.
"""

from __future__ import annotations

import math

import numpy as np

from madsim.agents import dones as D
from madsim.agents import rewards as R
from madsim.agents.pid import SPEED_UNIT_KMH, PIDController
from madsim.physics.sensors import (
    O_ANGLE,
    O_DAMAGE,
    O_DRACED,
    O_LASTLAP,
    O_RACEPOS,
    O_SX,
    O_TPOS,
    O_TRACK,
)

TICK_S = R.TICK_S

_GEAR_KMH = (50.0, 80.0, 110.0, 140.0, 170.0)     # madsim.agents.pid.speed_gear's thresholds


def speed_gear_many(speed_kmh: np.ndarray) -> np.ndarray:
    """madsim.agents.pid.speed_gear over an array (float gears)."""
    gear = np.ones(speed_kmh.shape)
    for threshold in _GEAR_KMH:
        gear += speed_kmh > threshold
    return gear


# --- rewards and dones over many episodes ------------------------------------------------------
# Each mirrors one component of madsim.agents.rewards / dones, float for float: per-episode
# parameters are copied from the component object built for the episode's stage, per-episode
# state lives in (n,) arrays. Call: (slots, prev, cur, length, collision) with prev, cur (m, 79)
# sensor rows of the learners, length (m,) track lengths m, collision (m,) bool.


class Batched:
    params: tuple[str, ...] = ()

    def __init__(self, n: int):
        for p in self.params:
            setattr(self, p, np.zeros(n))

    def start(self, e: int, comp, length: float) -> None:
        for p in self.params:
            getattr(self, p)[e] = getattr(comp, p)


class _Progress(Batched):
    def __call__(self, slots, prev, cur, length, collision):
        return (cur[:, O_DRACED] - prev[:, O_DRACED]) / length


class _Progress2(Batched):
    params = ("per_tick",)

    def __call__(self, slots, prev, cur, length, collision):
        return np.minimum(1.0, (cur[:, O_DRACED] - prev[:, O_DRACED]) / self.per_tick[slots])


class _Progress3(_Progress2):
    def __call__(self, slots, prev, cur, length, collision):
        return (cur[:, O_DRACED] - prev[:, O_DRACED]) / self.per_tick[slots]


class _AvgSpeed(Batched):
    params = ("target_speed",)

    def __init__(self, n):
        super().__init__(n)
        self.ticks = np.zeros(n, dtype=np.int64)
        self.laps_paid = np.zeros(n, dtype=np.int64)

    def start(self, e, comp, length):
        super().start(e, comp, length)
        self.ticks[e] = self.laps_paid[e] = 0

    def __call__(self, slots, prev, cur, length, collision):
        self.ticks[slots] += 1
        out = np.zeros(slots.shape[0])
        pay = ~(cur[:, O_DRACED] < (self.laps_paid[slots] + 1) * length)
        if pay.any():
            e = slots[pay]
            self.laps_paid[e] += 1
            avg_speed = length[pay] / (self.ticks[e] * TICK_S)
            self.ticks[e] = 0
            out[pay] = avg_speed / self.target_speed[e]
        return out


def _hit(prev, cur, collision):
    return collision | (cur[:, O_DAMAGE] > prev[:, O_DAMAGE])


class _Collision(Batched):
    def __call__(self, slots, prev, cur, length, collision):
        return _hit(prev, cur, collision).astype(np.float64)


class _TurnBackward(Batched):
    def __call__(self, slots, prev, cur, length, collision):
        return (np.cos(cur[:, O_ANGLE]) < 0.0).astype(np.float64)


def _wrap(a):
    return a - 2.0 * math.pi * np.floor((a + math.pi) / (2.0 * math.pi))


class _AngularAcceleration(Batched):
    params = ("reference", "threshold")

    def __init__(self, n):
        super().__init__(n)
        self.history = np.zeros((n, 2))
        self.fresh = np.ones(n, dtype=bool)

    def start(self, e, comp, length):
        super().start(e, comp, length)
        self.fresh[e] = True

    def __call__(self, slots, prev, cur, length, collision):
        fresh = self.fresh[slots]
        self.history[slots[fresh]] = prev[fresh, O_ANGLE, None]
        self.fresh[slots] = False
        a0, a1 = self.history[slots, 0], self.history[slots, 1]
        a2 = cur[:, O_ANGLE]
        self.history[slots, 0], self.history[slots, 1] = a1, a2
        acc = np.abs(_wrap(a2 - a1) - _wrap(a1 - a0))
        return np.where(acc > self.threshold[slots], acc / self.reference[slots], 0.0)


class _SuccessfulOvertake(Batched):
    def __init__(self, n):
        super().__init__(n)
        self.best = np.zeros(n)
        self.fresh = np.ones(n, dtype=bool)

    def start(self, e, comp, length):
        self.fresh[e] = True

    def __call__(self, slots, prev, cur, length, collision):
        fresh = self.fresh[slots]
        self.best[slots[fresh]] = prev[fresh, O_RACEPOS]
        self.fresh[slots] = False
        gained = self.best[slots] - cur[:, O_RACEPOS]
        up = gained > 0
        self.best[slots[up]] = cur[up, O_RACEPOS]
        return np.where(up, gained, 0.0)


class _RankOne(Batched):
    def __call__(self, slots, prev, cur, length, collision):
        return (cur[:, O_RACEPOS] == 1.0).astype(np.float64)


class _Task(Batched):
    params = ("position", "bonus")

    def __init__(self, n):
        super().__init__(n)
        self.paid = np.zeros(n, dtype=bool)

    def start(self, e, comp, length):
        super().start(e, comp, length)
        self.paid[e] = False

    def __call__(self, slots, prev, cur, length, collision):
        pay = ~(self.paid[slots] | (cur[:, O_RACEPOS] > self.position[slots]))
        self.paid[slots[pay]] = True
        return np.where(pay, self.bonus[slots], 0.0)


class _RaceOver(Batched):
    params = ("laps",)

    def __call__(self, slots, prev, cur, length, collision):
        return cur[:, O_DRACED] >= self.laps[slots] * length


class _LapCompleted(Batched):
    def __call__(self, slots, prev, cur, length, collision):
        return (cur[:, O_LASTLAP] > 0.0) & (cur[:, O_LASTLAP] != prev[:, O_LASTLAP])


class _TimeOut(Batched):
    def __init__(self, n):
        super().__init__(n)
        self.ticks = np.zeros(n, dtype=np.int64)
        self.limit = np.zeros(n, dtype=np.int64)

    def start(self, e, comp, length):
        limit = comp.max_steps
        if limit is None:
            limit = math.ceil(length / (comp.target_speed * TICK_S))
        self.limit[e] = limit
        self.ticks[e] = 0

    def __call__(self, slots, prev, cur, length, collision):
        self.ticks[slots] += 1
        return self.ticks[slots] >= self.limit[slots]


class _CollisionDone(Batched):
    def __call__(self, slots, prev, cur, length, collision):
        return _hit(prev, cur, collision)


class _TurnBackwardDone(Batched):
    def __call__(self, slots, prev, cur, length, collision):
        return np.cos(cur[:, O_ANGLE]) < 0.0


class _OutOfTrack(Batched):
    params = ("low", "high")

    def __call__(self, slots, prev, cur, length, collision):
        pos = cur[:, O_TPOS]
        return ((pos < self.low[slots]) | (pos > self.high[slots])
                | (cur[:, O_TRACK:O_TRACK + 19].min(axis=1) < 0.0))


class _Rank1(Batched):
    def __call__(self, slots, prev, cur, length, collision):
        return cur[:, O_RACEPOS] == 1.0


BATCHED = {
    R.Progress: _Progress, R.Progress2: _Progress2, R.Progress3: _Progress3,
    R.AvgSpeed: _AvgSpeed, R.Collision: _Collision, R.TurnBackward: _TurnBackward,
    R.AngularAcceleration: _AngularAcceleration, R.SuccessfulOvertake: _SuccessfulOvertake,
    R.RankOne: _RankOne, R.Task: _Task,
    D.RaceOver: _RaceOver, D.LapCompleted: _LapCompleted, D.TimeOut: _TimeOut,
    D.Collision: _CollisionDone, D.TurnBackward: _TurnBackwardDone, D.OutOfTrack: _OutOfTrack,
    D.Rank1: _Rank1,
}


class BatchedPID:
    """madsim.agents.pid.PID over episodes: integral, previous error, first-call flag."""

    def __init__(self, pid, n: int):
        self.kp, self.ki, self.kd = pid.kp, pid.ki, pid.kd
        self.limits, self.kick_free = pid.limits, pid.kick_free
        self.integral = np.zeros(n)
        self.prev = np.zeros(n)
        self.first = np.ones(n, dtype=bool)

    def reset(self, e: int) -> None:
        self.integral[e] = self.prev[e] = 0.0
        self.first[e] = True

    def __call__(self, slots, error):
        prev = self.prev[slots]
        if self.kick_free:
            prev = np.where(self.first[slots], error, prev)
        self.first[slots] = False
        derivative = error - prev
        self.prev[slots] = error
        held = self.integral[slots]
        integral = held + error
        out = self.kp * error + self.ki * integral + self.kd * derivative
        if self.limits is not None:
            low, high = self.limits
            hold = ((out > high) & (error > 0.0)) | ((out < low) & (error < 0.0))
            if hold.any():
                integral = np.where(hold, held, integral)
                held_out = self.kp * error + self.ki * integral + self.kd * derivative
                out = np.where(hold, held_out, out)
        self.integral[slots] = integral
        return out


class BatchedTS:
    """madsim.agents.pid.TrackSpeedController (with its PIDController) over episodes."""

    def __init__(self, pid: PIDController, track_limits, normalised: bool, n: int):
        self.compat = pid.compat
        self.accel_pid = BatchedPID(pid.accel_pid, n)
        self.steer_pid = BatchedPID(pid.steer_pid, n)
        self.accel_scale, self.steer_scale = pid.accel_scale, pid.steer_scale
        self.low, self.high = float(track_limits[0]), float(track_limits[1])
        self.normalised = normalised
        self.target_speed = np.zeros(n)
        self.lane_des, self.speed_des_kmh = np.zeros(n), np.zeros(n)
        self.prev_lane, self.prev_angle, self.prev_vel = np.zeros(n), np.zeros(n), np.zeros(n)
        self.fresh = np.ones(n, dtype=bool)

    def reset(self, e: int, row: np.ndarray, target_speed: float) -> None:
        self.accel_pid.reset(e)
        self.steer_pid.reset(e)
        self.prev_lane[e] = self.prev_angle[e] = self.prev_vel[e] = 0.0
        if not self.compat:
            self._update(np.array([e]), row[None, :])
        self.lane_des[e] = self.speed_des_kmh[e] = 0.0
        self.fresh[e] = True
        self.target_speed[e] = target_speed

    def _update(self, slots, rows) -> None:
        self.prev_lane[slots] = rows[:, O_TPOS]
        self.prev_angle[slots] = rows[:, O_ANGLE] / math.pi
        self.prev_vel[slots] = rows[:, O_SX] / SPEED_UNIT_KMH

    def set_action(self, slots, action) -> None:
        a0, a1 = action[:, 0], action[:, 1]
        if not self.normalised:
            self.lane_des[slots], self.speed_des_kmh[slots] = a0, a1
            return
        span = self.high - self.low
        lane = self.low + span * a0 if self.compat else self.low + span * (a0 + 1.0) / 2.0
        self.lane_des[slots] = lane
        self.speed_des_kmh[slots] = a1 * self.target_speed[slots] * 3.6

    def act(self, slots, rows) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(steer, accel, brake) of the coming tick from the latest sensor rows (m, 79)."""
        update = ~self.fresh[slots] if self.compat else np.ones(slots.shape[0], dtype=bool)
        self._update(slots[update], rows[update])
        self.fresh[slots] = False
        lane_error = self.prev_lane[slots] - self.lane_des[slots]
        steer_error = self.prev_angle[slots] - lane_error * self.steer_scale
        speed_error = self.speed_des_kmh[slots] / SPEED_UNIT_KMH - self.prev_vel[slots]
        accel_error = speed_error * self.accel_scale
        steer = self.steer_pid(slots, steer_error)
        accel = self.accel_pid(slots, accel_error)
        if self.compat:
            return steer, accel, np.where(accel < 0.0, 1.0, 0.0)
        return (np.minimum(1.0, np.maximum(-1.0, steer)), np.minimum(1.0, np.maximum(0.0, accel)),
                np.minimum(1.0, np.maximum(0.0, -accel)))
