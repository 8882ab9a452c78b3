"""The built-in drivers of `madsim run`: one per action space, both reading one car's SCR row.

In madsim a driver is whatever chooses a car's actions from its sensors: these built-in ones, a
trained policy (`madsim run --driver`), the SCR client's `madsim.net.client.simple_driver`, or
a TORCS robot (TORCS's own word for the same thing).

`builtin_driver(agent)` returns a callable row -> action that fits the agent's action space:
- T-S (`TrackSpeedDriver`): speed from the free road ahead, lane 0 unless a car is close
  ahead, then the side with more room; output (trackPos, km/h), or normalised.
- S-A-B (`PedalDriver`): the same lane and speed choice, reached with steering and pedals
  (steer to the lane, throttle proportional to the speed error, brake above it); output
  (steer, accel, brake), or normalised; a manual-gear agent gets MADRaS's speed gear.
"""

from __future__ import annotations

import math

import numpy as np

SAFE_DECEL_MS2 = 5.0        # braking rate the built-in drivers plan with, m/s^2
MIN_SPEED_KMH = 30.0
FRONT_SECTORS = (16, 17, 18, 19)   # opponents sectors within +-20 degrees of the nose
SIDE_SECTORS = tuple(range(6, 30))  # -120..+120 degrees: alongside or ahead
LEFT_SECTORS = tuple(range(7, 16))  # -110..-20 degrees: alongside on the left
RIGHT_SECTORS = tuple(range(20, 29))  # +20..+110 degrees: alongside on the right
PASS_LANE = 0.6
RECOVERY_SPEED_KMH = 20.0
STEER_LOCK_RAD = 0.366519   # the C++ SimpleDriver's steer lock (net.client.simple_driver)

__all__ = ["PedalDriver", "TrackSpeedDriver", "builtin_driver"]


class TrackSpeedDriver:
    """The built-in driver for a T-S action space: speed from the free road ahead
    (v <= sqrt(2 a d), a = SAFE_DECEL_MS2, d = longest of the three forward rangefinders), lane
    0 unless a car is close ahead, then the side with more room. Output: (trackPos, km/h)."""

    def __init__(self, top_speed_kmh: float, normalised: bool, target_speed_ms: float):
        self.top_speed_kmh = top_speed_kmh
        self.normalised = normalised
        self.target_speed_ms = target_speed_ms
        self.lane = 0.0

    def plan(self, row) -> tuple[float, float]:
        """(lane as trackPos, speed km/h) for this row; updates the remembered lane."""
        rays = row["track"]
        on_road = min(rays) >= 0
        ahead = max(rays[8], rays[9], rays[10]) if on_road else 0.0
        speed = min(self.top_speed_kmh, max(MIN_SPEED_KMH, 3.6 * math.sqrt(2 * SAFE_DECEL_MS2 * ahead)))
        opp = row["opponents"]
        left_clear = min(opp[k] for k in LEFT_SECTORS) > 8.0
        right_clear = min(opp[k] for k in RIGHT_SECTORS) > 8.0
        j = min(FRONT_SECTORS, key=lambda k: opp[k])
        close = opp[j]
        if not on_road:
            self.lane, speed = 0.0, RECOVERY_SPEED_KMH      # back onto the road, gently
        elif close < 50.0:
            # pass on the side away from the car ahead (sectors 16-17 are left of the nose),
            # if nobody is alongside there; otherwise wait behind it
            want = -PASS_LANE if j in (16, 17) else PASS_LANE
            if (want > 0 and left_clear) or (want < 0 and right_clear):
                self.lane = want
            if close < 20.0 and j in (17, 18):               # right behind it: do not run into it
                speed = min(speed, max(MIN_SPEED_KMH, 2.5 * close))
        elif min(opp[k] for k in SIDE_SECTORS) > 15.0:
            self.lane = 0.0                                   # nobody alongside: back to the centre
        if not left_clear and right_clear:                    # someone squeezing from the left
            self.lane = min(self.lane, 0.0) - 0.2
        elif not right_clear and left_clear:
            self.lane = max(self.lane, 0.0) + 0.2
        self.lane = max(-0.8, min(0.8, self.lane))
        return self.lane, speed

    def __call__(self, row) -> np.ndarray:
        lane, speed = self.plan(row)
        if self.normalised:   # [-1, 1] over track limits (-1, 1) and +-target speed
            return np.array([lane, speed / 3.6 / self.target_speed_ms], dtype=np.float32)
        return np.array([lane, speed], dtype=np.float32)


class PedalDriver:
    """The built-in driver for an S-A-B action space: TrackSpeedDriver's lane and speed, reached
    by steering (angle - 0.5 (trackPos - lane)) / steer lock and pedals (throttle error/20 + 0.2
    below the speed, brake beyond 5 km/h over it). Output: (steer, accel, brake[, gear])."""

    def __init__(self, top_speed_kmh: float, normalised: bool, manual_gear: bool):
        self.planner = TrackSpeedDriver(top_speed_kmh, False, top_speed_kmh / 3.6)
        self.normalised = normalised
        self.manual_gear = manual_gear

    def __call__(self, row) -> np.ndarray:
        from madsim.agents.pid import speed_gear

        lane, target_kmh = self.planner.plan(row)
        steer = (row["angle"] - 0.5 * (row["trackPos"] - lane)) / STEER_LOCK_RAD
        steer = max(-1.0, min(1.0, steer)) if math.isfinite(steer) else 0.0
        error = target_kmh - row["speedX"]
        accel = max(0.0, min(1.0, error / 20.0 + 0.2)) if error > 0 else 0.0
        brake = max(0.0, min(1.0, (-error - 5.0) / 20.0)) if error < -5.0 else 0.0
        action = [steer, accel, brake]
        if self.normalised:
            action = [steer, 2.0 * accel - 1.0, 2.0 * brake - 1.0]
        if self.manual_gear:
            gear = speed_gear(max(0.0, row["speedX"]))
            action.append((gear + 1) / 3.5 - 1.0 if self.normalised else float(gear))
        return np.array(action, dtype=np.float32)


def builtin_driver(agent):
    """The built-in driver fitting an `AgentConfig`'s action space: a callable row -> action."""
    action = agent.action
    if action.space == "TS":
        return TrackSpeedDriver(min(action.max_speed_kmh, agent.target_speed * 3.6), action.normalised,
                                agent.target_speed)
    return PedalDriver(min(action.max_speed_kmh, agent.target_speed * 3.6), action.normalised,
                       agent.gear == "manual")
