"""A few fidelity figures pinned against the real-TORCS traces (../shared/torcs-traces beside
the repository, or $MADSIM_TORCS_TRACES), replayed with benchmarks/fidelity.py's controller,
start and tick schedule. Skipped when the traces are absent. Each replay is a few seconds."""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
TRACES = Path(os.environ.get("MADSIM_TORCS_TRACES", ROOT.parent / "shared" / "torcs-traces"))

pytestmark = [pytest.mark.skipif(not TRACES.is_dir(), reason=f"no real-TORCS traces at {TRACES}"),
              pytest.mark.usefixtures("need_torcs")]


@pytest.fixture(scope="module")
def fidelity():
    spec = importlib.util.spec_from_file_location("fidelity_bench", ROOT / "benchmarks" / "fidelity.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod          # its dataclass looks its module up there
    spec.loader.exec_module(mod)
    yield mod
    sys.modules.pop(spec.name, None)


def replay(fidelity, name, **kw):
    run = fidelity.replay(TRACES / f"{name}.csv.gz", **kw)
    return run, fidelity.compare(run)


def test_torcs_clock_gives_every_message_time_of_a_trace(fidelity):
    from madsim.physics.schedule import TorcsClock

    t, _ = fidelity.read_trace(TRACES / "michigan__car1-trb1__150.csv.gz")
    lap, last = t["curLapTime"], t["lastLapTime"]
    race = lap + np.concatenate([[0.0], np.cumsum(np.where(np.diff(lap) < -1.0, last[1:], 0.0))])
    clock = TorcsClock()
    times = [clock.time] + [clock.substeps() and clock.time for _ in range(race.shape[0] - 1)]
    # the trace writes 6 significant digits
    np.testing.assert_allclose(times, race, rtol=0, atol=3e-5)


@pytest.mark.parametrize("name, t100_pct, v10_pct, spin_pct", [
    # measured with TORCS's explicit spin step and two-sample averages above 3 m/s (issue 12):
    # 0-100 km/h error, speed at 10 s, per-wheel spin error in %; the target is 3 % for
    # the first two, 5 % for the spins
    # 4WD: viscous centre differential and the torque fed back twice; -2.3 / +0.4 / 0.4
    # (before those: -13.5 / +8.2 / 6.2; before the averages -3.6 / +1.0 / 0.7)
    ("e-track-2__155-DTM__full", 3.0, 1.0, 1.0),
    ("e-track-2__car3-trb1__full", 1.5, 0.5, 1.0),     # +0.8 / -0.2 / 0.6 (was -0.3 / -0.1 / 0.8)
    ("e-track-2__baja-bug__full", 3.0, 1.5, 2.0),      # +2.0 / -0.9 / 1.2 (was +0.6 / +0.0 / 1.0)
])
def test_straight_line_runs(fidelity, name, t100_pct, v10_pct, spin_pct):
    _, r = replay(fidelity, name)
    assert abs(r["t100_madsim"] / r["t100_torcs"] - 1.0) * 100 < t100_pct
    assert abs(r["v10_madsim"] / r["v10_torcs"] - 1.0) * 100 < v10_pct
    assert r["spin_err"] < spin_pct            # per wheel, RMS by distance over TORCS's RMS
    assert r["z_rms"] < 1.0                    # cm (ride height under load; was ~9 cm without it)


def test_first_minute_of_a_clean_lap_run(fidelity):
    # forza with car1-trb1 touches nothing: speed and line follow TORCS's closely
    _, r = replay(fidelity, "forza__car1-trb1__100", until_s=60.0)
    assert r["z_rms"] < 1.0                    # cm, measured 0.04
    assert r["v_rms"] < 1.0 and r["pos_rms"] < 0.01     # measured 0.63 km/h (mostly the launch), 0.004
    assert r["dmg_madsim"] == 0


def test_launch_engages_the_gear_as_torcs_does(fidelity):
    # The engine revs in neutral through the countdown; the first gear change snaps it to the
    # wheels (idle), the shift then lets it free-rev at 0.1 throttle, and the controller's
    # 2-1 hunt follows TORCS's tick for tick (issue 12: madsim kept the revs through the shift
    # time, ran its gear request up to 6 and left forza at 8.7 km with car1-stock1).
    run, _ = replay(fidelity, "forza__car1-stock1__100", until_s=0.84)
    t, m = run.torcs, run.madsim
    n = min(t["rpm"].shape[0], m["rpm"].shape[0])
    assert n >= 40
    np.testing.assert_array_equal(m["gear"][:n], t["gear"][:n])
    # rpm to 0.01 % through the 2-1 hunt (32 ticks); later TORCS's per-wheel spins jitter it
    np.testing.assert_allclose(m["rpm"][:32], t["rpm"][:32], rtol=1e-3)


def test_first_upshift_hunts_back_to_first_as_torcs_does(fidelity):
    # michigan with car1-trb1: the 1-2 upshift's clutch re-engages inside a driver call whose
    # accel command the shift had capped at 0.1 (TORCS writes the cap into the command, and the
    # driver rewrites it only at its next call), so the engine brakes the wheels and reads 2483
    # in TORCS, under the controller's 2500 downshift threshold: it shifts back to 1, then up
    # again. madsim read 2591 and stayed in 2 until the cap held to the call's end (issue 12).
    run, _ = replay(fidelity, "michigan__car1-trb1__100", until_s=2.35)
    t, m = run.torcs, run.madsim
    n = min(t["rpm"].shape[0], m["rpm"].shape[0])
    assert n >= 110
    np.testing.assert_array_equal(m["gear"][:n], t["gear"][:n])    # 1 -> 2 -> 1 -> 2 at the same ticks
    k = int(np.flatnonzero(np.diff(t["gear"][:n]) < 0)[-1])         # the tick before the 2-1 hunt
    assert t["rpm"][k] < 2500 and m["rpm"][k] < 2500
    # measured 2493 against 2483; 2456 since each wheel sits at its own place on a curve
    # (session 14): the rear wheels meet the road's roughness at their own phases, as TORCS's do,
    # and their spins (which the engine follows through the clutch) jitter by a few rad/s
    assert m["rpm"][k] == pytest.approx(t["rpm"][k], rel=0.015)


def test_speed_z_is_the_bodys_vertical_velocity_as_in_torcs(fidelity):
    # TORCS's SCR speedZ is the body's vertical velocity (DynGC.vel.z); over e-track-4's first
    # 60 s (hills, crests: TORCS's speedZ 2.4 km/h RMS) madsim's body vz reads it to 0.003 km/h
    # RMS by distance raced. Compared by distance, as speedZ follows the road under the car:
    # per message the figure also holds the cars' gap along the track, which moves whenever the
    # controller's gear change moves by a tick (0.3 m on main at c511a08, 0.017 km/h; 0.8 m with
    # TORCS's shift inertia, 0.044 km/h; 0.042 with session 10's sub-step rounding), not the
    # body's response (issue 12, session 10). The road gradient x the speed (speedZ before
    # issue 12's shift round) was 0.075 km/h per message.
    run, _ = replay(fidelity, "e-track-4__car1-trb1__100", until_s=60.0)
    t, m = run.torcs, run.madsim
    grid = np.arange(10.0, min(t["distRaced"].max(), m["distRaced"].max()) - 1.0, 1.0)
    assert grid.shape[0] > 1000
    tz, mz = fidelity._by_distance(t, "speedZ", grid), fidelity._by_distance(m, "speedZ", grid)
    assert np.sqrt(np.mean(tz ** 2)) > 1.0                          # km/h: it does go up and down
    assert np.sqrt(np.mean((mz - tz) ** 2)) < 0.01


def test_car1_stock1_laps_forza_cleanly_like_torcs(fidelity):
    # TORCS's car1-stock1 touches nothing on forza. madsim's left the road at 2.88 km (and
    # before the gear-order fix at 8.7 km, lap 2 +37 %) until the lateral transfer went through
    # the roll centres split by roll stiffness (its front anti-roll bar, none at the rear;
    # issue 12). The 2.84-2.86 km kink is where TORCS slides out to trackPos 0.99.
    _, r = replay(fidelity, "forza__car1-stock1__100")
    assert r["end_madsim"] == "2 laps"
    assert abs(r["lap2_err"]) < 0.22                     # %, measured -0.01
    assert r["dmg_madsim"] == 0 and np.isnan(r["off_madsim"])
    assert r["v_rms"] < 1.5 and r["pos_rms"] < 0.02     # measured 0.96 km/h, 0.006


@pytest.mark.parametrize("name, lap_pct, damaged", [
    # at the grip limit: wheel-1 left the road at 4171 m (DNF) until the suspension and the
    # body's roll and pitch came in (issue 12's suspension round: -0.01 %, clean, as TORCS).
    # alpine-2 (TORCS: 282 damage points) was pinned here at 1 %; it is a contact run whose
    # outcome swings with the launch's 2-1 gear hunt (rpm 2483 in TORCS against the controller's
    # 2500 threshold): +0.02 to +0.09 % in three variants of the suspension, DNF in the final
    # one (docs/physics.md, "Checked against real TORCS")
    ("wheel-1__car1-trb1__100", 0.22, False),
    # clean laps of two other car classes (measured -0.01 % each)
    ("forza__car1-stock1__100", 0.22, False),
    ("forza__car3-trb1__100", 0.22, False),
])
def test_second_lap_time_and_damage(fidelity, name, lap_pct, damaged):
    _, r = replay(fidelity, name)
    assert abs(r["lap2_err"]) < lap_pct
    assert (r["dmg_madsim"] > 0) == damaged == (r["dmg_torcs"] > 0)


def test_turns_split_each_axles_wheel_spins_as_torcs_does(fidelity):
    # per-wheel spin and the axle differentials (issue 12 round 3): in forza's turns the right
    # and left wheels of an axle differ by 0.6-0.8 rad/s RMS in TORCS; madsim follows that
    # difference within 12 % (front) and 9 % (rear) of its RMS (before: left = right, 100 %)
    _, r = replay(fidelity, "forza__car1-trb1__100", until_s=120.0)
    assert r["split_err"] < 20.0


def test_dirt_2s_landings_take_torcs_bottoming_damage(fidelity):
    """dirt-2's road throws car1-trb1 into the air; TORCS's car takes 142 damage points on its
    packers in four landings before it reaches a wall (message 1057), where each wheel on its
    packers adds int(dammage x rebound x speed into the road x 0.8) (docs/physics.md,
    "Bottoming"). madsim's landings, message for message within 3: each within 20 % of TORCS's
    points (measured 13/15, 64/60, 18/18, 48/49), none elsewhere before the wall."""
    run, _ = replay(fidelity, "dirt-2__car1-trb1__100", until_message=1000)
    landings = ((750, 770), (855, 870), (872, 885), (940, 960))
    for who in (run.torcs, run.madsim):
        assert who["damage"][745] == 0
    for lo, hi in landings:
        torcs = run.torcs["damage"][hi] - run.torcs["damage"][lo]
        madsim = run.madsim["damage"][hi] - run.madsim["damage"][lo]
        assert torcs > 0 and madsim == pytest.approx(torcs, rel=0.2), (lo, hi, torcs, madsim)
    assert run.madsim["damage"][-1] == run.madsim["damage"][960]
    assert run.torcs["damage"][-1] == run.torcs["damage"][960]


def test_a_car_past_torcs_maximum_damage_is_out(fidelity):
    # TORCS's SimUpdate removes a car whose damage exceeds the race's maximum (10000). aalborg's
    # car nudged by 1e-3 rad of yaw at message 7500 drives free of the barrier where the
    # unnudged one rests, and scrapes on past 10000 points (11005 at its finish without the
    # rule, session 15): the replay must end DNF there, as TORCS would.
    from madsim.net.server import MAX_DAMAGE
    from madsim.physics import layout as L

    def watch(msg, world, f):
        if msg == 7500:                                  # coin_toss.py's yaw nudge
            world.state[0, L.S["yaw"]] += 1e-3

    run = fidelity.replay(TRACES / "aalborg__car1-trb1__100.csv.gz", watch=watch)
    assert MAX_DAMAGE == 10000.0
    assert run.madsim_end == "DNF"
    assert run.madsim["damage"][-1] > MAX_DAMAGE
    assert run.madsim["damage"][-2] <= MAX_DAMAGE      # it ends at the first message past it
    assert run.madsim["curLapTime"][-1] < 84.5 + 2587.5 / 10.0   # not the lap-time limit (aalborg 2587.5 m)
