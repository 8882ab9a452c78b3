"""benchmarks/excursions.py (issue 12, session 14): the message clock across a lap's reset, the
wall test, the heading change, and placing the World's car on a trace's state (bundled track
and car, no TORCS assets)."""

import math

import numpy as np
import pytest

from tests.benchmarks.conftest import load_script, unload


@pytest.fixture(scope="module")
def exc():
    yield load_script("excursions")
    unload()


def test_message_times_run_on_across_the_line(exc):
    # TORCS resets curLapTime at the line: 100.000 s, then 0.016 s of the new lap with
    # lastLapTime 100.004 s, i.e. 0.020 s after the message before
    rec = {"curLapTime": np.array([99.978, 100.000, 0.016, 0.038]),
           "lastLapTime": np.array([0.0, 0.0, 100.004, 100.004])}
    t = exc.message_times(rec)
    np.testing.assert_allclose(np.diff(t), [0.022, 0.020, 0.022], atol=1e-9)
    assert list(exc.substeps_of(t)) == [11, 10, 11]


def test_heading_change_follows_a_turn_through_pi(exc):
    # the track turns left by 0.6 rad through +-pi; the car keeps angle 0.1 (its heading lags the
    # track's by a constant): its heading turns by the track's 0.6 rad
    track = np.array([2.9, 3.1, 3.3, 3.5]) - 0.0
    wrapped = (track + np.pi) % (2 * np.pi) - np.pi
    d = exc.heading_change(wrapped, np.full(4, 0.1))
    np.testing.assert_allclose(d, [0.0, 0.2, 0.4, 0.6], atol=1e-12)


def test_touches_wall_on_a_velocity_jump_or_damage_not_on_braking_or_turning(exc):
    n = 20
    braking = {"speedX": 100.0 - 0.9 * np.arange(n), "speedY": np.zeros(n), "damage": np.zeros(n)}
    assert not exc.touches_wall(braking, np.zeros(n), 0, n - 1)
    # a sideways bounce: speedX 90 -> 77, speedY -17 -> +17 (aalborg, message 1037)
    hit = {"speedX": np.array([90.1, 77.3]), "speedY": np.array([-17.4, 17.5]), "damage": np.zeros(2)}
    assert exc.touches_wall(hit, np.zeros(2), 0, 1)
    # a glancing hit (alpine-2, message 4120): speedY 18.5 -> 1.6 km/h at the same speed, the
    # car's heading unchanged: the velocity turns by 11 degrees in one message
    glance = {"speedX": np.array([87.6, 89.3]), "speedY": np.array([18.5, 1.6]), "damage": np.zeros(2)}
    assert exc.touches_wall(glance, np.array([0.0, 0.017]), 0, 1)
    # a scrape that costs a damage point but no speed
    scrape = {"speedX": np.full(3, 60.0), "speedY": np.zeros(3), "damage": np.array([4.0, 4.0, 5.0])}
    assert exc.touches_wall(scrape, np.zeros(3), 0, 2)
    # the car yawing at 1.5 rad/s while its velocity keeps its direction: speedY grows, the
    # velocity in the ground frame stays (no hit)
    yaw = 0.03 * np.arange(10)
    turn = {"speedX": 80.0 * np.cos(yaw), "speedY": -80.0 * np.sin(yaw), "damage": np.zeros(10)}
    assert not exc.touches_wall(turn, yaw, 0, 9)


def test_slope_through_the_origin(exc):
    x = np.array([-1.0, 0.5, 2.0])
    assert exc.slope(x, 0.8 * x) == pytest.approx(0.8, abs=1e-15)
    assert math.isnan(exc.slope(np.zeros(3), x))


def test_placed_car_reads_the_traces_state(exc):
    # one message of a made-up trace on the bundled madsim-road: the placed car's sensors give it
    # back (position, attitude, both speeds, the four wheel spins, gear, engine speed), and its
    # yaw rate is the one the trace's angle and the track's heading imply
    from madsim.cars import load_car
    from madsim.physics import layout as L
    from madsim.physics.sensors import SensorSuite
    from madsim.physics.world import World
    from madsim.tracks import load_track

    track = load_track("madsim-road")
    world = World(track, [load_car("madsim-sedan")], np.random.default_rng(0))
    world.reset()
    s0 = 800.0
    t = np.arange(5) * 0.02
    speed = 25.0                                   # m/s along the track
    s = s0 + speed * t
    yaw_rate = 0.3                                 # rad/s, the car's own
    heading = track.heading_at(s)
    yaw = np.unwrap(heading)[0] + 0.05 + yaw_rate * t
    rec = {"distFromStart": s, "trackPos": np.full(5, -0.4), "angle": np.unwrap(heading) - yaw,
           "speedX": np.full(5, 85.0), "speedY": np.full(5, -6.5), "gear": np.full(5, 3.0),
           "rpm": np.full(5, 5200.0), "fuel": np.full(5, 40.0), "steer": np.full(5, 0.2)}
    for k in range(4):
        rec[f"wheelSpinVel_{k}"] = np.full(5, 70.0 + k)
    exc.place_on(world, track, world._cp[0], rec, 2, t)
    f = SensorSuite(world).frame()
    assert f.distFromStart[0] == pytest.approx(s[2], abs=1e-9)
    assert f.trackPos[0] == pytest.approx(-0.4, abs=1e-9)
    assert f.angle[0] == pytest.approx(rec["angle"][2], abs=1e-9)
    assert f.speedX[0] == pytest.approx(85.0, abs=1e-9)
    assert f.speedY[0] == pytest.approx(-6.5, abs=1e-9)
    np.testing.assert_allclose(f.wheelSpinVel[0], [70.0, 71.0, 72.0, 73.0], atol=1e-12)
    assert int(f.gear[0]) == 3
    assert f.rpm[0] == pytest.approx(5200.0, rel=1e-12)
    # central differences of a yaw linear in time: exact up to the heading's own curvature
    assert world.state[0, L.S_R] == pytest.approx(yaw_rate, abs=1e-9)


