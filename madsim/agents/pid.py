"""The track-position / speed (T-S) controller of MADRaS and an automatic gearbox.

`PIDController` is MADRaS's pair of discrete PIDs (spec madras-features.md section 6.3): one
steers towards a desired track position, one drives the speed (km/h / 50 units) towards a
desired speed; a negative speed output brakes. Gains are per tick (0.02 s), as MADRaS tuned
them, so there is no dt. `TrackSpeedController` turns a T-S action into the desired values
(section 6.2) and produces steer/accel/brake/gear every tick of the latency window (6.4).

Bugs of the original fixed here unless `madras_compat=True` (spec section 11, items 15, 19):
the state is seeded from the first observation (MADRaS starts from zeros), the first tick has
no derivative kick, the integrators stop winding up while their output saturates, outputs are
clipped to the SCR ranges, braking is proportional to the negative speed output (MADRaS brakes
fully on any negative output) and the normalised lane action spans the track limits (MADRaS
maps [-1, 1] to [-3, 1]).

The arithmetic is written once, compiled, over plain state and parameter rows (`pid_step`,
`pid_controls`): the classes here drive one controller with it, `BatchedTS`
(madsim.agents.component_batch) every learner of a batch, and the traffic kernel every traffic car.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from numba import njit

from madsim.facts import rpm_gear
from madsim.physics.sensors import O_ANGLE, O_SX, O_TPOS

__all__ = [
    "MADRAS_ACCEL_GAINS",
    "MADRAS_STEER_GAINS",
    "PID",
    "desired_lane_speed",
    "pid_controls",
    "pid_step",
    "PIDController",
    "TrackSpeedController",
    "rpm_gear",
    "speed_gear",
]

MADRAS_ACCEL_GAINS = (10.5, 0.05, 2.8)      # Kp, Ki, Kd (spec 6.3, paper table "PID params")
MADRAS_STEER_GAINS = (5.1, 0.001, 1e-6)
SPEED_UNIT_KMH = 50.0                        # gym_torcs scales speeds as km/h / 50 (spec 5.1)

# snakeoil's automatic gearbox (spec 6.1): speedX km/h above which each gear 2..6 is used
SPEED_GEAR_KMH = (50.0, 80.0, 110.0, 140.0, 170.0)


@njit(cache=True)
def speed_gear(speed_kmh: float) -> int:
    """MADRaS's (snakeoil's) gear for a forward speed in km/h: 1 up to 50, 2 above 50, 3 above
    80, 4 above 110, 5 above 140, 6 above 170."""
    gear = 1
    for threshold in SPEED_GEAR_KMH:
        if speed_kmh > threshold:
            gear += 1
    return gear


# A PID's parameter block: kp, ki, kd, kick_free, limited, low, high; its state block:
# integral, previous error, first call (1.0 until the first call after a reset).
PID_PARAMS, PID_STATE = 7, 3
# A controller's parameter block: the steer PID, the accel PID, accel_scale, steer_scale,
# compat; its state block: steer PID, accel PID, lane, angle / pi, speed / 50 (the observation).
CTRL_PARAMS, CTRL_STATE = 2 * PID_PARAMS + 3, 2 * PID_STATE + 3
_ACCEL_SCALE, _STEER_SCALE, _COMPAT = 2 * PID_PARAMS, 2 * PID_PARAMS + 1, 2 * PID_PARAMS + 2
_LANE, _ANGLE, _VEL = 2 * PID_STATE, 2 * PID_STATE + 1, 2 * PID_STATE + 2


@njit(cache=True, inline="always")
def py_min(a, b):
    return b if b < a else a          # Python's min(a, b), also for signed zeros


@njit(cache=True, inline="always")
def py_max(a, b):
    return b if b > a else a          # Python's max(a, b)


@njit(cache=True)
def pid_step(s, o, p, q, error):
    """One tick of the PID whose state is s[o:o + 3] and parameters p[q:q + 7] (see `PID`)."""
    if s[o + 2] != 0.0 and p[q + 3] != 0.0:
        s[o + 1] = error
    s[o + 2] = 0.0
    derivative = error - s[o + 1]
    s[o + 1] = error
    held = s[o]
    integral = held + error
    kp, ki, kd = p[q], p[q + 1], p[q + 2]
    out = kp * error + ki * integral + kd * derivative
    if p[q + 4] != 0.0 and ((out > p[q + 6] and error > 0.0) or (out < p[q + 5] and error < 0.0)):
        integral = held                                   # hold: no wind-up
        out = kp * error + ki * integral + kd * derivative
    s[o] = integral
    return out


@njit(cache=True)
def pid_controls(s, o, p, q, lane_des, speed_des_kmh):
    """(steer, accel, brake) of the controller with state s[o:o + 9] and parameters
    p[q:q + 17] towards a track position and a speed in km/h (see `PIDController`)."""
    steer_error = s[o + _ANGLE] - (s[o + _LANE] - lane_des) * p[q + _STEER_SCALE]
    accel_error = (speed_des_kmh / SPEED_UNIT_KMH - s[o + _VEL]) * p[q + _ACCEL_SCALE]
    steer = pid_step(s, o, p, q, steer_error)
    accel = pid_step(s, o + PID_STATE, p, q + PID_PARAMS, accel_error)
    if p[q + _COMPAT] != 0.0:
        return steer, accel, (1.0 if accel < 0.0 else 0.0)
    return (py_min(1.0, py_max(-1.0, steer)), py_min(1.0, py_max(0.0, accel)),
            py_min(1.0, py_max(0.0, -accel)))


@njit(cache=True)
def observe(s, o, track_pos, angle, speed_kmh):
    """Store the observation the next controls are computed from."""
    s[o + _LANE] = track_pos
    s[o + _ANGLE] = angle / math.pi
    s[o + _VEL] = speed_kmh / SPEED_UNIT_KMH


@njit(cache=True)
def ts_act(state, params, fresh, lane_des, speed_des_kmh, slots, rows, out):
    """The T-S controls (steer, accel, brake) -> out (m, 3) of slots (m,) from their latest
    sensor rows (m, 79): state (n, 9), params (17,) as `pid_controls`; MADRaS (compat)
    computes the first tick after a reset from the zeroed state (fresh (n,) bool)."""
    compat = params[_COMPAT] != 0.0
    for i in range(slots.shape[0]):
        e = slots[i]
        s = state[e]
        if not (compat and fresh[e]):
            observe(s, 0, rows[i, O_TPOS], rows[i, O_ANGLE], rows[i, O_SX])
        fresh[e] = False
        out[i, 0], out[i, 1], out[i, 2] = pid_controls(s, 0, params, 0, lane_des[e],
                                                       speed_des_kmh[e])


class PID:
    """One discrete PID, u = Kp e + Ki sum(e) + Kd (e - e_prev), evaluated once per tick.

    `limits` (low, high) enables anti-windup: the error is not added to the sum on a tick where
    the output is beyond a limit and the error pushes further out. `kick_free` makes the first
    call after `reset()` have a zero derivative term instead of Kd * e.
    """

    def __init__(self, kp: float, ki: float, kd: float, *,
                 limits: tuple[float, float] | None = None, kick_free: bool = True):
        self.kp, self.ki, self.kd = float(kp), float(ki), float(kd)
        self.limits = limits
        self.kick_free = kick_free
        self.state = np.zeros(PID_STATE)
        self.reset()

    def pack(self, p: np.ndarray) -> None:
        """Write the parameter block (7 values) into p."""
        low, high = self.limits if self.limits is not None else (0.0, 0.0)
        p[:] = self.kp, self.ki, self.kd, self.kick_free, self.limits is not None, low, high

    def reset(self) -> None:
        """Clear the integral and the previous error."""
        self.state[:] = 0.0, 0.0, 1.0

    @property
    def integral(self) -> float:
        return float(self.state[0])

    def __call__(self, error: float) -> float:
        """Advance one tick with this error and return the output."""
        p = np.empty(PID_PARAMS)
        self.pack(p)
        return pid_step(self.state, 0, p, 0, float(error))


class PIDController:
    """MADRaS's T-S controller: steer and speed PIDs driven by the last observation.

    Errors (spec 6.3; lane in trackPos units, angle in units of pi, speeds in km/h / 50):
    steer_error = angle - (trackPos - lane_des) * steer_scale,
    accel_error = (v_des - speedX) * accel_scale.
    Output of `get_action`: (steer, accel, brake).
    """

    def __init__(self, accel_gains: Sequence[float] = MADRAS_ACCEL_GAINS,
                 steer_gains: Sequence[float] = MADRAS_STEER_GAINS, *,
                 accel_scale: float = 1.0, steer_scale: float = 0.1,
                 madras_compat: bool = False):
        self.compat = bool(madras_compat)
        limits = None if self.compat else (-1.0, 1.0)
        self.accel_pid = PID(*accel_gains, limits=limits, kick_free=not self.compat)
        self.steer_pid = PID(*steer_gains, limits=limits, kick_free=not self.compat)
        self.accel_scale = float(accel_scale)
        self.steer_scale = float(steer_scale)
        self.params = np.zeros(CTRL_PARAMS)
        self.pack(self.params)
        self.state = np.zeros(CTRL_STATE)
        self.steer_pid.state = self.state[:PID_STATE]          # views: one state, two readers
        self.accel_pid.state = self.state[PID_STATE:2 * PID_STATE]
        self.reset()

    @classmethod
    def from_config(cls, pid) -> PIDController:
        """From a config's PidConfig (gains, scales, madras_compat)."""
        return cls(pid.accel_gains, pid.steer_gains, accel_scale=pid.accel_scale,
                   steer_scale=pid.steer_scale, madras_compat=pid.madras_compat)

    def pack(self, p: np.ndarray) -> None:
        """Write the controller's parameter block (17 values, see `pid_controls`) into p."""
        self.steer_pid.pack(p[:PID_PARAMS])
        self.accel_pid.pack(p[PID_PARAMS:2 * PID_PARAMS])
        p[_ACCEL_SCALE], p[_STEER_SCALE], p[_COMPAT] = self.accel_scale, self.steer_scale, self.compat

    @staticmethod
    def initial_state(s: np.ndarray) -> None:
        """A reset state block (9 values) in s: zeros, both PIDs before their first call."""
        s[:] = 0.0
        s[2] = s[PID_STATE + 2] = 1.0

    def reset(self, row: Mapping | None = None) -> None:
        """Start an episode. The fixed controller takes its state from `row` (the first
        observation); MADRaS (and a None row) starts from trackPos = angle = speed = 0."""
        self.initial_state(self.state)
        if row is not None and not self.compat:
            self.update(row)

    def update(self, row: Mapping) -> None:
        """Store the observation the next action is computed from (one car's SCR row)."""
        observe(self.state, 0, float(row["trackPos"]), float(row["angle"]), float(row["speedX"]))

    def get_action(self, lane_des: float, speed_des_kmh: float) -> tuple[float, float, float]:
        """(steer, accel, brake) towards a track position and a speed in km/h."""
        return pid_controls(self.state, 0, self.params, 0, float(lane_des), float(speed_des_kmh))


