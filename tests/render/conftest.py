"""Fixtures for renderer tests: the bundled road course, Worlds with cars placed by hand,
and a small serve-format trace written from a World."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from madsim.cars import load_car
from madsim.physics.sensors import SensorSuite
from madsim.physics.world import World
from madsim.tracks import load_track

# madsim-road's start straight runs due east (+x) from s = 0 to beyond s = 300 m
STRAIGHT_S = 100.0


@pytest.fixture(scope="session")
def road():
    return load_track("madsim-road")


@pytest.fixture(scope="session")
def sedan():
    return load_car("madsim-sedan")


@pytest.fixture
def make_world(road, sedan):
    """World with cars at placements (s m, n m, speed m/s) on madsim-road (contact off)."""

    def _make(placements, cars=None):
        specs = cars or [sedan] * len(placements)
        w = World(road, specs, np.random.default_rng(0), contact=False)
        w.reset(np.asarray(placements, dtype=np.float64))
        return w
    return _make


TRACE_FIELDS = ("tick", "time", "car", "x", "y", "yaw", "distFromStart", "trackPos", "angle",
                "speedX", "speedY", "rpm", "gear", "laps", "curLapTime", "lastLapTime", "damage",
                "steer", "accel", "brake", "gear_request", "clutch")


def write_trace(path, world, ticks: int, countdown: int = 2) -> None:
    """A `madsim serve --log-csv` style trace: `countdown` frozen ticks, then `ticks` ticks of
    full throttle in first gear (rows: tick, car)."""
    try:
        from madsim.net.server import CSV_FIELDS
        assert tuple(CSV_FIELDS) == TRACE_FIELDS
    except ImportError:
        pass
    suite = SensorSuite(world)
    u = np.zeros((world.n_cars, 5))
    u[:, 1], u[:, 3] = 1.0, 1.0
    with open(path, "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(TRACE_FIELDS)
        for t in range(-countdown, ticks):
            if t >= 0:
                world.step(u)
            fr = suite.frame()
            st = world.state
            for i in range(world.n_cars):
                out.writerow([t, f"{world.time:.3f}", i, f"{st[i, 0]:.4f}", f"{st[i, 1]:.4f}",
                              f"{st[i, 3]:.5f}", f"{fr.distFromStart[i]:.3f}", f"{fr.trackPos[i]:.5f}",
                              f"{fr.angle[i]:.5f}", f"{fr.speedX[i]:.3f}", f"{fr.speedY[i]:.3f}",
                              f"{fr.rpm[i]:.1f}", int(fr.gear[i]), int(world.laps[i]),
                              f"{fr.curLapTime[i]:.3f}", f"{fr.lastLapTime[i]:.3f}", int(fr.damage[i]),
                              "0", "1", "0", "1", "0"])


@pytest.fixture
def trace_file(tmp_path, make_world):
    """A 60-tick, 2-car trace starting on the grid behind the start line."""
    w = make_world([(3020.0, -2.0, 10.0), (3010.0, 2.0, 12.0)])
    p = tmp_path / "trace.csv"
    write_trace(p, w, 60)
    return p
