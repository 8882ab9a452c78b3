"""The shared facts (madsim.facts) are what the protocol, the sensors, the physics and the docs
use: one table, read everywhere (spec/scr-protocol.md sections 3.3 and 5)."""

from __future__ import annotations

import numpy as np
import pytest

from madsim import facts as F
from madsim.docs import generate
from madsim.net import protocol as P
from madsim.physics import sensors as S


def test_a_tick_is_ten_sub_steps_of_two_milliseconds_and_a_world_step_lasts_one():
    from madsim.cars import load_car
    from madsim.physics.world import World
    from madsim.tracks import load_track

    assert (F.SUBSTEP_S, F.SUBSTEPS_PER_TICK, F.TICK_S) == (0.002, 10, 0.02)
    world = World(load_track("madsim-oval"), [load_car("car1-trb1")], np.random.default_rng(0))
    world.step(np.zeros((1, 5)))
    world.step(np.zeros((1, 5)))
    assert world.time == pytest.approx(2 * F.TICK_S, abs=1e-15)   # 20 sums of 0.002


def test_protocol_sensors_and_docs_read_the_one_field_table():
    table = [(f.name, f.width, f.kind) for f in F.SCR_FIELDS]
    assert [(f.name, f.width, f.kind) for f in P.SENSOR_FIELDS] == table
    assert [(name, width) for name, width in S.SENSOR_WIDTHS] == [(n, w) for n, w, _ in table]
    assert S.INT_FIELDS == ("damage", "gear", "racePos")
    offset = 0
    for name, width, _ in table:
        assert S.SENSOR_OFFSETS[name] == (offset, width)
        offset += width
    assert offset == F.SCR_VALUE_COUNT == P.SENSOR_VALUE_COUNT == S.N_VALUES == 79
    doc = generate()["sensors.md"]
    for f in F.SCR_FIELDS:
        assert f"| `{f.name}` | {f.width} | {f.unit} | {f.meaning} |" in doc


def test_rangefinder_angle_sets_have_the_names_of_who_uses_them():
    # scr_server's fallback: -90..90 step 10 (spec 3.3); the C++ client's and snakeoil's lists
    assert F.SCR_SERVER_DEFAULT_ANGLES_DEG == tuple(float(a) for a in range(-90, 91, 10))
    assert P.DEFAULT_ANGLES_DEG == F.SCR_SERVER_DEFAULT_ANGLES_DEG
    assert F.SCR_CPP_CLIENT_ANGLES_DEG[:3] == (-90.0, -75.0, -60.0)
    assert F.SNAKEOIL_ANGLES_DEG[0] == -45.0 and F.SNAKEOIL_ANGLES_DEG[9] == 0.0
    for angles in (F.SCR_SERVER_DEFAULT_ANGLES_DEG, F.SCR_CPP_CLIENT_ANGLES_DEG, F.SNAKEOIL_ANGLES_DEG):
        assert len(angles) == 19 and list(angles) == sorted(angles)
        assert tuple(-a for a in reversed(angles)) == angles       # symmetric about straight ahead
    assert S.SCR_DEFAULT_ANGLES_DEG == F.SCR_CPP_CLIENT_ANGLES_DEG