@njit(cache=True)
def desired_lane_speed(a0, a1, low, high, normalised, compat, target_speed):
    """(lane in trackPos units, speed in km/h) of a T-S action: normalised, lane = low +
    (high - low) (a0 + 1) / 2 (MADRaS master: low + (high - low) a0, spec 6.2, bug 15) and
    speed = a1 * target_speed (m/s) in km/h; else a0, a1 as they are."""
    if not normalised:
        return a0, a1
    span = high - low
    lane = low + span * a0 if compat else low + span * (a0 + 1.0) / 2.0
    return lane, a1 * target_speed * 3.6


class TrackSpeedController:
    """A T-S action -> desired (trackPos, km/h) -> SCR controls, one call per tick.

    Action (a0, a1): normalised, both in [-1, 1]: lane = low + (high - low) (a0 + 1) / 2 over
    `track_limits`, speed = a1 * target_speed (m/s); not normalised: a0 is the trackPos and a1
    the speed in km/h. Use: `set_action(a)` once per env step, `act(row)` every tick with the
    latest observation; `act` returns np.array([steer, accel, brake, gear]) (gear from
    `speed_gear`, MADRaS's gearbox; the env overrides it in manual mode). The envs run the same
    controller over all their learners (madsim.agents.component_batch.BatchedTS).
    """

    def __init__(self, pid: PIDController, *, target_speed: float,
                 track_limits: tuple[float, float] = (-1.0, 1.0), normalised: bool = True):
        self.pid = pid
        self.target_speed = float(target_speed)
        self.track_limits = (float(track_limits[0]), float(track_limits[1]))
        self.normalised = bool(normalised)
        self.lane_des = 0.0
        self.speed_des_kmh = 0.0
        self._fresh = True

    def desired(self, action: Sequence[float]) -> tuple[float, float]:
        """(lane in trackPos units, speed in km/h) for a T-S action."""
        low, high = self.track_limits
        return desired_lane_speed(float(action[0]), float(action[1]), low, high,
                                  self.normalised, self.pid.compat, self.target_speed)

    def set_action(self, action: Sequence[float]) -> None:
        """Take a new T-S action; it holds until the next call."""
        self.lane_des, self.speed_des_kmh = self.desired(action)

    def reset(self, row: Mapping | None = None) -> None:
        """Start an episode (see `PIDController.reset`)."""
        self.pid.reset(row)
        self.lane_des = 0.0
        self.speed_des_kmh = 0.0
        self._fresh = True

    def act(self, row: Mapping) -> np.ndarray:
        """Controls for the coming tick from the latest observation `row`.

        MADRaS computes the first tick after a reset from its zeroed state and only then
        looks at observations; the compat mode reproduces that."""
        if not (self.pid.compat and self._fresh):
            self.pid.update(row)
        self._fresh = False
        steer, accel, brake = self.pid.get_action(self.lane_des, self.speed_des_kmh)
        return np.array([steer, accel, brake, speed_gear(float(row["speedX"]))])
