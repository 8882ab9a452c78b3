"""Every reward formula against hand-computed values (spec madras-features.md s. 7, paper)."""

import math

import pytest

from madsim.agents.rewards import REWARDS, RewardSet, canonical_reward_name, make_reward, reward_params

EXACT = 1e-12


def r(**kw):
    base = {"distRaced": 0.0, "angle": 0.0, "damage": 0.0, "racePos": 3}
    base.update(kw)
    return base


INFO = {"track_length": 3000.0}


def test_progress_is_fraction_of_track_per_tick():
    c = make_reward("Progress", target_speed=25.0)
    assert c(r(distRaced=100.0), r(distRaced=103.0), None, INFO) == pytest.approx(0.001, abs=EXACT)


@pytest.mark.parametrize("delta, expected", [(0.3, 0.6), (0.5, 1.0), (0.8, 1.0), (-0.1, -0.2)])
def test_progress2_is_capped_at_target_speed(delta, expected):
    c = make_reward("Progress2", target_speed=25.0)          # 0.5 m per 0.02 s tick
    assert c(r(distRaced=10.0), r(distRaced=10.0 + delta), None, INFO) == pytest.approx(expected, abs=1e-9)


def test_progress3_is_uncapped():
    c = make_reward("ProgressReward3", target_speed=25.0)
    assert c(r(distRaced=10.0), r(distRaced=10.8), None, INFO) == pytest.approx(1.6, abs=1e-9)


def test_avg_speed_pays_once_per_lap_with_that_laps_average():
    c = make_reward("AvgSpeed", target_speed=5.0)
    info = {"track_length": 10.0}
    d, paid = 0.0, []
    for _ in range(40):                          # 0.25 m per tick = 12.5 m/s, 40 ticks a lap
        paid.append(c(r(distRaced=d), r(distRaced=d + 0.25), None, info))
        d += 0.25
    assert paid[:39] == [0.0] * 39 and paid[39] == pytest.approx(12.5 / 5.0, abs=EXACT)
    for _ in range(20):                          # second lap at 0.5 m per tick = 25 m/s
        paid.append(c(r(distRaced=d), r(distRaced=d + 0.5), None, info))
        d += 0.5
    assert paid[40:59] == [0.0] * 19 and paid[59] == pytest.approx(25.0 / 5.0, abs=EXACT)
    assert c(r(distRaced=d), r(distRaced=d + 0.5), None, info) == 0.0      # not paid again
    c.reset()                                    # a new episode starts counting afresh
    assert c(r(distRaced=0.0), r(distRaced=10.0), None, info) == pytest.approx(10.0 / 0.02 / 5.0)


def test_collision_penalty_on_damage_rise_or_contact_flag():
    c = make_reward("CollisionPenalty", target_speed=1.0)
    assert c.kind == "penalty"
    assert c(r(damage=10), r(damage=25), None, INFO) == 1.0
    assert c(r(damage=25), r(damage=25), None, INFO) == 0.0        # no stale baseline
    assert c(r(damage=25), r(damage=25), None, {**INFO, "collision": True}) == 1.0


@pytest.mark.parametrize("angle, p", [(0.0, 0.0), (1.0, 0.0), (1.6, 1.0), (-2.0, 1.0), (math.pi, 1.0)])
def test_turn_backward_penalty(angle, p):
    assert make_reward("TurnBackward", target_speed=1.0)(r(), r(angle=angle), None, INFO) == p


def test_angular_acceleration_paper_formula():
    c = make_reward("AngAcclPenalty", {"max_ang_accl": 2.0}, target_speed=1.0)
    seq = [0.1, 0.3, 0.3, 0.2]
    out, prev = [], 0.1                          # history starts from the first observation
    for a in seq:
        out.append(c(r(angle=prev), r(angle=a), None, INFO))
        prev = a
    # |a_t + a_{t-2} - 2 a_{t-1}| / 2: (0.1,0.1,0.1)=0, (0.1,0.1,0.3)=0.2, (0.1,0.3,0.3)=0.2,
    # (0.3,0.3,0.2)=0.1
    assert out == pytest.approx([0.0, 0.1, 0.1, 0.05], abs=1e-12)


