"""`madsim run`: the main job on the bundled default scenario (issue 7)."""

import subprocess
import sys
import time

import matplotlib.image as mpimg
import numpy as np
import pytest

from madsim.run import TrackSpeedDriver, run


def test_madsim_run_with_no_arguments_finishes_a_lap_within_60_s(tmp_path):
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "madsim.cli", "run", "--quiet"], capture_output=True,
                          text=True, timeout=180, cwd=tmp_path)
    wall = time.perf_counter() - start
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert wall < 60.0
    lines = proc.stdout.strip().splitlines()
    assert "ended by LapCompleted" in lines[0]
    header = lines[1].split()
    assert header[:2] == ["car", "laps"] and "collisions" in header
    rows = lines[2:]
    # four traffic cars of mixed behaviours, then the learner, which completed its lap
    assert [r.split()[0] for r in rows] == ["traffic"] * 4 + ["driver"]
    assert {"(ConstVel)", "(SinusoidalSpeed)", "(RandomLaneSwitch)", "(Parked)"} <= set(" ".join(rows).split())
    driver = rows[-1].split()
    lap_time, avg, top = float(driver[2]), float(driver[3]), float(driver[4])
    assert int(driver[1]) == 1 and 60.0 < lap_time < 300.0
    # a 3,038 m lap from 25 m behind the line: average speed consistent with the lap time
    assert avg == pytest.approx(3.6 * 3063 / lap_time, rel=0.1)
    assert top <= 109.0                                  # the scenario's 30 m/s target


def test_run_plot_and_statistics(tmp_path):
    out = tmp_path / "run.png"
    stats = run(episodes=1, plot=str(out), progress=False, log=lambda m: None)[0]
    img = mpimg.imread(out)
    assert img.shape[0] > 400 and (img[..., :3].mean(axis=2) < 0.9).mean() > 0.05
    driver = stats[-1]
    assert driver.kind == "learner" and len(driver.lap_times) == 1
    assert driver.off_track_ticks == 0
    parked = [s for s in stats if "Parked" in s.label][0]
    assert parked.top_speed_kmh < 1.0            # a parked car never moves unless hit


def test_driver_passes_on_the_side_away_from_the_car_ahead():
    drv = TrackSpeedDriver(108.0, False, 30.0)
    row = {"track": [50.0] * 19, "opponents": [200.0] * 36}
    row["opponents"][17] = 30.0                   # just left of the nose, 30 m ahead
    lane, speed = drv(row)
    assert lane < 0 and speed > 50                # moves right, keeps going
    row["opponents"][17] = 200.0
    row["opponents"][18] = 10.0                   # right behind a car, just right of the nose
    lane, speed = drv(row)
    assert lane > 0 and speed == pytest.approx(30.0)   # slows to 2.5 km/h per metre, floored at 30
    row["opponents"][18] = 200.0
    lane, speed = drv(row)
    assert lane == 0.0 and speed == pytest.approx(min(108.0, 3.6 * np.sqrt(2 * 5.0 * 50.0)))
