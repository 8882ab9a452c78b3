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
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

__all__ = [
    "MADRAS_ACCEL_GAINS",
    "MADRAS_STEER_GAINS",
    "PID",
    "PIDController",
    "TrackSpeedController",
    "rpm_gear",
    "speed_gear",
]

MADRAS_ACCEL_GAINS = (10.5, 0.05, 2.8)      # Kp, Ki, Kd (spec 6.3, paper table "PID params")
MADRAS_STEER_GAINS = (5.1, 0.001, 1e-6)
SPEED_UNIT_KMH = 50.0                        # gym_torcs scales speeds as km/h / 50 (spec 5.1)

# snakeoil's automatic gearbox (spec 6.1): speedX km/h above which each gear 2..6 is used
_SPEED_GEAR_KMH = (50.0, 80.0, 110.0, 140.0, 170.0)
# The SCR championship sample driver (SimpleDriver): SCR rpm at which gears 1..5 shift up,
# and at which gears 2..6 shift down.
_GEAR_UP_RPM = (5000.0, 6000.0, 6000.0, 6500.0, 7000.0)
_GEAR_DOWN_RPM = (2500.0, 3000.0, 3000.0, 3500.0, 3500.0)


def speed_gear(speed_kmh: float) -> int:
    """MADRaS's (snakeoil's) gear for a forward speed in km/h: 1 up to 50, 2 above 50, 3 above
    80, 4 above 110, 5 above 140, 6 above 170."""
    gear = 1
    for threshold in _SPEED_GEAR_KMH:
        if speed_kmh > threshold:
            gear += 1
    return gear


def rpm_gear(gear: int, rpm: float) -> int:
    """The SCR sample driver's rule: next gear from the current gear and SCR `rpm` (engine
    rad/s x 10). Neutral or reverse go to first; shift up at 5000/6000/6000/6500/7000 from gears
    1-5, down at 2500/3000/3000/3500/3500 from gears 2-6."""
    gear = int(gear)
    if gear < 1:
        return 1
    if gear < 6 and rpm >= _GEAR_UP_RPM[gear - 1]:
        return gear + 1
    if gear > 1 and rpm <= _GEAR_DOWN_RPM[gear - 2]:
        return gear - 1
    return gear


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
        self.reset()

    def reset(self) -> None:
        """Clear the integral and the previous error."""
        self.integral = 0.0
        self.prev_error = 0.0
        self._first = True

    def __call__(self, error: float) -> float:
        """Advance one tick with this error and return the output."""
        if self._first and self.kick_free:
            self.prev_error = error
        self._first = False
        derivative = error - self.prev_error
        self.prev_error = error
        integral = self.integral + error
        out = self.kp * error + self.ki * integral + self.kd * derivative
        if self.limits is not None:
            low, high = self.limits
            if (out > high and error > 0.0) or (out < low and error < 0.0):
                integral = self.integral                      # hold: no wind-up
                out = self.kp * error + self.ki * integral + self.kd * derivative
        self.integral = integral
        return out


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
        self.reset()

    @classmethod
    def from_config(cls, pid) -> PIDController:
        """From a config's PidConfig (gains, scales, madras_compat)."""
        return cls(pid.accel_gains, pid.steer_gains, accel_scale=pid.accel_scale,
                   steer_scale=pid.steer_scale, madras_compat=pid.madras_compat)

    def reset(self, row: Mapping | None = None) -> None:
        """Start an episode. The fixed controller takes its state from `row` (the first
        observation); MADRaS (and a None row) starts from trackPos = angle = speed = 0."""
        self.accel_pid.reset()
        self.steer_pid.reset()
        self.prev_lane = self.prev_angle = self.prev_vel = 0.0
        if row is not None and not self.compat:
            self.update(row)

    def update(self, row: Mapping) -> None:
        """Store the observation the next action is computed from (one car's SCR row)."""
        self.prev_lane = float(row["trackPos"])
        self.prev_angle = float(row["angle"]) / math.pi
        self.prev_vel = float(row["speedX"]) / SPEED_UNIT_KMH

    def get_action(self, lane_des: float, speed_des_kmh: float) -> tuple[float, float, float]:
        """(steer, accel, brake) towards a track position and a speed in km/h."""
        steer_error = self.prev_angle - (self.prev_lane - lane_des) * self.steer_scale
        accel_error = (speed_des_kmh / SPEED_UNIT_KMH - self.prev_vel) * self.accel_scale
        steer = self.steer_pid(steer_error)
        accel = self.accel_pid(accel_error)
        if self.compat:
            return steer, accel, (1.0 if accel < 0.0 else 0.0)
        return (min(1.0, max(-1.0, steer)), min(1.0, max(0.0, accel)),
                min(1.0, max(0.0, -accel)))


class TrackSpeedController:
    """A T-S action -> desired (trackPos, km/h) -> SCR controls, one call per tick.

    Action (a0, a1): normalised, both in [-1, 1]: lane = low + (high - low) (a0 + 1) / 2 over
    `track_limits`, speed = a1 * target_speed (m/s); not normalised: a0 is the trackPos and a1
    the speed in km/h. Use: `set_action(a)` once per env step, `act(row)` every tick with the
    latest observation; `act` returns np.array([steer, accel, brake, gear]) (gear from
    `speed_gear`, MADRaS's gearbox; the env overrides it in manual mode).
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
        a0, a1 = float(action[0]), float(action[1])
        if not self.normalised:
            return a0, a1
        low, high = self.track_limits
        if self.pid.compat:
            lane = low + (high - low) * a0          # MADRaS master (spec 6.2, bug 15)
        else:
            lane = low + (high - low) * (a0 + 1.0) / 2.0
        return lane, a1 * self.target_speed * 3.6

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
