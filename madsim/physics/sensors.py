"""The SCR sensor set for every car, vectorised (spec/scr-protocol.md section 5).

`SensorFrame` holds every field of the SCR state message as arrays with the car axis first, in
SCR units (km/h, rad for `angle`, engine rad/s x 10 for `rpm`, m, s). This module is the one
source of truth for sensor semantics; the wire format lives in `madsim.net.protocol`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np

SCR_DEFAULT_ANGLES_DEG = (-90.0, -75.0, -60.0, -45.0, -30.0, -20.0, -15.0, -10.0, -5.0, 0.0,
                          5.0, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 75.0, 90.0)
SENSOR_RANGE_M = 200.0
FOCUS_COOLDOWN_S = 1.0
FOCUS_NONE = 360.0          # SCR's "no focus requested" sentinel
NOISE_STD = {"track": 0.1, "opponents": 0.02, "focus": 0.01}   # multiplicative N(1, std)
MS_TO_KMH = 3.6


@dataclass
class SensorFrame:
    """Every SCR sensor for N cars. Scalars are (N,) arrays; track (N, 19), opponents (N, 36),
    focus (N, 5), wheelSpinVel (N, 4) in TORCS wheel order FR, FL, RR, RL."""

    angle: np.ndarray
    curLapTime: np.ndarray
    damage: np.ndarray
    distFromStart: np.ndarray
    distRaced: np.ndarray
    fuel: np.ndarray
    gear: np.ndarray
    lastLapTime: np.ndarray
    opponents: np.ndarray
    racePos: np.ndarray
    rpm: np.ndarray
    speedX: np.ndarray
    speedY: np.ndarray
    speedZ: np.ndarray
    track: np.ndarray
    trackPos: np.ndarray
    wheelSpinVel: np.ndarray
    z: np.ndarray
    focus: np.ndarray
    cars: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))  # world rows

    def row(self, k: int) -> dict:
        """One car's sensors as a dict of floats / lists (the codec's input)."""
        out = {}
        for name in SENSOR_ORDER:
            v = getattr(self, name)[k]
            out[name] = v.tolist() if np.ndim(v) else v.item()
        return out


SENSOR_ORDER = ("angle", "curLapTime", "damage", "distFromStart", "distRaced", "fuel", "gear",
                "lastLapTime", "opponents", "racePos", "rpm", "speedX", "speedY", "speedZ", "track",
                "trackPos", "wheelSpinVel", "z", "focus")


@numba.njit(cache=True)
def opponents_kernel(idx, x, y, yaw, active, max_range, out):
    """out[k, 0..35] = nearest distance of another active car in each 10-degree sector around
    car idx[k]; bearing positive clockwise from the heading, sector 0 starts dead astern
    (SCR section 5.2); cars at 0 or >= max_range m are skipped; empty sectors = max_range."""
    n = x.shape[0]
    for k in range(idx.shape[0]):
        i = idx[k]
        for a in range(36):
            out[k, a] = max_range
        for j in range(n):
            if j == i or not active[j]:
                continue
            dx = x[j] - x[i]
            dy = y[j] - y[i]
            d = math.sqrt(dx * dx + dy * dy)
            if d <= 0.0 or d >= max_range:
                continue
            beta = math.degrees(yaw[i] - math.atan2(dy, dx))
            beta = beta - 360.0 * math.floor((beta + 180.0) / 360.0)   # [-180, 180)
            if beta <= -180.0:
                beta += 360.0                                            # (-180, 180]
            sector = int(math.floor((beta + 180.0) / 10.0))
            if sector >= 36:
                continue  # dead astern after wrapping: SCR drops it
            if d < out[k, sector]:
                out[k, sector] = d


def wrap_angle(a):
    """Wrap radians to (-pi, pi]."""
    a = np.asarray(a, dtype=np.float64)
    w = np.mod(a + np.pi, 2 * np.pi) - np.pi
    return np.where(w == -np.pi, np.pi, w)


def apply_noise(frame: SensorFrame, rng: np.random.Generator) -> None:
    """SCR `-noisy`: multiply track, opponents and focus by N(1, std) draws (in place); the -1
    sentinels of track and focus stay exact (spec 5.1, 5.2, 5.3)."""
    for name, std in NOISE_STD.items():
        values = getattr(frame, name)
        draw = rng.normal(1.0, std, size=values.shape)
        if name in ("track", "focus"):
            draw = np.where(values == -1.0, 1.0, draw)
        values *= draw


class FocusState:
    """Per-car focus bookkeeping: the angle requested in the previous control message and the
    simulated time from which the next valid reading may be produced (one per second)."""

    def __init__(self, n: int):
        self.requested_deg = np.zeros(n)          # a client that never asks gets focus 0
        self.next_allowed_s = np.zeros(n)

    def request(self, cars: np.ndarray, focus_deg: np.ndarray) -> None:
        """Store the focus requests of this tick's control messages (used for the next state)."""
        f = np.asarray(focus_deg, dtype=np.float64)
        self.requested_deg[cars] = np.where((f >= -90) & (f <= 90), f, FOCUS_NONE)

    def due(self, cars: np.ndarray, race_time_s: np.ndarray, on_track: np.ndarray) -> np.ndarray:
        """Which of `cars` get a valid reading now; advances their cooldown."""
        ok = on_track & (self.requested_deg[cars] != FOCUS_NONE) & (race_time_s >= self.next_allowed_s[cars])
        self.next_allowed_s[cars[ok]] = race_time_s[ok] + FOCUS_COOLDOWN_S
        return ok


