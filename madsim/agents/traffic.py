"""Traffic cars: programmable behaviours on one base class (spec madras-features.md section 4).

A behaviour turns one car's SCR sensors into controls, one call per 0.02 s tick:

    b = BEHAVIOURS["ConstVel"](target_speed=13.89, lane=-0.5)
    b.reset(rng, info)                       # episode start; draws go into `info`
    steer, accel, brake, gear = b.act(row)   # row: SensorFrame.row(k) or a decoded UDP state

The row is all a behaviour sees, so the same object drives a car in-process or as a UDP client
of any scr_server. It assumes SCR's default rangefinder angles (track[0] 90 deg left, track[9]
ahead, track[18] 90 deg right); UDP clients must ask for them.

A subclass only says where it wants to be: `target(row, t_s) -> (lane, speed)`, lane in trackPos
units (+1 left edge, -1 right edge), speed in m/s; a speed <= 0 means stop and hold the brake.
`TrafficBehaviour.act` does the driving: the T-S PID controller (madsim.agents.pid) towards the
lane and speed, plus what MADRaS's traffic lacked or got wrong (spec section 4):
- collision avoidance (`gaps_ahead`): cars in the front half of the opponents sensor
  (symmetric; MADRaS used sectors 16-18, 20 deg left to 10 deg right) that are in the own path
  (own lane and any lane it is moving to, bent with the road) cap the speed at
  (gap - min_safe_dist) / collision_time_window, so a follower keeps min_safe_dist + window x
  speed; closer than min_safe_dist it brakes fully. The PID's own braking is kept otherwise
  (MADRaS overwrote it with brake = 0);
- off-track prevention (`_guard`): a car heading for the near edge (reached within 0.5 s), or
  within min_safe_dist of it outside its lane, steers back towards the road, not towards the
  nearer edge as MADRaS did; off the road it drives back to the centre at walking pace;
- bends: the speed is capped by the free road ahead (track[7..11]) and by the road curvature,
  which an observer estimates from the own steering and the rate of `angle`; the same
  estimate steers forward and corrects `angle` for the kinematic sideslip, so a car holds its
  lane within ~0.1 through a 12 m radius bend (the PID alone drifts ~1 there);
- lane changes move at most LANE_SPEED sideways; a behaviour can ask `side_clear` first.
Randomness comes only from the rng given to `reset`.

New behaviours: subclass, implement `target`, decorate with `@register_behaviour("Name")`
(docs/traffic.md). `make_behaviour(entry)` builds one from a config TrafficConfig.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from madsim.agents.pid import PIDController, speed_gear

__all__ = ["BEHAVIOURS", "CarGeometry", "ConstVel", "DriveAndPark", "Parked", "RandomLaneSwitch",
           "RandomStopping", "SinusoidalSpeed", "TrafficBehaviour", "draw_traffic_placements",
           "make_behaviour", "register_behaviour"]

TICK_S = 0.02
KMH = 3.6
NO_CAR_M = 200.0                     # opponents sensor value of an empty sector
BEHAVIOURS: dict[str, type[TrafficBehaviour]] = {}


def register_behaviour(name: str):
    """Class decorator: make a TrafficBehaviour subclass available as `name` (config
    `behaviour:` and `madsim traffic --behaviour`). Registering a second class under a taken
    name is an error; re-registering the same class (a module reload) is not."""
    def decorate(cls):
        if not (isinstance(cls, type) and issubclass(cls, TrafficBehaviour)):
            raise TypeError(f"register_behaviour({name!r}): {cls!r} is not a TrafficBehaviour subclass")
        old = BEHAVIOURS.get(name)
        if old is not None and (old.__module__, old.__qualname__) != (cls.__module__, cls.__qualname__):
            raise ValueError(f"traffic behaviour {name!r} is already registered ({old.__qualname__})")
        BEHAVIOURS[name] = cls
        cls.behaviour_name = name
        return cls
    return decorate


@dataclass(frozen=True)
class CarGeometry:
    """What a behaviour needs of its car, m and rad (defaults: madsim-sedan)."""

    length_m: float = 4.78
    width_m: float = 1.84
    wheelbase_m: float = 2.85
    rear_axle_m: float = 1.51        # CG to rear axle
    steer_lock_rad: float = 0.5236

    @classmethod
    def of(cls, car) -> CarGeometry:
        """From None (defaults), a CarSpec, or a car name/path (loaded with madsim.cars)."""
        if car is None:
            return cls()
        if isinstance(car, CarGeometry):
            return car
        if isinstance(car, str):
            return _geometry_of_name(car)
        return cls(float(car.body_length), float(car.body_width), float(car.wheelbase),
                   float(car.b), float(car.steer_lock))


@functools.lru_cache(maxsize=64)
def _geometry_of_name(name: str) -> CarGeometry:
    from madsim.cars import load_car
    return CarGeometry.of(load_car(name))


# (cos, sin) of five bearings spanning each opponents sector j, [(j - 18) * 10, (j - 17) * 10] deg
_SUB_BEARINGS = tuple(tuple((math.cos(math.radians((j - 18) * 10.0 + 2.5 * k)),
                             math.sin(math.radians((j - 18) * 10.0 + 2.5 * k))) for k in range(5))
                      for j in range(36))


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class TrafficBehaviour:
    """Base class: sensor row -> (steer, accel, brake, gear) through the PID controller.

    Args: pid (default: MADRaS's gains), collision_time_window (s, following headway),
    min_safe_dist (m, bumper gap kept to a car ahead and margin kept to the road edge),
    car (name, CarSpec or CarGeometry; overridden by info["car"] at reset).
    Subclasses implement `target` and may override `setup` (draws at reset).
    """

    behaviour_name = "TrafficBehaviour"
    FRONT_CONE_DEG = 90.0        # half angle of the opponents cone used for braking
    LATERAL_MARGIN_M = 0.4       # side clearance added to a car width when testing "in my path"
    PLAN_DECEL = 3.0             # m/s^2 used to anticipate corners and to plan stops
    LAT_ACCEL = 4.0              # m/s^2 allowed in corners
    LANE_SPEED = 1.0             # m/s: how fast the lane target may move sideways
    CURVATURE_TAU_S = 0.25       # time constant of the road curvature observer
    HOLD_SPEED = 0.3             # m/s below which a stopping car holds the brake
    GUARD_HORIZON_S = 0.5        # lateral look-ahead of the off-track guard
    GUARD_SPEED = 3.0            # m/s: speed while off the road
    CREEP_SPEED = 1.0            # m/s towards a car that is possibly, not surely, in the path
    CREEP_GAP_M = 0.3            # ... down to this bumper gap

    def __init__(self, *, pid: PIDController | None = None, collision_time_window: float = 1.0,
                 min_safe_dist: float = 1.0, car=None):
        if not collision_time_window > 0 or not min_safe_dist >= 0:
            raise ValueError("collision_time_window must be > 0 and min_safe_dist >= 0")
        self.pid = pid if pid is not None else PIDController()
        self.window_s = float(collision_time_window)
        self.min_safe_dist = float(min_safe_dist)
        self._car = car
        self.params: dict[str, Any] = {}
        self.info: dict = {}

    # --- the interface the env and the UDP client use --------------------------------------

    def reset(self, rng: np.random.Generator, info: dict | None = None) -> None:
        """Start an episode. info (read: track_length m, track_width m, car, tick_s, placement
        (s m, n m); written: behaviour, params and every draw)."""
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        self.rng = rng
        self.info = info = {} if info is None else info
        self.tick_s = float(info.get("tick_s", TICK_S))
        self.geometry = CarGeometry.of(info.get("car", self._car))
        length, width = info.get("track_length"), info.get("track_width")
        self.track_length = float(length) if length else None
        self.half_width = float(width) / 2.0 if width else None
        self.pid.reset(None)
        self.ticks = 0
        self._steer = 0.0
        self._kappa = 0.0
        self._angle_prev: float | None = None
        self._lane_cmd: float | None = None
        self._dist0: float | None = None
        self._dfs0 = self._dfs_prev = 0.0
        self.travelled = 0.0
        info["behaviour"] = self.behaviour_name
        info["params"] = dict(self.params)
        self.setup(rng, info)

    def act(self, row: Mapping) -> tuple[float, float, float, int]:
        """Controls for the coming tick from the latest sensors (SCR names and units)."""
        if row["curLapTime"] < 0.0:               # TORCS countdown: wait, the clock has not started
            return 0.0, 0.0, 1.0, 1
        t_s = self.ticks * self.tick_s
        self.ticks += 1
        self._observe(row)
        lane, speed = self.target(row, t_s)
        return self._drive(row, float(lane), float(speed))

    # --- for subclasses --------------------------------------------------------------------

    def setup(self, rng: np.random.Generator, info: dict) -> None:
        """Per-episode draws (from rng only; write them into info)."""

    def target(self, row: Mapping, t_s: float) -> tuple[float, float]:
        """(lane in trackPos units, speed in m/s; <= 0: stop) at time t_s since the start."""
        raise NotImplementedError

    def side_clear(self, row: Mapping, to_left: bool) -> bool:
        """No car beside the own car on that side, from 170 deg behind to 10 deg ahead, within
        two car lengths (use before a lane change)."""
        opp = row["opponents"]
        sectors = range(1, 17) if to_left else range(19, 35)
        reach = 2.0 * self.geometry.length_m
        return all(opp[j] >= reach for j in sectors)

    # --- the driving -----------------------------------------------------------------------

    def _observe(self, row: Mapping) -> None:
        """Road half width (if not given), odometry and the curvature observer."""
        track = row["track"]
        tpos, angle = float(row["trackPos"]), float(row["angle"])
        if self.half_width is None and abs(tpos) < 1.0 and track[0] > 0 and track[18] > 0:
            self.half_width = 0.5 * (track[0] + track[18]) * abs(math.cos(angle))
        dist, dfs = float(row["distRaced"]), float(row["distFromStart"])
        if self._dist0 is None:
            self._dist0, self._dfs0 = dist, dfs
        elif self.track_length is None and dfs < self._dfs_prev - 50.0:   # crossed the line
            self.track_length = self._dfs0 + (dist - self._dist0) - dfs
        self._dfs_prev = dfs
        self.travelled = dist - self._dist0
        v = float(row["speedX"]) / KMH
        if self._angle_prev is not None and v > 2.0:
            # d(angle)/dt = kappa_road * v - yaw rate, yaw rate = v * tan(wheel angle) / wheelbase
            g = self.geometry
            kappa_car = math.tan(self._steer * g.steer_lock_rad) / g.wheelbase_m
            raw = kappa_car + _wrap(angle - self._angle_prev) / (v * self.tick_s)
            self._kappa += min(1.0, self.tick_s / self.CURVATURE_TAU_S) * (raw - self._kappa)
        self._angle_prev = angle

    def gaps_ahead(self, row: Mapping, lanes=(), max_range_m: float = NO_CAR_M) -> tuple[float, float]:
        """Bumper gaps (m, along the road; inf if none) to the nearest car ahead that is surely
        and that is possibly in the own path.

        Every sector of the front half (+-FRONT_CONE_DEG) is turned into the road frame with
        `angle`. Its car is possibly in the path if, at some bearing of the sector's 10 degrees
        and some road curvature between 0 and the estimate, its lateral offset from the own lane
        line comes within a car width plus LATERAL_MARGIN_M of the band between the own position
        and `lanes` (trackPos units, where the car is going); surely, if so at the sector's centre
        bearing for both curvatures. Ten-degree sectors cannot tell 1.8 m from 2.5 m beside at
        10 m, hence the two answers: the first stops the car, the second lets it creep. Cars
        farther than max_range_m (centre distance) are ignored."""
        opp = row["opponents"]
        g = self.geometry
        reach = g.width_m + self.LATERAL_MARGIN_M
        shifts = [0.0]
        if self.half_width:
            shifts += [(lane - float(row["trackPos"])) * self.half_width for lane in lanes]
        lo_edge, hi_edge = min(shifts) - reach, max(shifts) + reach
        k_lo, k_hi = self._curvature_range(row)
        heading = float(row["angle"])                   # car points this far right of the road
        cos_h, sin_h = math.cos(heading), math.sin(heading)
        n_side = round(self.FRONT_CONE_DEG / 10.0)
        max_range_m = min(max_range_m, NO_CAR_M)
        sure = possible = math.inf
        for j in range(18 - n_side, 18 + n_side):
            d = float(opp[j])
            if d >= max_range_m or d <= 0.0:
                continue
            for step, (cos_b, sin_b) in enumerate(_SUB_BEARINGS[j]):    # across the sector
                x = d * (cos_b * cos_h - sin_b * sin_h)                # along the road
                y = -d * (sin_b * cos_h + cos_b * sin_h)               # to the left
                if x <= 0.0:
                    continue
                e_hi, e_lo = y - k_lo * 0.5 * x * x, y - k_hi * 0.5 * x * x
                if e_lo <= hi_edge and e_hi >= lo_edge:
                    possible = min(possible, x - g.length_m)
                    if step == 2 and lo_edge <= e_lo and e_hi <= hi_edge:
                        sure = min(sure, x - g.length_m)
        return sure, possible

    def _curvature_range(self, row: Mapping) -> tuple[float, float]:
        """Road curvatures (1/m, left +) to allow for ahead: between 0 and the estimate, cut to
        what the free ray straight ahead (track[9], length D) allows: a road of curvature k
        keeps the ray inside only if |y0 - angle D - k D^2 / 2| <= half width (y0: own offset)."""
        lo, hi = min(0.0, self._kappa), max(0.0, self._kappa)
        ahead, hw = float(row["track"][9]), self.half_width
        if ahead <= 0.0 or not hw:
            return lo, hi
        y0 = float(row["trackPos"]) * hw - float(row["angle"]) * ahead
        ray_lo, ray_hi = 2.0 * (y0 - hw) / ahead ** 2, 2.0 * (y0 + hw) / ahead ** 2
        lo, hi = max(lo, ray_lo), min(hi, ray_hi)
        if lo > hi:
            lo = hi = min(max(self._kappa, ray_lo), ray_hi)
        return lo, hi

    def _speed_cap(self, row: Mapping) -> float:
        """m/s allowed by the road: stop before the road edge ahead (the
        longest ray within 10 deg of ahead), limit the corner acceleration."""
        ahead = max(row["track"][7:12])                   # free road within 10 deg of ahead
        cap = math.inf
        if ahead > 0.0:
            cap = math.sqrt(2.0 * self.PLAN_DECEL * max(ahead - self.min_safe_dist, 0.0))
        if abs(self._kappa) > 1e-6:
            cap = min(cap, math.sqrt(self.LAT_ACCEL / abs(self._kappa)))
        return max(cap, self.GUARD_SPEED)

    def _guard(self, row: Mapping, lane: float, v: float) -> tuple[float, bool] | None:
        """(lane towards the road, cut the throttle) if the car is leaving the road, else None.

        Off the road: back to the centre at GUARD_SPEED. Heading for the near edge, reached
        within GUARD_HORIZON_S at the present lateral speed: steer back, no throttle. Within
        min_safe_dist of the edge and outside its own lane: steer back to the lane."""
        tpos = float(row["trackPos"])
        if abs(tpos) >= 1.0:
            return 0.0, False
        side = 1.0 if tpos > 0.0 else -1.0
        hw = self.half_width or 1.0
        edge_m = (1.0 - abs(tpos)) * hw
        outward = -side * v * math.sin(float(row["angle"]))     # m/s towards the near edge
        inside = abs(tpos) - 0.3
        if edge_m < outward * self.GUARD_HORIZON_S:
            return side * (max(lane * side, inside) if lane * side < abs(tpos) else inside), True
        if edge_m < self.min_safe_dist and lane * side < abs(tpos) - 0.05:
            return side * max(lane * side, inside), False
        return None

    def _drive(self, row: Mapping, lane: float, speed: float) -> tuple[float, float, float, int]:
        g = self.geometry
        v = float(row["speedX"]) / KMH
        tpos = float(row["trackPos"])
        if self._lane_cmd is None:
            self._lane_cmd = max(-1.0, min(1.0, tpos))
        step = self.LANE_SPEED * self.tick_s / (self.half_width or 5.0)
        self._lane_cmd += max(-step, min(step, lane - self._lane_cmd))
        lane_des = self._lane_cmd
        stopping = speed <= 0.0
        relevant = g.length_m + self.min_safe_dist + self.window_s * max(speed, v) + 5.0
        sure, possible = self.gaps_ahead(row, (lane, lane_des), relevant)
        s0 = self.min_safe_dist
        creep = self.CREEP_SPEED if possible > self.CREEP_GAP_M else 0.0
        v_des = min(max(speed, 0.0), self._speed_cap(row), max(0.0, (sure - s0) / self.window_s),
                    max(creep, (possible - s0) / self.window_s))
        blocked = sure < s0 or possible < self.CREEP_GAP_M
        guard = self._guard(row, lane_des, v)
        cut = False
        if guard is not None:
            lane_des, cut = guard
            if abs(tpos) >= 1.0:
                v_des = min(v_des, self.GUARD_SPEED)
        # In a bend the CG moves at the kinematic sideslip atan(b kappa) to the heading; the PID
        # gets the angle of the motion, or it would hold the car off its lane by that angle.
        slip = math.atan(g.rear_axle_m * self._kappa)
        self.pid.update({"trackPos": tpos, "angle": float(row["angle"]) - slip,
                         "speedX": float(row["speedX"])})
        steer, accel, brake = self.pid.get_action(lane_des, v_des * KMH)
        steer += math.atan(g.wheelbase_m * self._kappa) / g.steer_lock_rad
        steer = max(-1.0, min(1.0, steer))
        if stopping or cut:
            accel = 0.0
        if (stopping and v < self.HOLD_SPEED) or blocked:
            accel, brake = 0.0, 1.0
        if stopping and v < self.HOLD_SPEED:
            steer = 0.0
        self._steer = steer
        return steer, accel, brake, speed_gear(float(row["speedX"]))


# --- the built-in behaviours (parameters: madsim.envs.config.TRAFFIC_PARAMS, SI units) --------


@register_behaviour("ConstVel")
class ConstVel(TrafficBehaviour):
    """Constant speed (m/s) in a constant lane (trackPos units)."""

    def __init__(self, target_speed: float = 13.89, lane: float = 0.0, **base):
        super().__init__(**base)
        self.params = {"target_speed": float(target_speed), "lane": float(lane)}

    def target(self, row, t_s):
        return self.params["lane"], self.params["target_speed"]


@register_behaviour("SinusoidalSpeed")
class SinusoidalSpeed(TrafficBehaviour):
    """speed = mean_speed + speed_amplitude sin(2 pi t / speed_period) (m/s, s) in a lane;
    t from the first tick. MADRaS oscillated around 0; this oscillates around the mean."""

    def __init__(self, mean_speed: float = 13.89, speed_amplitude: float = 13.89,
                 speed_period: float = 125.66, lane: float = 0.0, **base):
        super().__init__(**base)
        if not speed_period > 0:
            raise ValueError(f"speed_period must be > 0 s, got {speed_period}")
        self.params = {"mean_speed": float(mean_speed), "speed_amplitude": float(speed_amplitude),
                       "speed_period": float(speed_period), "lane": float(lane)}

    def target(self, row, t_s):
        p = self.params
        return p["lane"], p["mean_speed"] + p["speed_amplitude"] * math.sin(
            2.0 * math.pi * t_s / p["speed_period"])


@register_behaviour("RandomLaneSwitch")
class RandomLaneSwitch(TrafficBehaviour):
    """Every lane_change_interval s (from t = 0) pick one of `lanes` uniformly at random and
    drive there at target_speed. A move waits while the side it goes to is not clear.
    info["lane_draws"]: [(t_s, lane)] per draw."""

    def __init__(self, target_speed: float = 27.78, lane_change_interval: float = 0.1,
                 lanes=(-0.75, 0.75), **base):
        super().__init__(**base)
        if not lane_change_interval > 0:
            raise ValueError(f"lane_change_interval must be > 0 s, got {lane_change_interval}")
        self.params = {"target_speed": float(target_speed),
                       "lane_change_interval": float(lane_change_interval),
                       "lanes": tuple(float(x) for x in lanes)}

    def setup(self, rng, info):
        self.lane: float | None = None
        self.wanted = 0.0
        self.draws = info["lane_draws"] = []

    def target(self, row, t_s):
        p = self.params
        if t_s >= len(self.draws) * p["lane_change_interval"] - 1e-9:
            lanes = p["lanes"]
            self.wanted = lanes[int(self.rng.integers(len(lanes)))]
            self.draws.append((t_s, self.wanted))
        if self.lane is None:
            self.lane = float(row["trackPos"])
        if self.wanted != self.lane and self.side_clear(row, self.wanted > self.lane):
            self.lane = self.wanted
        return self.lane, p["target_speed"]


@register_behaviour("RandomStopping")
class RandomStopping(TrafficBehaviour):
    """Drive at target_speed in a lane; while driving, with stop_probability per tick, halt and
    stand still for a duration ~ U(0, max_stop_duration] s (counted from the standstill), then
    drive on. No throttle while halting. info["stops"]: [(t_s, duration_s)] per halt."""

    def __init__(self, target_speed: float = 13.89, lane: float = 0.0, stop_probability: float = 0.1,
                 max_stop_duration: float = 0.1, **base):
        super().__init__(**base)
        if not 0.0 <= stop_probability <= 1.0:
            raise ValueError(f"stop_probability must be in [0, 1], got {stop_probability}")
        self.params = {"target_speed": float(target_speed), "lane": float(lane),
                       "stop_probability": float(stop_probability),
                       "max_stop_duration": float(max_stop_duration)}

    def setup(self, rng, info):
        self.stand_s: float | None = None      # standstill still to come; None: driving
        self.stops = info["stops"] = []

    def target(self, row, t_s):
        p = self.params
        if self.stand_s is None and self.rng.random() < p["stop_probability"]:
            self.stand_s = p["max_stop_duration"] * (1.0 - self.rng.random())   # (0, max]
            self.stops.append((t_s, self.stand_s))
        if self.stand_s is not None:
            if float(row["speedX"]) / KMH < self.HOLD_SPEED:
                self.stand_s -= self.tick_s
                if self.stand_s <= 0.0:
                    self.stand_s = None
            if self.stand_s is not None:
                return p["lane"], 0.0
        return p["lane"], p["target_speed"]


@register_behaviour("DriveAndPark")
class DriveAndPark(TrafficBehaviour):
    """Drive at target_speed in the parking lane to the parking distance from the start line
    (m, the next time the car gets there) and park: brake held from then on. Lane and distance
    are drawn uniformly from their ranges at reset (info["parking_lane"], ["parking_distance"])."""

    STOP_TOLERANCE_M = 0.25

    def __init__(self, target_speed: float = 13.89, parking_lane=(-0.8, 0.0),
                 parking_distance=(185.0, 200.0), **base):
        super().__init__(**base)
        self.params = {"target_speed": float(target_speed),
                       "parking_lane": tuple(float(x) for x in parking_lane),
                       "parking_distance": tuple(float(x) for x in parking_distance)}

    def setup(self, rng, info):
        self.lane = float(rng.uniform(*self.params["parking_lane"]))
        self.distance = float(rng.uniform(*self.params["parking_distance"]))
        info["parking_lane"], info["parking_distance"] = self.lane, self.distance
        self.parked = False
        self.to_go: float | None = None        # m from the first tick's position to the spot

    def remaining(self, row) -> float:
        """m still to drive to the parking spot (inf while the track length is unknown and
        the spot lies beyond the start line)."""
        if self.to_go is None:
            d = self.distance - self._dfs0
            if d < 0.0 and self.track_length is None:
                return math.inf
            self.to_go = d % self.track_length if self.track_length else d
        return self.to_go - self.travelled

    def target(self, row, t_s):
        rem = self.remaining(row)
        if not self.parked and (rem <= self.STOP_TOLERANCE_M or (
                rem < 1.0 and float(row["speedX"]) / KMH < self.HOLD_SPEED)):
            self.parked = True
        if self.parked:
            return self.lane, 0.0
        speed = min(self.params["target_speed"], math.sqrt(2.0 * self.PLAN_DECEL * max(rem, 0.0)))
        return self.lane, max(speed, 0.5)


@register_behaviour("Parked")
class Parked(TrafficBehaviour):
    """Stands where it was placed from the first tick: no throttle, brake held."""

    def target(self, row, t_s):
        return float(row["trackPos"]), 0.0


# --- building and placing ----------------------------------------------------------------------


def make_behaviour(entry) -> TrafficBehaviour:
    """A behaviour from one config traffic entry (madsim.envs.config.TrafficConfig: behaviour,
    params, pid, collision_time_window, min_safe_dist, car)."""
    try:
        cls = BEHAVIOURS[entry.behaviour]
    except KeyError:
        raise ValueError(f"unknown traffic behaviour {entry.behaviour!r}; registered: "
                         f"{', '.join(sorted(BEHAVIOURS))}") from None
    pid = PIDController.from_config(entry.pid) if getattr(entry, "pid", None) is not None else None
    return cls(**dict(entry.params), pid=pid, collision_time_window=entry.collision_time_window,
               min_safe_dist=entry.min_safe_dist, car=entry.car)


def draw_traffic_placements(entries, count, rng: np.random.Generator, track, *,
                            car_length_m: float = 4.78, car_width_m: float = 1.84,
                            min_gap_m: float = 1.0, max_tries: int = 1000):
    """Traffic of one episode as the paper's Appendix C draws it.

    count: (min, max) -> n ~ discrete uniform on [min, max]; None -> every entry; the first n
    entries drive. Car i: s ~ U(entries[i].initial_distance) (m from the start line), trackPos
    ~ U(entries[i].initial_trackpos) (n = trackPos x half width), each only if given, else its
    grid slot. A draw that would overlap a car placed before it (footprints plus min_gap_m) is
    redrawn, so with crowded ranges the draws are uniform conditional on no overlap.
    Returns (entries used, placements (n, 3) of s m, n m, speed 0)."""
    from madsim.physics.tables import grid_positions
    entries = list(entries)
    if count is None:
        n = len(entries)
    else:
        low, high = int(count[0]), int(count[1])
        if not 0 <= low <= high <= len(entries):
            raise ValueError(f"traffic count range {list(count)} needs 0 <= min <= max <= "
                             f"{len(entries)} (the traffic entries)")
        n = int(rng.integers(low, high + 1))
    used = entries[:n]
    s_grid, n_grid = grid_positions(track, n) if n else (np.zeros(0), np.zeros(0))
    out = np.zeros((n, 3))
    half_width, length = track.width / 2.0, track.length
    for i, entry in enumerate(used):
        dist, tpos = getattr(entry, "initial_distance", None), getattr(entry, "initial_trackpos", None)
        for _ in range(max_tries):
            s = float(np.mod(rng.uniform(*dist), length)) if dist is not None else s_grid[i]
            lat = float(rng.uniform(*tpos)) * half_width if tpos is not None else n_grid[i]
            ds = np.abs(np.mod(out[:i, 0] - s + length / 2.0, length) - length / 2.0)
            clash = (ds < car_length_m + min_gap_m) & (np.abs(out[:i, 1] - lat) < car_width_m + min_gap_m)
            if not clash.any():
                break
            if dist is None and tpos is None:
                raise ValueError(f"traffic[{i}] ({entry.behaviour}): its grid slot overlaps a car "
                                 "placed before it")
        else:
            raise ValueError(f"traffic[{i}] ({entry.behaviour}): no place without overlap in "
                             f"{max_tries} draws of initial_distance / initial_trackpos")
        out[i, 0], out[i, 1] = s, lat
    return used, out
