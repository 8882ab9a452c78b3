"""The rolling resistance's drag on the body: TORCS 1.3.7's speed clamp (read in Debian's
simuv2.so, SimCarUpdate) and its yaw-moment clamp (simuv2's public source, SimCarUpdate;
docs/physics.md, "Rolling resistance").

The numbers are a car1-trb1-like car with all four wheels on sand (rolling resistance 0.1 under
12 kN: 1200 N), wheelbase 2.6 m, yaw inertia 2000 kg m^2, mass 1200 kg, 2 ms steps.
"""

from __future__ import annotations

import pytest

from madsim.physics.kernel import rolling_drag

ROLL_N, M_KG, IZZ, WB_M, DT_S = 1200.0, 1200.0, 2000.0, 2.6, 0.002


def test_yaw_moment_is_the_full_moment_or_torcs_r_izz_below_its_threshold():
    # roll wb / 2 = 1560 N m against the yaw while that over izz (0.78 rad/s^2) is below |r|;
    # below it TORCS takes r izz (no step time: it damps the yaw by r dt per step, 0.2 %)
    _, rm = rolling_drag(ROLL_N, 20.0, -0.3, M_KG, IZZ, WB_M, DT_S)
    assert rm == -0.3 * IZZ
    _, rm = rolling_drag(ROLL_N, 20.0, 0.77, M_KG, IZZ, WB_M, DT_S)
    assert rm == 0.77 * IZZ
    _, rm = rolling_drag(ROLL_N, 20.0, -0.79, M_KG, IZZ, WB_M, DT_S)
    assert rm == pytest.approx(-ROLL_N * WB_M / 2.0, rel=1e-12)
    _, rm = rolling_drag(ROLL_N, 20.0, 1e-4, M_KG, IZZ, WB_M, DT_S)
    assert rm == pytest.approx(1e-4 * IZZ, rel=1e-12)
    _, rm = rolling_drag(ROLL_N, 20.0, 0.0, M_KG, IZZ, WB_M, DT_S)
    assert rm == 0.0


def test_drag_at_speed_is_the_force_over_the_speed():
    rv, _ = rolling_drag(ROLL_N, 20.0, 0.0, M_KG, IZZ, WB_M, DT_S)
    assert rv * 20.0 == pytest.approx(ROLL_N, rel=1e-12)
    rv, _ = rolling_drag(ROLL_N, 0.0, 0.0, M_KG, IZZ, WB_M, DT_S)
    assert rv == 0.0


def test_drag_at_a_crawl_is_clamped_as_torcs_does():
    # rv dt / m = (1200 / 0.02) 0.002 / 1200 = 0.1 > 0.02 m/s: rv = v m / dt = 12 N s/m, so a
    # step removes v^2 = 0.0004 m/s of the 0.02 (not the whole speed)
    rv, _ = rolling_drag(ROLL_N, 0.02, 0.0, M_KG, IZZ, WB_M, DT_S)
    assert rv == pytest.approx(0.02 * M_KG / DT_S, rel=1e-12)
    assert rv * 0.02 / M_KG * DT_S == pytest.approx(0.02 ** 2, rel=1e-9)
