"""Evaluation figures (madsim.train.evaluate) on hand-made trajectories and on one real lap."""

import numpy as np
import pytest

from madsim.train.evaluate import run_episode, summarise, trajectory_metrics

ONE_LAP_TS = {
    "server": {"tracks": ["madsim-road"], "cars": ["madsim-sedan"], "max_steps": 15000},
    "agents": [{"name": "driver", "target_speed": 27.78, "action": {"space": "TS", "normalised": True},
                "pid": {"latency": 5}, "observation": {"mode": "SingleAgentSimpleLapObs"},
                "rewards": {"Progress2": {"scale": 1.0}},
                "dones": ["LapCompleted", "TimeOut", "Collision", "TurnBackward", "OutOfTrack"]}],
}


def test_half_lap_at_constant_speed():
    # 100 steps of 5 m each on a 1,000 m track: half a lap; speed (30, 40) km/h -> 50 km/h
    # by Pythagoras (MADRaS averages the planar speed), return = sum of rewards.
    d = 5.0 * np.arange(1, 101)
    m = trajectory_metrics(d, [30.0] * 100, [40.0] * 100, [0.5] * 100, track_length_m=1000.0,
                           ticks=500)
    assert m["lap_fraction"] == pytest.approx(0.5, abs=1e-12)
    assert m["avg_speed_kmh"] == pytest.approx(50.0, abs=1e-12)
    assert m["return"] == pytest.approx(50.0, abs=1e-12)
    assert not m["completed"]
    assert m["steps"] == 100
    assert m["sim_time_s"] == pytest.approx(10.0, abs=1e-12)    # 500 ticks x 0.02 s


def test_lap_fraction_counts_laps_and_clips():
    d = [400.0, 800.0, 1200.0]
    zeros = [0.0] * 3
    one = trajectory_metrics(d, zeros, zeros, zeros, track_length_m=1000.0)
    two = trajectory_metrics(d, zeros, zeros, zeros, track_length_m=1000.0, laps=2)
    assert one["lap_fraction"] == 1.0 and one["completed"]          # 1,200 m >= one lap
    assert two["lap_fraction"] == pytest.approx(0.6) and not two["completed"]
    backwards = trajectory_metrics([-3.0, -8.0], [0.0] * 2, [0.0] * 2, [0.0] * 2,
                                   track_length_m=1000.0)
    assert backwards["lap_fraction"] == 0.0                          # reversing is no progress


def test_a_lap_completed_done_counts_as_completed():
    # The lap is timed at the start line, a few metres before distRaced reaches L when the
    # car started behind the line.
    m = trajectory_metrics([990.0], [100.0], [0.0], [1.0], track_length_m=1000.0,
                           dones=("LapCompleted",))
    assert m["completed"] and m["lap_fraction"] == pytest.approx(0.99)


def test_summary_averages_episodes():
    eps = [{"lap_fraction": f, "avg_speed_kmh": v, "completed": c, "return": r, "steps": s}
           for f, v, c, r, s in [(1.0, 80.0, True, 10.0, 100), (0.5, 60.0, False, 4.0, 50),
                                 (1.0, 70.0, True, 7.0, 90), (0.1, 10.0, False, 1.0, 10)]]
    s = summarise(eps)
    assert s["completion_rate"] == pytest.approx(0.5)
    assert s["lap_fraction"] == pytest.approx(0.65)
    assert s["avg_speed_kmh"] == pytest.approx(55.0)
    assert s["mean_return"] == pytest.approx(5.5)
    assert s["mean_steps"] == pytest.approx(62.5)
    assert s["episodes"] == 4


_ONE = {"dist_raced_m": [1.0], "speed_x_kmh": [1.0], "speed_y_kmh": [1.0], "rewards": [1.0],
        "track_length_m": 1.0}


@pytest.mark.parametrize("bad", [
    {**_ONE, "dist_raced_m": [], "speed_x_kmh": [], "speed_y_kmh": [], "rewards": []},  # empty
    {**_ONE, "dist_raced_m": [1.0, 2.0]},                                                # lengths
    {**_ONE, "track_length_m": 0.0},
    {**_ONE, "laps": 0},
])
def test_bad_trajectories_are_refused(bad):
    with pytest.raises(ValueError):
        trajectory_metrics(**bad)


def test_a_real_lap_at_half_the_target_speed():
    # T-S action [centre, 0.5]: the PID holds 50 km/h, which is slow enough for every bend of
    # madsim-road; the lap completes. The mean of the sampled speeds and the average over the
    # lap (distance / simulated time) are two measures of one thing: they agree within
    # 2 km/h (the samples miss the start's acceleration within a step).
    from madsim.envs import MadrasEnv

    env = MadrasEnv(ONE_LAP_TS)
    m = run_episode(env, lambda obs: np.array([0.0, 0.5], dtype=np.float32), seed=3)
    env.close()
    assert m["completed"] and m["dones"] == ("LapCompleted",)
    assert m["lap_fraction"] == pytest.approx(1.0, abs=0.01)
    average = m["distance_m"] / m["sim_time_s"] * 3.6
    assert m["avg_speed_kmh"] == pytest.approx(average, abs=2.0)
    assert 40.0 < m["avg_speed_kmh"] <= 51.0       # a 50 km/h set point, with the standing start
    assert m["sim_time_s"] == pytest.approx(m["steps"] * 5 * 0.02, abs=0.1)   # 5 ticks per step
