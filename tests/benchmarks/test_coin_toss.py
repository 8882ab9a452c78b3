"""benchmarks/coin_toss.py (issue 12, session 12): the damage events and first parting of two
runs' records, and the nudges it gives madsim's car, in closed form."""

import math

import numpy as np
import pytest

from tests.benchmarks.conftest import load_script, unload


@pytest.fixture(scope="module")
def toss():
    yield load_script("coin_toss")
    unload()


def test_damage_events_are_the_messages_where_damage_grows(toss):
    rec = {"damage": np.array([0.0, 0.0, 57.0, 60.0, 60.0, 60.0, 63.0]),
           "distRaced": np.arange(7.0) * 10.0, "speedX": np.array([90.0, 80, 66.6, 71, 50, 40, -78.6]),
           "trackPos": np.array([0.0, -1, -2.83, -2.82, -2.8, -2.8, -2.88])}
    ev = toss.damage_events(rec)
    assert [e[0] for e in ev] == [2, 3, 6]
    assert ev[0] == (2, 20.0, 57.0, 66.6, -2.83)
    assert [e[2] for e in ev] == [57.0, 3.0, 3.0]


def test_first_parting_per_column_with_the_angle_wrapped(toss):
    n = 10
    t = {"speedX": np.full(n, 100.0), "trackPos": np.zeros(n), "angle": np.full(n, 3.13)}
    m = {"speedX": np.full(n + 3, 100.0), "trackPos": np.zeros(n + 3), "angle": np.full(n + 3, 3.13)}
    m["speedX"][4:] += 2.5                  # 2.5 km/h > 2.0 from message 4
    m["trackPos"][7] = 0.11                 # one message beyond 0.1
    m["angle"][2:] = -3.14                  # across +-pi: 0.0132 rad apart, not a parting
    m["angle"][8:] = -3.05                  # 0.103 rad apart across +-pi: parted at 8
    part = toss.first_parting(t, m)
    assert part == {"speedX": 4, "trackPos": 7, "angle": 8}
    same = toss.first_parting(t, {k: v[:n].copy() for k, v in t.items()})
    assert same == {"speedX": -1, "trackPos": -1, "angle": -1}


def test_nudges_move_the_cars_state_as_named():
    from madsim.cars import load_car
    from madsim.physics import layout as L
    from madsim.physics.world import World
    from madsim.tracks import load_track

    toss = load_script("coin_toss")
    unload()
    w = World(load_track("g-track-1"), [load_car("car1-trb1")], np.random.default_rng(0), contact=False)
    w.reset()
    st = w.state
    st[0, L.S["yaw"]] = math.pi - 0.001
    st[0, L.S["vx_g"]], st[0, L.S["vy_g"]] = -20.0, 1.0
    before = st[0].copy()
    toss.nudge_state(w, "yaw", 0.003)           # wraps through +-pi
    assert st[0, L.S["yaw"]] == pytest.approx(-math.pi + 0.002, abs=1e-12)
    toss.nudge_state(w, "yaw", -0.003)
    assert st[0, L.S["yaw"]] == pytest.approx(before[L.S["yaw"]], abs=1e-12)
    x0, y0, yaw = st[0, L.S["x"]], st[0, L.S["y"]], st[0, L.S["yaw"]]
    toss.nudge_state(w, "lateral", 0.25)        # 0.25 m to the car's left: (-sin, cos) of its heading
    assert st[0, L.S["x"]] - x0 == pytest.approx(-0.25 * math.sin(yaw), abs=1e-12)
    assert st[0, L.S["y"]] - y0 == pytest.approx(0.25 * math.cos(yaw), abs=1e-12)
    toss.nudge_state(w, "speed", 0.01)
    assert st[0, L.S["vx_g"]] == pytest.approx(-20.2) and st[0, L.S["vy_g"]] == pytest.approx(1.01)
    changed = np.flatnonzero(st[0] != before)
    assert set(changed) <= {L.S[c] for c in ("x", "y", "yaw", "vx_g", "vy_g", "vx", "vy")}
    with pytest.raises(ValueError):
        toss.nudge_state(w, "pitch", 0.1)


def test_outcome_errs_against_torcs_only_where_both_have_a_lap_2(toss):
    # g-track-2 at 150: TORCS 98.610 s; a variant with 91.370 s is 7.34 % faster
    lap2, err, end, dmg = toss.outcome(98.610, 91.370, "2 laps", 156.0)
    assert (lap2, end, dmg) == (91.370, "2 laps", 156.0)
    assert err == pytest.approx(100.0 * (91.370 - 98.610) / 98.610, abs=1e-12)
    assert err == pytest.approx(-7.342, abs=1e-3)
    assert math.isnan(toss.outcome(98.610, float("nan"), "DNF", 95.0)[1])
    assert math.isnan(toss.outcome(float("nan"), 217.790, "2 laps", 780.0)[1])
