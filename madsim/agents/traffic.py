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
The driving, compiled over all traffic cars at once (madsim.agents.traffic_kernel, run by a
`TrafficFleet`; `act` is a fleet of one): the T-S PID controller (madsim.agents.pid's gains)
towards the lane and speed, plus what MADRaS's traffic lacked or got wrong (spec section 4):
- collision avoidance: cars in the front half of the opponents sensor
  (symmetric; MADRaS used sectors 16-18, 20 deg left to 10 deg right) that are in the own path
  (own lane and any lane it is moving to, bent with the road) cap the speed at
  (gap - min_safe_dist) / collision_time_window, so a follower keeps min_safe_dist + window x
  speed; closer than min_safe_dist it brakes fully. The PID's own braking is kept otherwise
  (MADRaS overwrote it with brake = 0);
- off-track prevention: a car heading for the near edge (reached within 0.5 s), or
  within min_safe_dist of it outside its lane, steers back towards the road, not towards the
  nearer edge as MADRaS did; off the road it drives back to the centre at walking pace;
- bends: the speed is capped by the free road ahead (track[7..11]) and by the road curvature,
  which an observer estimates from the own steering and the rate of `angle`; the same
  estimate steers forward and corrects `angle` for the kinematic sideslip, so a car holds its
  lane within ~0.1 through a 12 m radius bend (the PID alone drifts ~1 there);
- lane changes move at most LANE_SPEED sideways; a behaviour can ask `side_clear` first.
Randomness comes only from the rng given to `reset` (taken 64 draws at a time, in the order
the behaviour consumes them).

New behaviours: subclass, implement `target`, decorate with `@register_behaviour("Name")`
(docs/traffic.md); their `target` runs in Python (~5-10 us per car and tick), the driving
stays compiled. `make_behaviour(entry)` builds one from a config TrafficConfig.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from madsim.agents import traffic_kernel as tk
from madsim.agents.pid import CTRL_PARAMS, CTRL_STATE, PIDController
from madsim.agents.traffic_fleet import TrafficFleet
from madsim.physics.sensors import N_VALUES, SENSOR_OFFSETS

__all__ = ["BEHAVIOURS", "CarGeometry", "ConstVel", "DriveAndPark", "Parked", "RandomLaneSwitch",
           "RandomStopping", "SinusoidalSpeed", "TrafficBehaviour", "draw_traffic_placements",
           "make_behaviour", "register_behaviour"]

TICK_S = 0.02
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


class TrafficBehaviour:
    """Base class: sensor row -> (steer, accel, brake, gear) through the PID controller.

    Args: pid (default: MADRaS's gains), collision_time_window (s, following headway),
    min_safe_dist (m, bumper gap kept to a car ahead and margin kept to the road edge),
    car (name, CarSpec or CarGeometry; overridden by info["car"] at reset).
    Subclasses implement `target` and may override `setup` (draws at reset). The driving is
    compiled (madsim.agents.traffic_kernel); the state lives in the rows of a `TrafficFleet`
    (its own one-row fleet, or the env's), which `ticks`, `travelled`, `half_width` and
    `track_length` read.
    """

    behaviour_name = "TrafficBehaviour"
    _kernel_kind = tk.K_USER          # a built-in's target is compiled; a subclass's is Python

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
        self._own = TrafficFleet(1)
        self._fleet, self._r = self._own, 0
        self._sens = np.zeros((1, N_VALUES))
        self._ctrl = np.zeros((1, 4))
        self._rows = np.zeros(1, dtype=np.int64)

    # --- the interface the env and the UDP client use --------------------------------------

    def reset(self, rng: np.random.Generator, info: dict | None = None) -> None:
        """Start an episode. info (read: track_length m, track_width m, car, tick_s, placement
        (s m, n m); written: behaviour, params and every draw)."""
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        self.rng = rng
        self.info = info = {} if info is None else info
        self.tick_s = float(info.get("tick_s", TICK_S))
        self.geometry = g = CarGeometry.of(info.get("car", self._car))
        length, width = info.get("track_length"), info.get("track_width")
        own = self._fleet = self._own
        self._r = 0
        own.S[0] = 0.0
        PIDController.initial_state(own.S[0, tk.S_PID:tk.S_PID + CTRL_STATE])
        own.S[0, tk.RAND_AT] = tk.RAND_BUF
        own.S[0, tk.TRACK_LENGTH] = float(length) if length else 0.0
        own.S[0, tk.HALF_WIDTH] = float(width) / 2.0 if width else 0.0
        p = own.P[0]
        p[:] = 0.0
        p[[tk.WINDOW_S, tk.MIN_SAFE, tk.LENGTH, tk.WIDTH, tk.WHEELBASE, tk.REAR_AXLE,
           tk.STEER_LOCK, tk.TICK]] = (self.window_s, self.min_safe_dist, g.length_m, g.width_m,
                                       g.wheelbase_m, g.rear_axle_m, g.steer_lock_rad, self.tick_s)
        self.pid.pack(p[tk.P_PID:tk.P_PID + CTRL_PARAMS])
        info["behaviour"] = self.behaviour_name
        info["params"] = dict(self.params)
        self.setup(rng, info)
        self._pack(p, own.lanes[0])
        custom = type(self).target is not TrafficBehaviour.target
        self._kind = tk.K_USER if custom else self._kernel_kind
        own.put(0, self)

    def act(self, row: Mapping) -> tuple[float, float, float, int]:
        """Controls for the coming tick from the latest sensors (SCR names and units)."""
        if self._fleet is not self._own:          # driven in a batch until now: take it back
            self._unbind()
        sens = self._sens
        for name in _READ if self._kind != tk.K_USER else SENSOR_OFFSETS:   # target sees all
            value = row[name] if name in _READ else row.get(name)
            if value is not None:
                o, w = SENSOR_OFFSETS[name]
                sens[0, o:o + w] = value
        self._own.act(sens, self._ctrl, self._rows)
        steer, accel, brake, gear = self._ctrl[0].tolist()
        return steer, accel, brake, int(gear)

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

    # --- state, read from the fleet row --------------------------------------------------------

    def _state(self, col: int) -> float:
        return float(self._fleet.S[self._r, col])

    @property
    def ticks(self) -> int:
        """Ticks driven since reset (countdown ticks excluded)."""
        return int(self._state(tk.TICKS))

    @property
    def travelled(self) -> float:
        """m driven since the first tick (distRaced)."""
        return self._state(tk.TRAVELLED)

    @property
    def half_width(self) -> float | None:
        """m, from info["track_width"] or estimated from the rangefinders (None: not yet)."""
        return self._state(tk.HALF_WIDTH) or None

    @property
    def track_length(self) -> float | None:
        """m, from info["track_length"] or learnt at the first start-line crossing."""
        return self._state(tk.TRACK_LENGTH) or None

    def _pack(self, p: np.ndarray, lanes: np.ndarray) -> None:
        """Write the behaviour's parameters into its fleet parameter row (built-ins)."""

    def _draws(self, k: int) -> np.ndarray:
        """k draws from the episode's generator, in the order the behaviour consumes them."""
        raise NotImplementedError

    def _record(self, event: float, t_s: float, value: float) -> None:
        """Write a draw the kernel made into the episode info."""

    def _bind(self, fleet: TrafficFleet, r: int) -> None:
        """Move this car's state to row r of `fleet` (called by fleet.put)."""
        if fleet is not self._own and type(self).act is not TrafficBehaviour.act:
            fleet.kind[r] = tk.K_FOREIGN        # it overrides act: a batch calls that
            return
        fleet.kind[r] = self._kind
        if fleet is not self._own:
            for a in ("S", "P", "lanes", "rand"):
                getattr(fleet, a)[r] = getattr(self._own, a)[0]
        self._fleet, self._r = fleet, r

    def _unbind(self) -> None:
        for a in ("S", "P", "lanes", "rand"):
            getattr(self._own, a)[0] = getattr(self._fleet, a)[self._r]
        self._fleet, self._r = self._own, 0


_READ = ("angle", "curLapTime", "distFromStart", "distRaced", "opponents", "speedX", "track",
         "trackPos")


# --- the built-in behaviours (parameters: madsim.envs.config.TRAFFIC_PARAMS, SI units) --------


@register_behaviour("ConstVel")
class ConstVel(TrafficBehaviour):
    """Constant speed (m/s) in a constant lane (trackPos units)."""

    _kernel_kind = tk.K_CONST_VEL

    def __init__(self, target_speed: float = 13.89, lane: float = 0.0, **base):
        super().__init__(**base)
        self.params = {"target_speed": float(target_speed), "lane": float(lane)}

    def _pack(self, p, lanes):
        p[tk.SPEED], p[tk.LANE_P] = self.params["target_speed"], self.params["lane"]


@register_behaviour("SinusoidalSpeed")
class SinusoidalSpeed(TrafficBehaviour):
    """speed = mean_speed + speed_amplitude sin(2 pi t / speed_period) (m/s, s) in a lane;
    t from the first tick. MADRaS oscillated around 0; this oscillates around the mean."""

    _kernel_kind = tk.K_SINUSOIDAL

    def __init__(self, mean_speed: float = 13.89, speed_amplitude: float = 13.89,
                 speed_period: float = 125.66, lane: float = 0.0, **base):
        super().__init__(**base)
        if not speed_period > 0:
            raise ValueError(f"speed_period must be > 0 s, got {speed_period}")
        self.params = {"mean_speed": float(mean_speed), "speed_amplitude": float(speed_amplitude),
                       "speed_period": float(speed_period), "lane": float(lane)}

    def _pack(self, p, lanes):
        q = self.params
        p[[tk.MEAN, tk.AMPLITUDE, tk.PERIOD, tk.LANE_P]] = (
            q["mean_speed"], q["speed_amplitude"], q["speed_period"], q["lane"])


@register_behaviour("RandomLaneSwitch")
class RandomLaneSwitch(TrafficBehaviour):
    """Every lane_change_interval s (from t = 0) pick one of `lanes` uniformly at random and
    drive there at target_speed. A move waits while the side it goes to is not clear.
    info["lane_draws"]: [(t_s, lane)] per draw."""

    _kernel_kind = tk.K_LANE_SWITCH

    def __init__(self, target_speed: float = 27.78, lane_change_interval: float = 0.1,
                 lanes=(-0.75, 0.75), **base):
        super().__init__(**base)
        if not lane_change_interval > 0:
            raise ValueError(f"lane_change_interval must be > 0 s, got {lane_change_interval}")
        if not 1 <= len(lanes) <= tk.MAX_LANES:
            raise ValueError(f"lanes must hold 1 to {tk.MAX_LANES} lanes, got {len(lanes)}")
        self.params = {"target_speed": float(target_speed),
                       "lane_change_interval": float(lane_change_interval),
                       "lanes": tuple(float(x) for x in lanes)}

    def setup(self, rng, info):
        self.draws = info["lane_draws"] = []

    def _pack(self, p, lanes):
        q = self.params
        p[tk.SPEED], p[tk.INTERVAL], p[tk.N_LANES] = (q["target_speed"],
                                                      q["lane_change_interval"], len(q["lanes"]))
        lanes[:len(q["lanes"])] = q["lanes"]

    def _draws(self, k):
        return self.rng.integers(len(self.params["lanes"]), size=k)

    def _record(self, event, t_s, value):
        self.draws.append((t_s, value))


@register_behaviour("RandomStopping")
class RandomStopping(TrafficBehaviour):
    """Drive at target_speed in a lane; while driving, with stop_probability per tick, halt and
    stand still for a duration ~ U(0, max_stop_duration] s (counted from the standstill), then
    drive on. No throttle while halting. info["stops"]: [(t_s, duration_s)] per halt."""

    _kernel_kind = tk.K_STOPPING

    def __init__(self, target_speed: float = 13.89, lane: float = 0.0, stop_probability: float = 0.1,
                 max_stop_duration: float = 0.1, **base):
        super().__init__(**base)
        if not 0.0 <= stop_probability <= 1.0:
            raise ValueError(f"stop_probability must be in [0, 1], got {stop_probability}")
        self.params = {"target_speed": float(target_speed), "lane": float(lane),
                       "stop_probability": float(stop_probability),
                       "max_stop_duration": float(max_stop_duration)}

    def setup(self, rng, info):
        self.stops = info["stops"] = []

    def _pack(self, p, lanes):
        q = self.params
        p[[tk.SPEED, tk.LANE_P, tk.STOP_P, tk.MAX_STOP]] = (
            q["target_speed"], q["lane"], q["stop_probability"], q["max_stop_duration"])

    def _draws(self, k):
        return self.rng.random(k)

    def _record(self, event, t_s, value):
        self.stops.append((t_s, value))


@register_behaviour("DriveAndPark")
class DriveAndPark(TrafficBehaviour):
    """Drive at target_speed in the parking lane to the parking distance from the start line
    (m, the next time the car gets there) and park: brake held from then on. Lane and distance
    are drawn uniformly from their ranges at reset (info["parking_lane"], ["parking_distance"])."""

    _kernel_kind = tk.K_PARK

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

    def _pack(self, p, lanes):
        p[tk.SPEED], p[tk.PARK_LANE], p[tk.PARK_DISTANCE] = (
            self.params["target_speed"], self.lane, self.distance)

    @property
    def parked(self) -> bool:
        return bool(self._state(tk.PARKED))


@register_behaviour("Parked")
class Parked(TrafficBehaviour):
    """Stands where it was placed from the first tick: no throttle, brake held."""

    _kernel_kind = tk.K_PARKED


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
