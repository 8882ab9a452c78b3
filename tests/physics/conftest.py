"""Fixtures for physics tests: small TORCS track files written to tmp_path, test cars, drivers."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from trackfiles import segment, torcs_installed, track_xml

from madsim.cars import load_car
from madsim.physics.world import World
from madsim.tracks import load_track


@pytest.fixture(scope="module")
def road():
    """madsim-road, loaded once per test module."""
    return load_track("madsim-road")


@pytest.fixture(scope="module")
def sedan():
    """The bundled madsim-sedan as it ships."""
    return load_car("madsim-sedan")


@pytest.fixture
def need_torcs():
    if not torcs_installed():
        pytest.skip("TORCS data not installed: apt-get install torcs-data")


@pytest.fixture
def make_track(tmp_path):
    """Build a Track from segment sections; the road material `tar` has the given friction and
    rolling resistance (no borders or sides: beyond the road edge is the barrier material)."""
    count = [0]

    def _make(segs: list[str], *, width: float = 20.0, friction: float = 1.0, rolling: float = 0.01):
        count[0] += 1
        name = f"t{count[0]}"
        surfaces = (f'<section name="tar"><attnum name="friction" val="{friction}"/>'
                    f'<attnum name="rolling resistance" val="{rolling}"/></section>')
        text = track_xml(segs, width=width, surfaces=surfaces, name=name,
                         main_extra='<attstr name="surface" val="tar"/>')
        d = tmp_path / name
        d.mkdir()
        p = d / f"{name}.xml"
        p.write_text(text, encoding="utf-8")
        return load_track(p)

    return _make


@pytest.fixture
def straight(make_track):
    """A flat straight of `length` m."""
    def _straight(length: float = 3000.0, **kw):
        return make_track([segment("s", "str", lg=length)], **kw)
    return _straight


def sedan_without_lift(**changes):
    """The bundled sedan without body lift (so wheel loads are m g exactly), with changes."""
    car = load_car("madsim-sedan")
    return dataclasses.replace(car, clift=np.zeros(2), **changes)


def world_at(track, car, s=100.0, n=0.0, speed=0.0, gear=0, **kw):
    """A one-car World placed at (s, n) with `speed` along the track, contact off."""
    kw.setdefault("contact", False)
    w = World(track, [car], np.random.default_rng(0), **kw)
    w.reset(np.array([[s, n, speed]]), gears=gear)
    return w


def hold_line(world, target_n=0.0, gain=0.5):
    """Steering command that follows the track like the issue's reference controller."""
    angle = (world.track_heading - world.yaw + math.pi) % (2 * math.pi) - math.pi
    return np.clip((angle - gain * (world.n - target_n) / (world.track.width / 2)) / 0.366519, -1, 1)


def drive_steady(world, speed, gear, ticks, gain):
    """Step car 0 `ticks` ticks in `gear` on the line (`hold_line`) at `speed` m/s (throttle
    proportional to the speed error with `gain` per m/s, clipped to [0, 1])."""
    u = np.zeros((1, 5))
    u[0, 3] = gear
    for _ in range(ticks):
        u[0, 0] = hold_line(world)[0]
        u[0, 1] = float(np.clip((speed - world.vx[0]) * gain, 0.0, 1.0))
        world.step(u)


@pytest.fixture
def ph():
    """Helpers for physics tests: ph.sedan(**changes), ph.world_at(track, car, ...),
    ph.hold_line(world), ph.drive_steady(world, speed, gear, ticks, gain)."""
    import types
    return types.SimpleNamespace(sedan=sedan_without_lift, world_at=world_at, hold_line=hold_line,
                                 drive_steady=drive_steady)