def test_angular_acceleration_wraps_across_pi_and_honours_threshold():
    c = make_reward("AngularAcceleration", {"max_ang_accl": 2.0}, target_speed=1.0)
    c(r(angle=3.1), r(angle=3.1), None, INFO)
    # 3.1 -> -3.1 is a turn of 2 pi - 6.2 rad, not -6.2
    assert c(r(angle=3.1), r(angle=-3.1), None, INFO) == pytest.approx((2 * math.pi - 6.2) / 2.0)
    t = make_reward("AngularAcceleration", {"max_ang_accl": 2.0, "threshold": 0.15}, target_speed=1.0)
    t(r(angle=0.0), r(angle=0.0), None, INFO)
    assert t(r(angle=0.0), r(angle=0.2), None, INFO) == pytest.approx(0.1)     # 0.2 > 0.15
    assert t(r(angle=0.2), r(angle=0.3), None, INFO) == 0.0                    # 0.1 <= 0.15


def test_successful_overtake_pays_new_best_positions_only():
    c = make_reward("SuccessfulOvertakeReward", target_speed=1.0)
    steps = [(5, 4), (4, 5), (5, 4), (4, 2), (2, 2)]
    assert [c(r(racePos=a), r(racePos=b), None, INFO) for a, b in steps] == [1.0, 0.0, 0.0, 2.0, 0.0]
    c.reset()
    assert c(r(racePos=5), r(racePos=4), None, INFO) == 1.0


def test_rank_one_and_task():
    rank = make_reward("RankOneReward", target_speed=1.0)
    assert rank(r(), r(racePos=1), None, INFO) == 1.0 and rank(r(), r(racePos=2), None, INFO) == 0.0
    task = make_reward("TaskReward", target_speed=1.0)
    assert [task(r(), r(racePos=p), None, INFO) for p in (3, 2, 1)] == [0.0, 100.0, 0.0]
    task.reset()
    assert task(r(), r(racePos=1), None, INFO) == 100.0
    assert make_reward("Task", {"position": 1, "bonus": 7.0}, target_speed=1.0)(
        r(), r(racePos=1), None, INFO) == 7.0


def test_total_is_weighted_rewards_minus_weighted_penalties():
    class Term:
        def __init__(self, name, scale, params=None):
            self.name, self.scale, self.params = name, scale, params or {}
    rs = RewardSet.from_terms([Term("Progress2", 1.0), Term("Collision", 10.0),
                               Term("AngularAcceleration", 5.0, {"max_ang_accl": 2.0}),
                               Term("RankOne", 100.0)], target_speed=25.0)
    rs.reset()
    prev = r(distRaced=10.0, angle=0.0, damage=0.0, racePos=2)
    cur = r(distRaced=10.3, angle=0.2, damage=5.0, racePos=1)
    total, terms = rs(prev, cur, None, INFO)
    # r: 1 * 0.6 + 100 * 1; p: 10 * 1 + 5 * (0.2 / 2)
    assert terms == pytest.approx({"Progress2": 0.6, "Collision": -10.0,
                                   "AngularAcceleration": -0.5, "RankOne": 100.0}, abs=1e-9)
    assert total == pytest.approx(0.6 + 100.0 - 10.0 - 0.5, abs=1e-9)


def test_registry_names_and_parameters():
    assert set(REWARDS) == {"Progress", "Progress2", "Progress3", "AvgSpeed", "Collision",
                            "TurnBackward", "AngularAcceleration", "SuccessfulOvertake",
                            "RankOne", "Task"}
    assert canonical_reward_name("AngAcclPenalty") == "AngularAcceleration"
    assert reward_params("AngAcclPenalty") == {"max_ang_accl": 2.0, "threshold": 0.0}
    assert reward_params("Progress2") == {}            # target_speed comes from the agent
    with pytest.raises(KeyError):
        canonical_reward_name("SpeedReward")
