"""Fidelity against real TORCS 1.3.7: car1-trb1 driven by the fixed reference controller of issue 3.

Prints one line per figure: madsim's value, the TORCS reference and the error in %.
Controller inputs come from World state as SCR defines them (track spec 10.3): angle = track
tangent heading - yaw (wrapped), trackPos = n / (w/2), speedX in km/h, rpm = engine rad/s x 10.
Needs the TORCS data (car1-trb1, g-track-1, e-track-2). Run: python benchmarks/fidelity.py
"""

from __future__ import annotations

import math
import sys
import time

import numpy as np

from madsim.cars import load_car
from madsim.physics.world import World
from madsim.tracks import load_track

REFERENCE = {"lap": 76.04, "t100": 3.71, "v10": 207.5, "v15": 239.9}
GEAR_UP = (5000, 6000, 6000, 6500, 7000)          # rpm x10 units, from gear 1..5
GEAR_DOWN = (0, 2500, 3000, 3000, 3500, 3500)     # from gear 1..6


def scr_inputs(world: World) -> tuple[float, float, float, float]:
    """(angle rad, trackPos, speedX km/h, rpm) of car 0 as the SCR server reports them."""
    angle = (world.track_heading[0] - world.yaw[0] + math.pi) % (2 * math.pi) - math.pi
    track_pos = world.n[0] / (world.track.width / 2.0)
    return angle, track_pos, world.vx[0] * 3.6, world.engine_speed[0] * 10.0


def steer_of(angle: float, track_pos: float) -> float:
    return float(np.clip((angle - 0.5 * track_pos) / 0.366519, -1.0, 1.0))


def flying_lap(track_name: str = "g-track-1", car_name: str = "car1-trb1", target_kmh: float = 100.0,
               max_time: float = 400.0) -> float:
    """Flying-lap time (s): the second lap, between the second and third line crossings, from a
    standing start 100 m before the line, with the SCR sample gear rule. (The first lastLapTime
    includes the run-up from the start: TORCS's first lap timer runs from the race start.)"""
    track = load_track(track_name)
    world = World(track, [load_car(car_name)], np.random.default_rng(0), contact=False)
    world.reset(np.array([[track.length - 100.0, 0.0, 0.0]]), gears=1)
    u = np.zeros((1, 5))
    while world.time < max_time:
        angle, pos, speed, rpm = scr_inputs(world)
        gear = max(int(world.gear[0]), 1)
        if gear < 6 and rpm >= GEAR_UP[gear - 1]:
            gear += 1
        elif gear > 1 and rpm <= GEAR_DOWN[gear - 1]:
            gear -= 1
        u[0] = (steer_of(angle, pos), np.clip((target_kmh - speed) / 10.0, 0, 1),
                np.clip((speed - target_kmh) / 10.0, 0, 1), gear, 0.0)
        world.step(u)
        if world.laps[0] >= 3:
            return float(world.last_lap_time[0])
    return math.nan


def straight_line(track_name: str = "e-track-2", car_name: str = "car1-trb1") -> tuple[float, float, float]:
    """(0-100 km/h time s, speedX at 10 s, at 15 s km/h) at full throttle from the pole position."""
    track = load_track(track_name)
    car = load_car(car_name)
    world = World(track, [car], np.random.default_rng(0), contact=False)
    world.reset(gears=1)
    up_kmh = [0.95 * car.redline_speed(g) * 3.6 for g in range(1, car.top_gear + 1)]
    u = np.zeros((1, 5))
    t100 = math.nan
    v10 = v15 = math.nan
    prev_t, prev_v = 0.0, 0.0
    while world.time < 15.0 - 1e-9:
        angle, pos, speed, _ = scr_inputs(world)
        gear = int(world.gear[0])
        if gear < car.top_gear and speed >= up_kmh[gear - 1]:
            gear += 1
        u[0] = (steer_of(angle, pos), 1.0, 0.0, gear, 0.0)
        world.step(u)
        v = world.vx[0] * 3.6
        t = world.time
        if math.isnan(t100) and v >= 100.0:
            t100 = prev_t + (100.0 - prev_v) / (v - prev_v) * (t - prev_t)
        if abs(t - 10.0) < 1e-6:
            v10 = v
        prev_t, prev_v = t, v
    v15 = world.vx[0] * 3.6
    return t100, v10, v15


def main() -> int:
    t0 = time.perf_counter()
    lap = flying_lap()
    t100, v10, v15 = straight_line()
    rows = (("g-track-1 flying lap, s", lap, REFERENCE["lap"], 2.0),
            ("e-track-2 0-100 km/h, s", t100, REFERENCE["t100"], 5.0),
            ("e-track-2 speed at 10 s, km/h", v10, REFERENCE["v10"], 5.0),
            ("e-track-2 speed at 15 s, km/h", v15, REFERENCE["v15"], 5.0))
    for name, got, ref, tol in rows:
        err = 100.0 * (got - ref) / ref
        flag = "ok" if abs(err) <= tol else "OUT"
        print(f"{name:32s} madsim {got:8.2f}  TORCS {ref:8.2f}  error {err:+6.2f} %  (target {tol:g} %) {flag}")
    print(f"(ran in {time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
