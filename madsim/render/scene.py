"""What a frame shows, as plain arrays: car poses and sizes, the HUD values, sensor overlays.

The renderer takes these, not a World, so that it draws a live World, an env behind the UDP
backend (poses rebuilt from SCR sensors) and a replayed `madsim serve --log-csv` trace alike.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from madsim.physics import layout as L

KINDS = ("learner", "traffic", "parked")
CAMERAS = ("track", "follow", "rotate")


class CarPoses(NamedTuple):
    """Every car of a frame: x, y (m), yaw (rad, counter-clockwise from +x), length, width
    (m), each (N,)."""

    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray
    length: np.ndarray
    width: np.ndarray

    @classmethod
    def from_world(cls, world) -> CarPoses:
        """Poses and body sizes of a `madsim.physics.world.World`."""
        st = world.state
        return cls(np.array(st[:, L.S_X]), np.array(st[:, L.S_Y]), np.array(st[:, L.S_YAW]),
                   np.array([c.body_length for c in world.cars], dtype=np.float64),
                   np.array([c.body_width for c in world.cars], dtype=np.float64))

    @classmethod
    def from_arrays(cls, x, y, yaw, length=4.78, width=1.84) -> CarPoses:
        """From array-likes; length and width broadcast (default madsim-sedan)."""
        x = np.atleast_1d(np.asarray(x, dtype=np.float64))

        def b(v):
            return np.array(np.broadcast_to(np.asarray(v, dtype=np.float64), x.shape))
        return cls(x, b(y), b(yaw), b(length), b(width))

    def __len__(self) -> int:   # number of cars, not of fields
        return int(self.x.shape[0])


@dataclass(frozen=True)
class Hud:
    """The head-up display of one car: speed km/h, gear (-1 R, 0 N), engine rpm, lap
    (start-line crossings so far: the lap being driven; None: unknown), current lap time s,
    race position
    of n_cars, simulated time s, and a label (car id)."""

    speed_kmh: float
    gear: int
    rpm: float
    lap: int | None
    lap_time_s: float
    position: int
    n_cars: int
    time_s: float = 0.0
    label: str = ""

    @classmethod
    def from_world(cls, world, k: int, label: str = "") -> Hud:
        """HUD of World row k (rpm = engine rad/s x 60 / 2 pi)."""
        st = world.state
        return cls(speed_kmh=float(st[k, L.S_VX]) * 3.6, gear=int(st[k, L.S_GEAR]),
                   rpm=float(st[k, L.S_WE]) * 60.0 / (2.0 * np.pi), lap=int(st[k, L.S_LAPS]),
                   lap_time_s=float(st[k, L.S_CURLAP]), position=int(world.race_pos[k]),
                   n_cars=int(world.n_cars), time_s=float(st[k, L.S_TIME]), label=label)


def gear_text(gear: int) -> str:
    return "R" if gear < 0 else "N" if gear == 0 else str(gear)


def lap_time_text(t: float) -> str:
    """m:ss.ss (negative times, the countdown, as -s.ss)."""
    if t < 0:
        return f"-{-t:.2f}"
    m, s = divmod(t, 60.0)
    return f"{int(m)}:{s:05.2f}"


def hud_lines(hud: Hud) -> list[str]:
    """The HUD's text lines, top to bottom (what the renderer draws, exactly)."""
    lines = [hud.label] if hud.label else []
    lines += [f"{int(round(hud.speed_kmh))} km/h",     # int: a parked car's -0.3 km/h shows as 0, not -0
              f"gear {gear_text(hud.gear)}  {hud.rpm:.0f} rpm",
              f"lap {'-' if hud.lap is None else hud.lap}  {lap_time_text(hud.lap_time_s)}",
              f"pos {hud.position}/{hud.n_cars}  t {hud.time_s:.1f} s"]
    return lines


@dataclass(frozen=True)
class Overlay:
    """Sensor overlays of one car: rangefinder `ray_angles_deg` (A,) (SCR: positive to the
    right) with `ray_dist_m` (A,) (negative: no reading), and `sectors_m` (36,) opponent
    distances (sector 0 starts dead astern, clockwise; 200 m or more: empty)."""

    ray_angles_deg: np.ndarray | None = None
    ray_dist_m: np.ndarray | None = None
    sectors_m: np.ndarray | None = None

    @classmethod
    def from_sensors(cls, frame, k: int, angles_deg) -> Overlay:
        """From row k of a SensorFrame and that car's 19 rangefinder angles."""
        return cls(np.asarray(angles_deg, dtype=np.float64), np.array(frame.track[k]),
                   np.array(frame.opponents[k]))