def test_wheel_surfaces_find_the_wheels_off_the_road(exc):
    # the sedan at trackPos -0.9 on madsim-road (12 m wide): its right wheels (y = -0.8 m or
    # so) stand beyond the right edge at -6 m, its left ones on the tarmac
    from madsim.cars import load_car
    from madsim.physics.world import World
    from madsim.tracks import load_track

    track = load_track("madsim-road")
    world = World(track, [load_car("madsim-sedan")], np.random.default_rng(0))
    s = np.array([100.0, 100.5])
    rec = {"distFromStart": s, "trackPos": np.array([-0.9, 0.0]), "angle": np.zeros(2)}
    under = exc.wheel_surfaces(track, world._cp[0], rec)
    road = track.surface_at(s, 0.0)
    assert list(under[0] != road[0]) == [True, False, True, False]      # FR, FL, RR, RL
    assert not np.any(under[1] != road[1])


def test_message_table_starts_on_the_traces_state_and_follows_a_straight_run(exc, tmp_path):
    # a made-up trace of the bundled sedan running straight down madsim-road's first straight at
    # 72 km/h, centred, wheels rolling, no commands but a light throttle: the table's first row
    # is the placement (madsim's figures equal TORCS's, heading change 0), it has lead + horizon
    # + 1 rows, and over 0.2 s madsim's car stays straight and near the trace's speed
    import csv
    import gzip

    from madsim.tracks import load_track

    track = load_track("madsim-road")
    n = exc.fidelity.COUNTDOWN_MESSAGES + 40
    v = 20.0                                           # m/s
    s0 = 20.0
    path = tmp_path / "madsim-road__madsim-sedan__100.csv.gz"
    with gzip.open(path, "wt", newline="") as f:
        w = csv.writer(f)
        w.writerow(exc.COLUMNS)
        for j in range(n):
            k = j - exc.fidelity.COUNTDOWN_MESSAGES
            t = 0.02 * max(k, 0)
            row = {"curLapTime": t, "lastLapTime": 0.0, "damage": 0.0, "distFromStart": s0 + v * t,
                   "speedX": 3.6 * v, "speedY": 0.0, "angle": 0.0, "trackPos": 0.0, "fuel": 40.0, "gear": 3.0,
                   "rpm": 5000.0, "z": 0.3, "accel": 0.2, "brake": 0.0, "gear_cmd": 3.0, "steer": 0.0, "clutch": 0.0}
            for q in range(4):
                row[f"wheelSpinVel_{q}"] = v / 0.3
            w.writerow([row[c] for c in exc.COLUMNS])
    assert track.curvature_at(np.array([s0, s0 + v * 0.8])).max() == 0.0     # a straight throughout
    rows = exc.message_table(path, 5, 2, 8, [])
    assert len(rows) == 2 + 8 + 1
    first = rows[0]
    assert first["msg"] == 3
    for key in ("speedX", "speedY", "trackPos"):
        assert first["madsim"][key] == pytest.approx(first["torcs"][key], abs=1e-9)
    np.testing.assert_allclose(first["madsim"]["spins"], first["torcs"]["spins"], atol=1e-9)
    assert first["madsim"]["dpsi"] == 0.0 and first["torcs"]["dpsi"] == 0.0
    road = track.surfaces[int(track.surface_at(np.array([s0]), 0.0)[0])].name
    assert all(r["under"] == [road] * 4 for r in rows)
    last = rows[-1]["madsim"]
    assert abs(last["dpsi"]) < 1e-3 and abs(last["trackPos"]) < 1e-3
    assert last["speedX"] == pytest.approx(72.0, abs=2.0)


def test_parse_leads_expands_ranges(exc):
    assert exc.parse_leads("1-4,10,20") == [1, 2, 3, 4, 10, 20]
    assert exc.parse_leads("3,6,10,15") == [3, 6, 10, 15]
    assert exc.parse_leads("5-5,") == [5]


def test_sweep_summary_counts_the_leads_that_turn_more_in_torcs_direction(exc):
    # TORCS turns right (negative heading change) by 0.5 rad: errors -0.03 and -0.01 turn more,
    # +0.02 and 0 do not; TORCS's figure (error 0) lies inside [-0.03, +0.02]
    s = exc.sweep_summary(np.array([-0.03, 0.02, -0.01, 0.0]), np.full(4, -0.5))
    assert s["more"] == 2 and s["n"] == 4 and s["inside"]
    assert s["mean"] == pytest.approx(-0.005, abs=1e-12)
    assert (s["min"], s["max"]) == (-0.03, 0.02)
    # a left turn: the same errors now mean turning less where negative; all on one side: outside
    s = exc.sweep_summary(np.array([0.01, 0.04, 0.02]), np.full(3, 0.3))
    assert s["more"] == 3 and not s["inside"]
    s = exc.sweep_summary(np.array([-0.01, -0.04]), np.array([0.3, 0.2]))
    assert s["more"] == 0 and not s["inside"]
