"""Traffic behaviours (issue 6; spec madras-features.md section 4; paper Appendix C).

Each behaviour drives real cars in a `World` on a bundled track: place the cars with
`World.reset(placements)`, then every tick `frame = suite.frame()`, controls from
`behaviour.act(frame.row(k))`, `world.step(controls)`. Tolerances are the issue's acceptance
numbers unless a comment says otherwise.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
import pytest
import yaml

from madsim.agents.traffic import (
    BEHAVIOURS,
    ConstVel,
    DriveAndPark,
    Parked,
    RandomLaneSwitch,
    RandomStopping,
    SinusoidalSpeed,
    TrafficBehaviour,
    draw_traffic_placements,
    make_behaviour,
    register_behaviour,
)
from madsim.agents.traffic_fleet import TrafficFleet
from madsim.cars import load_car
from madsim.envs.config import TRAFFIC_PARAMS, load_config
from madsim.physics.sensors import N_VALUES, O_CURLAP, O_SX, O_TPOS, O_TRACK, SensorSuite
from madsim.physics.world import World
from madsim.tracks import load_track

TICK_S = 0.02
KMH = 3.6


@dataclass
class Run:
    """What `drive` recorded, one row per tick (before the tick's step), one column per car."""

    t: np.ndarray            # (T,) s
    s: np.ndarray            # (T, N) distFromStart, m
    n: np.ndarray            # (T, N) lateral offset, m, left +
    trackpos: np.ndarray     # (T, N)
    speed: np.ndarray        # (T, N) speedX, m/s
    controls: np.ndarray     # (T, N, 4) steer, accel, brake, gear
    car_contact: np.ndarray  # (T, N) contact with another car during the step
    infos: list[dict]
    world: World


def drive(track_name: str, behaviours: list[TrafficBehaviour], placements, seconds: float, *,
          seed: int = 0, car: str = "madsim-sedan") -> Run:
    """Run traffic cars alone on a track (no learner) and record them."""
    track = load_track(track_name)
    n_cars = len(behaviours)
    world = World(track, [load_car(car)] * n_cars, np.random.default_rng(seed))
    pl = np.asarray(placements, dtype=float)
    world.reset(pl)
    suite = SensorSuite(world)
    infos = []
    for k, b in enumerate(behaviours):
        info = {"track_length": track.length, "track_width": track.width, "car": car,
                "tick_s": TICK_S, "placement": (pl[k, 0], pl[k, 1])}
        b.reset(np.random.default_rng([seed, k]), info)
        infos.append(info)
    ticks = round(seconds / TICK_S)
    rec = {name: np.zeros((ticks, n_cars)) for name in ("s", "n", "tp", "v", "hit")}
    controls = np.zeros((ticks, n_cars, 4))
    u = np.zeros((n_cars, 5))
    for i in range(ticks):
        frame = suite.frame()
        for k, b in enumerate(behaviours):
            u[k, :4] = b.act(frame.row(k))
        controls[i] = u[:, :4]
        rec["s"][i], rec["tp"][i], rec["v"][i] = frame.distFromStart, frame.trackPos, frame.speedX / KMH
        rec["n"][i] = world.n
        world.step(u)
        rec["hit"][i] = world.contact_car
    return Run(np.arange(ticks) * TICK_S, rec["s"], rec["n"], rec["tp"], rec["v"], controls,
               rec["hit"].astype(bool), infos, world)


# --- registry and configuration -------------------------------------------------------------


def test_the_six_behaviours_are_registered_by_name():
    assert {"ConstVel", "SinusoidalSpeed", "RandomLaneSwitch", "DriveAndPark", "Parked",
            "RandomStopping"} <= set(BEHAVIOURS)
    assert BEHAVIOURS["DriveAndPark"] is DriveAndPark and DriveAndPark.behaviour_name == "DriveAndPark"


@pytest.mark.parametrize("name", sorted(TRAFFIC_PARAMS))
def test_class_defaults_are_the_config_schema_defaults(name):
    """The config (madsim.envs.config.TRAFFIC_PARAMS) is the schema; the classes agree with it,
    so `madsim traffic` without --param drives like a config entry without parameters."""
    assert BEHAVIOURS[name]().params == dict(TRAFFIC_PARAMS[name])


def test_register_behaviour_rejects_a_second_class_under_a_taken_name():
    with pytest.raises(ValueError, match="already registered"):
        @register_behaviour("ConstVel")
        class Other(TrafficBehaviour):
            def target(self, row, t_s):
                return 0.0, 1.0
    with pytest.raises(TypeError, match="not a TrafficBehaviour"):
        register_behaviour("NotOne")(dict)
    assert BEHAVIOURS["ConstVel"] is ConstVel


def test_a_user_behaviour_registers_and_is_accepted_by_the_config():
    @register_behaviour("TestCreeper")
    class Creeper(TrafficBehaviour):
        def __init__(self, speed: float = 2.0, **base):
            super().__init__(**base)
            self.params = {"speed": float(speed)}

        def target(self, row, t_s):
            return 0.0, self.params["speed"]

    try:
        cfg = load_config({"traffic": [{"behaviour": "TestCreeper", "speed": 3.0}]})
        b = make_behaviour(cfg.traffic[0])
        assert isinstance(b, Creeper) and b.params == {"speed": 3.0}
        run = drive("madsim-oval", [b], [[50.0, 0.0, 0.0]], 12.0)
        assert run.speed[-50:, 0] == pytest.approx(3.0, abs=0.3)
    finally:
        BEHAVIOURS.pop("TestCreeper", None)


def test_shipped_mixed_traffic_config_builds_every_behaviour():
    from importlib import resources
    path = resources.files("madsim.envs") / "configs" / "mixed_traffic.yml"
    cfg = load_config(str(path))
    built = [make_behaviour(entry) for entry in cfg.traffic]
    assert [b.behaviour_name for b in built] == [e.behaviour for e in cfg.traffic]
    for b, entry in zip(built, cfg.traffic):
        assert b.params == dict(entry.params)
        assert b.window_s == entry.collision_time_window and b.min_safe_dist == entry.min_safe_dist


def test_reset_needs_a_generator_and_never_touches_numpy_global_state():
    b = RandomStopping(stop_probability=0.5, max_stop_duration=1.0)
    with pytest.raises(TypeError, match="Generator"):
        b.reset(42, {})
    before = np.random.get_state()[1].copy()
    drive("madsim-oval", [b, RandomLaneSwitch(lane_change_interval=0.5)],
          [[50.0, -3.0, 0.0], [80.0, 3.0, 0.0]], 4.0)
    assert np.array_equal(np.random.get_state()[1], before)


def test_same_seed_same_draws_and_trajectory_other_seed_other_draws():
    def once(seed):
        b = RandomLaneSwitch(target_speed=12.0, lane_change_interval=1.0, lanes=(-0.5, 0.5))
        return drive("madsim-oval", [b], [[50.0, 0.0, 0.0]], 10.0, seed=seed)
    a, b, c = once(1), once(1), once(2)
    assert a.infos[0]["lane_draws"] == b.infos[0]["lane_draws"]
    assert np.array_equal(a.n, b.n)
    assert a.infos[0]["lane_draws"] != c.infos[0]["lane_draws"]


# --- the behaviours do what they say ----------------------------------------------------------


@pytest.mark.parametrize("speed, lane", [(16.67, -0.5), (11.11, 0.4)])
def test_const_vel_holds_speed_within_2kmh_and_lane_within_005(speed, lane):
    """madsim-oval (15 m wide, bends of 150 m radius): after 15 s of settling, 45 s held."""
    run = drive("madsim-oval", [ConstVel(target_speed=speed, lane=lane)], [[30.0, 0.0, 0.0]], 60.0)
    settled = run.t >= 15.0
    assert np.abs(run.speed[settled, 0] - speed).max() * KMH < 2.0
    assert np.abs(run.trackpos[settled, 0] - lane).max() < 0.05


def test_const_vel_keeps_its_lane_through_the_12m_bends_of_the_street():
    """madsim-street is 5 m wide with 90-degree bends of 12 m radius; MADRaS's PID alone drifts
    ~1 trackPos unit (off the road) in them. Measured here: 0.08 at lane 0.6; bound 0.12."""
    run = drive("madsim-street", [ConstVel(target_speed=13.89, lane=0.6)], [[180.0, 1.5, 0.0]], 40.0)
    assert run.s[-1, 0] > 500.0                      # went through the bends at 214, 409, 554 m
    assert np.abs(run.trackpos[:, 0] - 0.6).max() < 0.12


def test_sinusoidal_speed_follows_mean_plus_amplitude_sine():
    """Fit v = m + a sin(w t) + b cos(w t) to the speed after 10 s: amplitude and mean within
    10 %, phase lag within 10 % of the period."""
    mean, amp, period = 15.0, 4.0, 20.0
    b = SinusoidalSpeed(mean_speed=mean, speed_amplitude=amp, speed_period=period, lane=0.0)
    run = drive("madsim-oval", [b], [[30.0, 0.0, 0.0]], 70.0)
    keep = run.t >= 10.0
    w = 2.0 * math.pi / period
    t = run.t[keep]
    basis = np.stack([np.ones_like(t), np.sin(w * t), np.cos(w * t)], axis=1)
    (m, a, c), *_ = np.linalg.lstsq(basis, run.speed[keep, 0], rcond=None)
    fitted_amp, lag = math.hypot(a, c), -math.atan2(c, a)      # v = m + A sin(w t - lag)
    assert fitted_amp == pytest.approx(amp, rel=0.10)
    assert m == pytest.approx(mean, rel=0.10)
    assert abs(lag) < 0.10 * 2.0 * math.pi
    assert lag >= 0.0                                  # the car follows, it does not lead


def test_random_lane_switch_draws_once_per_interval_and_drives_there():
    """MADRaS never advanced its step counter and drew a lane every tick; here one draw per
    interval, at t = k * interval, and the car is in the drawn lane before the next draw."""
    interval, lanes = 8.0, (-0.3, 0.3)
    b = RandomLaneSwitch(target_speed=13.0, lane_change_interval=interval, lanes=lanes)
    run = drive("madsim-oval", [b], [[30.0, 0.0, 0.0]], 64.0, seed=6)     # seed 6: 6 changes
    draws = run.infos[0]["lane_draws"]
    assert [t for t, _ in draws] == pytest.approx([k * interval for k in range(8)], abs=1e-9)
    assert {lane for _, lane in draws} == set(lanes)
    changes = sum(1 for (_, x), (_, y) in itertools.pairwise(draws) if x != y)
    assert changes == 6
    for k, (t0, lane) in enumerate(draws):
        end = round((t0 + interval) / TICK_S) - 1           # last tick before the next draw
        assert run.trackpos[end, 0] == pytest.approx(lane, abs=0.05), f"interval {k}"
        # within an interval the car only moves towards the drawn lane
        start = round(t0 / TICK_S)
        seg = run.trackpos[start:end + 1, 0]
        assert np.all(np.diff(seg) * np.sign(lane - seg[0]) > -0.01)


def test_random_lane_switch_waits_while_the_side_is_taken():
    """A car driving beside on the left (same speed): a draw of the left lane waits."""
    mover = RandomLaneSwitch(target_speed=10.0, lane_change_interval=2.0, lanes=(0.6, 0.6))
    beside = ConstVel(target_speed=10.0, lane=0.45)
    run = drive("madsim-oval", [mover, beside], [[60.0, -3.75, 0.0], [60.0, 3.4, 0.0]], 12.0)
    assert run.trackpos[:, 0].max() < -0.2                    # stayed in its lane ...
    assert not run.car_contact.any()
    assert run.infos[0]["lane_draws"][0][1] == 0.6            # ... although it wanted to move


def test_drive_and_park_stops_within_1m_of_its_drawn_spot_and_stays():
    b = DriveAndPark(target_speed=13.89, parking_lane=(0.3, 0.5), parking_distance=(150.0, 170.0))
    run = drive("madsim-street", [b], [[10.0, 0.0, 0.0]], 40.0, seed=5)
    info = run.infos[0]
    assert 0.3 <= info["parking_lane"] <= 0.5 and 150.0 <= info["parking_distance"] <= 170.0
    hw = 2.5
    miss = math.hypot(run.s[-1, 0] - info["parking_distance"], run.n[-1, 0] - info["parking_lane"] * hw)
    assert miss < 1.0
    last10 = run.t >= 30.0
    assert np.ptp(run.s[last10, 0]) < 0.01 and np.abs(run.speed[last10, 0]).max() < 0.05
    assert np.all(run.controls[last10, 0, 1] == 0.0) and np.all(run.controls[last10, 0, 2] == 1.0)
    assert run.speed[:, 0].max() * KMH > 45.0              # it did drive at its speed on the way


def test_drive_and_park_beyond_the_start_line_learns_the_track_length_from_the_sensors():
    """As a UDP client it is told nothing about the track: start 30 m before the line, park at
    40 m after it (MADRaS's ParkedAgent case: cross the line once, then park)."""
    track = load_track("madsim-street")
    b = DriveAndPark(target_speed=12.0, parking_lane=(0.0, 0.0), parking_distance=(40.0, 40.0))
    world = World(track, [load_car("madsim-sedan")], np.random.default_rng(0))
    world.reset([[track.length - 30.0, 0.0, 0.0]])
    suite = SensorSuite(world)
    b.reset(np.random.default_rng(0), {})                       # no track length, no width
    for _ in range(int(25.0 / TICK_S)):
        world.step(np.array([[*b.act(suite.frame().row(0)), 0.0]]))
    assert b.track_length == pytest.approx(track.length, abs=0.05)
    assert world.s[0] == pytest.approx(40.0, abs=1.0) and world.speed[0] < 0.05


def test_parked_stands_with_the_brake_held_from_the_first_tick_while_traffic_passes():
    parked = Parked()
    passer = ConstVel(target_speed=10.0, lane=-0.6)
    run = drive("madsim-street", [parked, passer], [[120.0, 1.5, 0.0], [60.0, -1.5, 0.0]], 20.0)
    assert np.all(run.controls[:, 0, 1] == 0.0) and np.all(run.controls[:, 0, 2] == 1.0)
    assert np.ptp(run.s[:, 0]) < 0.01 and np.ptp(run.n[:, 0]) < 0.01
    assert run.s[-1, 1] > 200.0 and not run.car_contact.any()   # the other car went past


def test_parked_moves_only_when_hit():
    """A car driven straight into the parked one (no avoidance: raw controls) moves it."""
    track = load_track("madsim-oval")
    world = World(track, [load_car("madsim-sedan")] * 2, np.random.default_rng(0))
    world.reset([[100.0, 0.0, 0.0], [80.0, 0.0, 8.0]])
    suite = SensorSuite(world)
    parked = Parked()
    parked.reset(np.random.default_rng(0), {})
    s0 = float(world.s[0])
    hit_at = None
    for i in range(200):
        u = np.array([[*parked.act(suite.frame().row(0)), 0.0], [0.0, 0.5, 0.0, 1.0, 0.0]])
        before = float(world.s[0])
        world.step(u)
        if hit_at is None and world.contact_car[0]:
            hit_at = i
            assert before == pytest.approx(s0, abs=0.005)        # stood still until the hit ...
    assert hit_at is not None
    assert world.s[0] - s0 > 0.05                                 # ... until it was hit


def test_random_stopping_halts_without_throttle_and_drives_on():
    b = RandomStopping(target_speed=12.0, lane=0.0, stop_probability=0.01, max_stop_duration=2.0)
    run = drive("madsim-oval", [b], [[30.0, 0.0, 0.0]], 60.0, seed=2)
    stops = run.infos[0]["stops"]
    assert len(stops) >= 3
    starts = [t for t, _ in stops]
    restarts = 0
    for t0, duration in stops:
        assert 0.0 < duration <= 2.0
        i0 = round(t0 / TICK_S)
        standing = np.nonzero(run.speed[i0:, 0] < 0.3)[0]
        assert standing.size, f"the stop at {t0:.2f} s never came to a standstill"
        # the standstill is counted from the first slow row; allow one tick of rounding
        stand_end = i0 + standing[0] + math.ceil(duration / TICK_S) - 1
        assert np.all(run.controls[i0:stand_end - 1, 0, 1] == 0.0)   # no throttle while halting
        check = stand_end + 250                                      # 5 s after the standstill
        if check < len(run.t) and not any(t0 < t <= check * TICK_S for t in starts):
            assert run.speed[check, 0] > 8.0, f"no restart after the stop at {t0:.2f} s"
            restarts += 1
    assert restarts >= 2
    assert run.speed[:, 0].max() > 11.0


# --- the base class's safety nets (synthetic rows) --------------------------------------------


def _row(*, speed_kmh=50.0, tp=0.0, angle=0.0, opponents=None, ahead=200.0, half_width=5.0):
    """A synthetic SCR row on a straight road: edges by the +-90 deg rays, `ahead` elsewhere."""
    track = [-1.0] * 19
    if abs(tp) < 1.0:
        track = [(1.0 - tp) * half_width] + [ahead] * 17 + [(1.0 + tp) * half_width]
    return {"angle": angle, "trackPos": tp, "speedX": speed_kmh, "curLapTime": 1.0,
            "distFromStart": 100.0, "distRaced": 0.0, "track": track,
            "opponents": opponents or [200.0] * 36, "rpm": 3000.0, "gear": 2}


def _fresh(behaviour):
    behaviour.reset(np.random.default_rng(0), {"track_width": 10.0})
    return behaviour


@pytest.mark.parametrize("sector", range(9, 18))
def test_collision_cone_is_symmetric(sector):
    """MADRaS looked at sectors 16-18 (20 deg left to 10 deg right); here sector j and its
    mirror 35 - j give the same response."""
    out = []
    for j in (sector, 35 - sector):
        opp = [200.0] * 36
        opp[j] = 8.0
        b = _fresh(ConstVel(target_speed=13.89))
        out.append(b.act(_row(opponents=opp)))
    (s1, a1, b1, _), (s2, a2, b2, _) = out
    assert (a1, b1) == (a2, b2) and s1 == pytest.approx(-s2, abs=1e-12)


def test_car_ahead_within_the_time_window_brakes():
    """50 km/h with a car 8 m ahead (gap 3.2 m < 1 m + 1 s x 13.9 m/s): brake, no throttle."""
    opp = [200.0] * 36
    opp[17] = 8.0
    _, accel, brake, _ = _fresh(ConstVel(target_speed=13.89)).act(_row(opponents=opp))
    assert accel == 0.0 and brake > 0.5


def test_car_far_ahead_or_beside_in_another_lane_does_not_brake():
    opp = [200.0] * 36
    opp[17] = 60.0                      # ahead, far
    opp[12] = 6.0                       # 55 deg right, 6 m: 4.9 m to the side
    _, accel, brake, _ = _fresh(ConstVel(target_speed=13.89)).act(_row(opponents=opp))
    assert brake == 0.0 and accel > 0.0


def test_the_pids_own_braking_is_kept_when_nothing_is_ahead():
    """MADRaS set brake = 0 whenever no car was near, overriding the PID's braking."""
    _, accel, brake, _ = _fresh(ConstVel(target_speed=8.0)).act(_row(speed_kmh=60.0))
    assert accel == 0.0 and brake > 0.5


@pytest.mark.parametrize("tp, angle", [(-0.85, 0.3), (0.85, -0.3)])
def test_off_track_guard_steers_towards_the_road_not_the_nearer_edge(tp, angle):
    """Near the right edge (tp < 0) heading out (angle > 0: pointing right of the road), steer
    left (+); MADRaS steered towards the nearer rangefinder side (right, -1). Mirror for the
    left edge. The car's own lane is the centre."""
    steer, accel, _, _ = _fresh(ConstVel(target_speed=13.89, lane=0.0)).act(
        _row(tp=tp, angle=angle))
    assert steer * tp < 0.0 and accel == 0.0


def test_a_car_off_the_road_drives_back_onto_it():
    """Placed 1 m beyond the left edge of madsim-road (rangefinders -1), heading along the road:
    MADRaS's loop never ended off the road; here the car is back on it within 10 s."""
    road = load_track("madsim-road")
    run = drive("madsim-road", [ConstVel(target_speed=13.89, lane=0.5)],
                [[400.0, road.width / 2.0 + 1.0, 0.0]], 10.0)
    assert run.trackpos[0, 0] > 1.0
    assert abs(run.trackpos[-1, 0]) < 1.0
    assert run.speed[run.trackpos[:, 0] > 1.0, 0].max() < 3.5          # crawled while off it


def test_countdown_states_hold_the_brake_and_do_not_start_the_clock():
    b = _fresh(SinusoidalSpeed(mean_speed=10.0, speed_amplitude=5.0, speed_period=4.0))
    row = _row(speed_kmh=0.0)
    assert b.act(dict(row, curLapTime=-0.5)) == (0.0, 0.0, 1.0, 1)
    assert b.ticks == 0
    b.act(row)
    assert b.ticks == 1


# --- placement (paper, Appendix C) -----------------------------------------------------------


def _ks_uniform(values, low, high) -> float:
    """Kolmogorov-Smirnov distance of a sample from U(low, high)."""
    x = np.sort((np.asarray(values) - low) / (high - low))
    n = len(x)
    return float(max(np.max(np.arange(1, n + 1) / n - x), np.max(x - np.arange(n) / n)))


def _entries(*pairs, behaviour="ConstVel"):
    cfg = load_config({"traffic": [{"behaviour": behaviour, "initial_distance": list(d),
                                    "initial_trackpos": list(p)} for d, p in pairs]})
    return list(cfg.traffic)


def test_placement_count_is_discrete_uniform_and_positions_continuous_uniform():
    """5000 seeds: count in [2, 6] (chi-square, 4 dof, 0.1 % critical value 18.5); the first
    car's distance ~ U(100, 300) m and trackPos ~ U(-0.8, 0.8) (KS distance below the 1 %
    critical value 1.63 / sqrt(n)); the ranges of the other cars hold."""
    road = load_track("madsim-road")
    entries = _entries(((100.0, 300.0), (-0.8, 0.8)), *[((600.0 + 150 * i, 700.0 + 150 * i),
                                                          (-0.5, 0.5)) for i in range(5)])
    counts, s0, tp0 = [], [], []
    for seed in range(5000):
        used, pl = draw_traffic_placements(entries, (2, 6), np.random.default_rng(seed), road)
        assert len(used) == len(pl) and used == entries[:len(pl)]
        counts.append(len(pl))
        s0.append(pl[0, 0])
        tp0.append(pl[0, 1] / (road.width / 2.0))
        for i, (entry, (s, n, v)) in enumerate(zip(used, pl)):
            assert entry.initial_distance[0] <= s <= entry.initial_distance[1] and v == 0.0
    observed = np.bincount(counts, minlength=7)[2:]
    assert observed.sum() == 5000 and np.all(np.bincount(counts)[:2] == 0)
    chi2 = float(((observed - 1000.0) ** 2 / 1000.0).sum())
    assert chi2 < 18.5
    assert _ks_uniform(s0, 100.0, 300.0) < 1.63 / math.sqrt(5000)
    assert _ks_uniform(tp0, -0.8, 0.8) < 1.63 / math.sqrt(5000)


def test_placement_without_ranges_uses_the_grid_and_never_overlaps():
    street = load_track("madsim-street")
    cfg = load_config({"traffic": [{"behaviour": "ConstVel"}] * 3})
    _, pl = draw_traffic_placements(cfg.traffic, None, np.random.default_rng(0), street)
    from madsim.physics.tables import grid_positions
    s, n = grid_positions(street, 3)
    assert np.allclose(pl[:, 0], s) and np.allclose(pl[:, 1], n)
    crowd = _entries(*[((0.0, 80.0), (-0.6, 0.6))] * 8)
    for seed in range(50):
        _, pl = draw_traffic_placements(crowd, None, np.random.default_rng(seed), street)
        for i in range(8):
            for j in range(i):
                assert abs(pl[i, 0] - pl[j, 0]) >= 5.78 or abs(pl[i, 1] - pl[j, 1]) >= 2.84


def test_placement_errors_name_the_entry():
    street = load_track("madsim-street")
    with pytest.raises(ValueError, match=r"traffic\[1\] \(ConstVel\): no place"):
        draw_traffic_placements(_entries(*[((10.0, 12.0), (0.0, 0.0))] * 2), None,
                                np.random.default_rng(0), street)
    with pytest.raises(ValueError, match="count range"):
        draw_traffic_placements(_entries(((10.0, 12.0), (0.0, 0.0))), (0, 3),
                                np.random.default_rng(0), street)


# --- safety: mixed traffic on the narrow street ------------------------------------------------

MIXED_STREET_YAML = """
# 8 traffic cars, no learner, madsim-street (5 m wide, bends of 12 m radius). Lanes +-0.6
# (3 m apart) are as close as two 1.84 m cars can pass with the opponents sensor's 10-degree
# sectors; the Parked car blocks the left lane for good.
server: {tracks: [madsim-street], traffic_count: [8, 8]}
traffic:
  - {behaviour: ConstVel, target_speed: 11.0, lane: -0.6, initial_distance: [0, 250], initial_trackpos: [-0.7, -0.5]}
  - {behaviour: SinusoidalSpeed, mean_speed: 10.0, speed_amplitude: 4.0, speed_period: 15.0, lane: 0.6,
     initial_distance: [0, 250], initial_trackpos: [0.5, 0.7]}
  - {behaviour: RandomLaneSwitch, target_speed: 12.0, lane_change_interval: 6.0, lanes: [-0.6, 0.6],
     initial_distance: [0, 250], initial_trackpos: [-0.6, 0.6]}
  - {behaviour: RandomStopping, target_speed: 12.0, lane: -0.6, stop_probability: 0.002, max_stop_duration: 3.0,
     initial_distance: [0, 250], initial_trackpos: [-0.7, -0.5]}
  - {behaviour: DriveAndPark, target_speed: 12.0, parking_lane: [0.5, 0.7], parking_distance: [300, 600],
     initial_distance: [0, 250], initial_trackpos: [0.5, 0.7]}
  - {behaviour: Parked, initial_distance: [100, 400], initial_trackpos: [0.55, 0.7]}
  - {behaviour: ConstVel, target_speed: 13.89, lane: 0.6, initial_distance: [0, 250], initial_trackpos: [0.5, 0.7]}
  - {behaviour: RandomLaneSwitch, target_speed: 10.0, lane_change_interval: 4.0, lanes: [-0.6, 0.6],
     initial_distance: [0, 250], initial_trackpos: [-0.6, 0.6]}
"""


def mixed_street_episode(seed: int, seconds: float = 60.0, *, cfg=None, track=None, cars=None) -> dict:
    """One safety episode: placements from `draw_traffic_placements`, behaviours from the config.
    Returns ticks with a car-car contact, car-ticks off the road (|trackPos| > 1), the distance
    each car drove (m) and which cars stand still at the end outside the Parked car's lane."""
    cfg = cfg or load_config(yaml.safe_load(MIXED_STREET_YAML))
    track = track or load_track(cfg.server.tracks[0])
    rng = np.random.default_rng(seed)
    used, pl = draw_traffic_placements(cfg.traffic, cfg.server.traffic_count, rng, track)
    world = World(track, cars or [load_car(cfg.server.traffic_car)] * len(used), rng)
    world.reset(pl)
    suite = SensorSuite(world)
    behaviours = [make_behaviour(e) for e in used]
    for k, b in enumerate(behaviours):
        b.reset(np.random.default_rng([seed, k]), {"track_length": track.length, "car": cfg.server.traffic_car,
                                                    "track_width": track.width, "tick_s": TICK_S})
    u = np.zeros((len(used), 5))
    contact_ticks = off_track = 0
    for _ in range(round(seconds / TICK_S)):
        frame = suite.frame()
        for k, b in enumerate(behaviours):
            u[k, :4] = b.act(frame.row(k))
        off_track += int(np.count_nonzero(np.abs(frame.trackPos) > 1.0))
        world.step(u)
        contact_ticks += bool(world.contact_car.any())
    stuck = [b.behaviour_name for k, b in enumerate(behaviours)
             if world.speed[k] < 0.5 and world.n[k] < 0.0 and b.behaviour_name != "Parked"]
    return {"contact_ticks": contact_ticks, "off_track": off_track,
            "travelled": [b.travelled for b in behaviours], "stuck": stuck}


SAFETY_EPISODES = 8          # in the suite; benchmarks/traffic_safety.py runs 200


def test_mixed_traffic_on_the_narrow_street_never_collides_nor_leaves_the_road():
    cfg = load_config(yaml.safe_load(MIXED_STREET_YAML))
    track = load_track("madsim-street")
    cars = [load_car(cfg.server.traffic_car)] * 8
    moved = []
    for seed in range(SAFETY_EPISODES):
        out = mixed_street_episode(seed, cfg=cfg, track=track, cars=cars)
        assert out["contact_ticks"] == 0, f"seed {seed}: traffic-traffic contact"
        assert out["off_track"] == 0, f"seed {seed}: a car left the road"
        moved.append(out["travelled"])
    moved = np.array(moved)
    # not safe by standing still: the cars that drive cover 100 m or more on average
    assert moved[:, [0, 2, 3, 7]].mean() > 150.0


def test_the_documented_example_behaviour_runs(capsys):
    """docs/traffic.md's example (a user behaviour, registered and driven on madsim-road)."""
    from pathlib import Path
    text = (Path(__file__).resolve().parents[2] / "docs" / "traffic.md").read_text()
    code = text.split("```python\n", 1)[1].split("```", 1)[0]
    try:
        exec(compile(code, "docs/traffic.md", "exec"), {"__name__": "traffic_doc_example"})
        out = capsys.readouterr().out
        assert "lanes drawn: [" in out
        distance = float(out.split(" m from the start")[0])
        assert 150.0 < distance < 200.0           # 50 m + ~10 s at up to 15 m/s
        cfg = load_config({"traffic": [{"behaviour": "Weaver", "speed": 10.0}]})
        assert make_behaviour(cfg.traffic[0]).params == {"speed": 10.0, "width": 0.5}
    finally:
        BEHAVIOURS.pop("Weaver", None)


# --- the fleet: all traffic cars in one compiled call -------------------------------------------


class Weaving(TrafficBehaviour):
    """A user behaviour (Python target): lane +-0.5, switching every 2 s, 9 m/s."""

    def target(self, row, t_s):
        return (0.5 if int(t_s / 2.0) % 2 else -0.5), 9.0


class Gentle(ConstVel):
    """A behaviour that overrides act (and drives through the built-in one): throttle <= 0.3."""

    def act(self, row):
        steer, accel, brake, gear = super().act(row)
        return steer, min(accel, 0.3), brake, gear


class Foreign:
    """A traffic_factory object that is no TrafficBehaviour: creeps straight on."""

    def reset(self, rng, info):
        pass

    def act(self, row):
        return 0.0, 0.2 if row["speedX"] < 10.0 else 0.0, 0.0, 1


def _episode(seed: int):
    cfg = load_config(yaml.safe_load(MIXED_STREET_YAML))
    track = load_track("madsim-street")
    rng = np.random.default_rng(seed)
    used, pl = draw_traffic_placements(cfg.traffic, cfg.server.traffic_count, rng, track)
    behaviours = [make_behaviour(e) for e in used] + [Weaving(), Foreign(), Gentle(lane=-0.6)]
    pl = np.vstack([pl, [[420.0, 0.0, 0.0], [470.0, 0.0, 0.0], [520.0, -1.5, 0.0]]])
    world = World(track, [load_car(cfg.server.traffic_car)] * len(behaviours),
                  np.random.default_rng(seed))
    world.reset(pl)
    infos = []
    for k, b in enumerate(behaviours):
        info = {"track_length": track.length, "track_width": track.width, "tick_s": TICK_S,
                "car": cfg.server.traffic_car}
        b.reset(np.random.default_rng([seed, k]), info)
        infos.append(info)
    return world, SensorSuite(world), behaviours, infos


def test_a_fleet_drives_every_car_bit_identically_to_each_behaviour_alone():
    """8 mixed built-in cars (lane switches, random stops, parking), a user behaviour, one that
    overrides act and a foreign object: one fleet call per tick == one act per car, for 20 s (the random draws
    of RandomStopping cross several 64-draw refills)."""
    ticks = 1000
    world, suite, behaviours, infos_a = _episode(3)
    u = np.zeros((len(behaviours), 5))
    controls_a = []
    for _ in range(ticks):
        frame = suite.frame()
        for k, b in enumerate(behaviours):
            u[k, :4] = b.act(frame.row(k))
        controls_a.append(u.copy())
        world.step(u)
    world, suite, behaviours, infos_b = _episode(3)
    fleet = TrafficFleet(len(behaviours))
    for k, b in enumerate(behaviours):
        fleet.put(k, b)
    rows = np.arange(len(behaviours))
    u = np.zeros((len(behaviours), 5))
    controls_b = []
    for _ in range(ticks):
        fleet.act(suite.frame().flat, u, rows)
        controls_b.append(u.copy())
        world.step(u)
    assert np.array_equal(np.array(controls_a), np.array(controls_b))
    assert infos_a == infos_b
    assert sum(len(i.get("lane_draws", ())) for i in infos_b) > 4     # draws were recorded
    assert behaviours[0].travelled > 100.0                           # state read from the fleet


def test_random_stopping_consumes_its_generator_draw_by_draw():
    """A car standing still (speed 0): each tick it drives it draws u1 and halts if u1 < p,
    for max (1 - u2) s; the stops recorded equal that rule applied to rng.random() draws of the
    same seed, over 300 ticks (several refills of the 64-draw buffer)."""
    p, max_s = 0.3, 0.1
    b = RandomStopping(stop_probability=p, max_stop_duration=max_s)
    info = {"track_width": 10.0}
    b.reset(np.random.default_rng(7), info)
    row = np.zeros(N_VALUES)
    row[O_TRACK:O_TRACK + 19] = 5.0
    row[O_CURLAP], row[O_SX], row[O_TPOS] = 1.0, 0.0, 0.0
    fleet, u = b._own, np.zeros((1, 4))
    for _ in range(300):
        fleet.act(row[None, :], u, np.zeros(1, dtype=np.int64))
    ref, stand, expected = np.random.default_rng(7), None, []
    for tick in range(300):
        if stand is None and ref.random() < p:
            stand = max_s * (1.0 - ref.random())
            expected.append((tick * TICK_S, stand))
        if stand is not None:
            stand -= TICK_S
            if stand <= 0.0:
                stand = None
    assert len(expected) > 20
    assert info["stops"] == expected
