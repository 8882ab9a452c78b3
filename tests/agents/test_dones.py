"""Every done condition against hand-made rows (spec madras-features.md section 8)."""

import pytest

from madsim.agents.dones import DONES, DoneSet, make_done


def r(**kw):
    base = {"distRaced": 0.0, "angle": 0.0, "damage": 0.0, "racePos": 2, "trackPos": 0.0,
            "track": [5.0] * 19, "lastLapTime": 0.0}
    base.update(kw)
    return base


INFO = {"track_length": 100.0}


def test_race_over_after_the_configured_laps():
    c = make_done("RaceOver", laps=2)
    assert not c(r(), r(distRaced=199.9), None, INFO)
    assert c(r(), r(distRaced=200.0), None, INFO)


def test_lap_completed_when_a_lap_time_appears():
    c = make_done("LapCompleted")
    assert not c(r(lastLapTime=0.0), r(lastLapTime=0.0), None, INFO)
    assert c(r(lastLapTime=0.0), r(lastLapTime=61.3), None, INFO)
    assert not c(r(lastLapTime=61.3), r(lastLapTime=61.3), None, INFO)
    assert c(r(lastLapTime=61.3), r(lastLapTime=58.9), None, INFO)


def test_timeout_counts_ticks_and_is_a_truncation():
    c = make_done("TimeOut", max_steps=3, target_speed=10.0)
    assert c.truncation
    assert [c(r(), r(), None, INFO) for _ in range(3)] == [False, False, True]
    c.reset()
    assert not c(r(), r(), None, INFO)


def test_timeout_without_max_steps_is_one_lap_at_target_speed():
    c = make_done("TimeOut", max_steps=None, target_speed=5.0)   # 0.1 m/tick, L = 100 m
    out = [c(r(), r(), None, INFO) for _ in range(1000)]
    assert out.index(True) == 999


def test_collision_on_damage_rise_or_contact_only():
    c = make_done("Collision")
    assert c(r(damage=0), r(damage=3), None, INFO)
    assert not c(r(damage=3), r(damage=3), None, INFO)           # no stale baseline
    assert c(r(damage=3), r(damage=3), None, {**INFO, "collision": True})


def test_turn_backward():
    c = make_done("TurnBackward")
    assert c(r(), r(angle=1.6), None, INFO) and not c(r(), r(angle=1.5), None, INFO)


@pytest.mark.parametrize("pos, track, done", [(0.45, [5.0] * 19, False), (0.55, [5.0] * 19, True),
                                              (-0.6, [5.0] * 19, True),
                                              (0.0, [-1.0] * 19, True)])
def test_out_of_track_limits_and_off_road(pos, track, done):
    c = make_done("OutOfTrack", track_limits=(-0.5, 0.5))
    assert c(r(), r(trackPos=pos, track=track), None, INFO) == done


def test_rank1():
    c = make_done("Rank1")
    assert c(r(), r(racePos=1), None, INFO) and not c(r(), r(racePos=2), None, INFO)


def test_done_set_reports_terminal_truncation_and_names():
    ds = DoneSet.from_names(["TimeOut", "Collision", "Rank1"], max_steps=2, laps=1,
                            track_limits=(-1, 1), target_speed=10.0)
    ds.reset()
    assert ds(r(), r(damage=1.0), None, INFO) == (True, False, ["Collision"])
    # every component is evaluated every tick: TimeOut counted the first tick too
    assert ds(r(), r(racePos=1), None, INFO) == (True, True, ["TimeOut", "Rank1"])
    assert set(DONES) == {"RaceOver", "TimeOut", "Collision", "TurnBackward", "OutOfTrack",
                          "Rank1", "LapCompleted"}