class SensorSuite:
    """Computes SensorFrames for a World: per-car rangefinder angles, focus requests and
    cooldowns, the SCR `distRaced` origin, optional noise from a Generator.

    One suite per door (server, env): it holds what SCR keeps per client between ticks.
    """

    def __init__(self, world, *, noisy: bool = False, rng: np.random.Generator | None = None):
        self.world = world
        self.noisy = bool(noisy)
        self.rng = rng if rng is not None else world.rng
        n = world.n_cars
        self.angles_deg = np.tile(np.asarray(SCR_DEFAULT_ANGLES_DEG), (n, 1))
        self.focus = FocusState(n)
        self.dist_origin = np.zeros(n)
        self.reset()

    def reset(self) -> None:
        """Call after `world.reset()`: distRaced restarts from 0, focus cooldowns clear."""
        self.dist_origin = np.array(self.world.column("dist_raced"), dtype=np.float64)
        self.focus = FocusState(self.world.n_cars)

    def set_angles(self, car: int, angles_deg) -> None:
        """The 19 rangefinder angles a client asked for in its identification (degrees)."""
        a = np.asarray(angles_deg, dtype=np.float64)
        if a.shape != (19,):
            raise ValueError(f"rangefinder angles must be 19 values, got shape {a.shape}")
        self.angles_deg[car] = a

    def request_focus(self, cars, focus_deg) -> None:
        """Focus angles from this tick's control messages (used for the next frame)."""
        self.focus.request(np.atleast_1d(np.asarray(cars, dtype=np.int64)), np.atleast_1d(focus_deg))

    def frame(self, cars=None) -> SensorFrame:
        """Sensors of `cars` (default: all) at the world's current state, in SCR units."""
        w = self.world
        track = w.track
        cars = np.arange(w.n_cars) if cars is None else np.atleast_1d(np.asarray(cars, dtype=np.int64))
        col = w.column
        x, y, yaw = col("x")[cars], col("y")[cars], col("yaw")[cars]
        s, n = col("s")[cars], col("n")[cars]
        half = track.width / 2
        track_pos = n / half
        on_road = np.abs(track_pos) <= 1.0
        k = len(cars)

        rays = np.full((k, 19), -1.0)
        if on_road.any():
            idx = np.nonzero(on_road)[0]
            for group in _groups_by_angles(self.angles_deg[cars[idx]]):
                sel = idx[group]
                rays[sel] = track.rangefinders(x[sel], y[sel], yaw[sel], self.angles_deg[cars[sel[0]]],
                                               s_hint=s[sel], max_range_m=SENSOR_RANGE_M)

        focus = np.full((k, 5), -1.0)
        race_time = col("time")[cars]
        due = self.focus.due(cars, race_time, on_road)
        for j in np.nonzero(due)[0]:
            centre = self.focus.requested_deg[cars[j]]
            focus[j] = track.rangefinders(x[j:j + 1], y[j:j + 1], yaw[j:j + 1], centre + np.arange(-2.0, 3.0),
                                          s_hint=s[j:j + 1], max_range_m=SENSOR_RANGE_M)[0]

        opponents = np.empty((k, 36))
        opponents_kernel(cars, np.ascontiguousarray(col("x")), np.ascontiguousarray(col("y")),
                         np.ascontiguousarray(col("yaw")), _active(w),
                         SENSOR_RANGE_M, opponents)

        vxg, vyg = col("vx_g")[cars], col("vy_g")[cars]
        speed_z = col("grad_x")[cars] * vxg + col("grad_y")[cars] * vyg   # z follows the road
        frame = SensorFrame(
            angle=wrap_angle(col("track_heading")[cars] - yaw),
            curLapTime=col("cur_lap_time")[cars].copy(),
            damage=np.floor(col("damage")[cars]).astype(np.int64),
            distFromStart=s.copy(),
            distRaced=col("dist_raced")[cars] - self.dist_origin[cars],
            fuel=col("fuel")[cars].copy(),
            gear=col("gear")[cars].astype(np.int64),
            lastLapTime=col("last_lap_time")[cars].copy(),
            opponents=opponents,
            racePos=np.asarray(w.race_pos)[cars].astype(np.int64),
            rpm=col("engine_speed")[cars] * 10.0,
            speedX=col("vx")[cars] * MS_TO_KMH,
            speedY=col("vy")[cars] * MS_TO_KMH,
            speedZ=speed_z * MS_TO_KMH,
            track=rays,
            trackPos=track_pos,
            wheelSpinVel=np.asarray(w.wheel_spin)[cars].copy(),
            z=col("z")[cars] - col("road_z")[cars],
            focus=focus,
            cars=cars,
        )
        if self.noisy:
            apply_noise(frame, self.rng)
        return frame


def _active(world) -> np.ndarray:
    """Cars still in the race (all, unless the world says otherwise)."""
    active = getattr(world, "active", None)
    return np.ones(world.n_cars, dtype=np.bool_) if active is None else np.asarray(active, dtype=np.bool_)


def _groups_by_angles(angles: np.ndarray) -> list[np.ndarray]:
    """Row indices grouped by identical angle sets (almost always one group)."""
    if len(angles) <= 1 or np.all(angles == angles[0]):
        return [np.arange(len(angles))]
    _, inverse = np.unique(angles, axis=0, return_inverse=True)
    return [np.nonzero(inverse.ravel() == g)[0] for g in range(inverse.max() + 1)]
