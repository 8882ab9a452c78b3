"""Bottoming (docs/physics.md, "Bottoming"; TORCS 1.3.7's SimCarCollideZ): a wheel on its
packers takes the body's velocity into the road times the surface's rebound off, once per wheel,
and the car takes int(dammage x that speed x skill factor) damage points per wheel. Closed-form
drops onto flat ground, none while the suspension holds the body above its packers, none for a
car sliding along a slope on its packers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from madsim.physics import layout as L
from madsim.physics.kernel import G
from madsim.physics.tables import DAMAGE_SKILL
from tests.support.trackfiles import segment

DT = 0.002
STILL = np.zeros((1, 5))


def _rigid(ph):
    """The sedan with its packers at full extension: a wheel touching the road is on them."""
    car = ph.sedan()
    return ph.sedan(susp_packers=car.susp_course / car.susp_bellcrank)


def _drop(w, h):
    """Lift the car at rest by h m and let it fall; returns (vz at the end of the last sub-step
    before any damage, vz and damage gained at the end of the first sub-step with damage)."""
    for _ in range(50):
        w.step(STILL)
    d0 = w.state[0, L.S_DAMAGE]
    w.state[0, L.S_Z] += h
    vz = 0.0
    for _ in range(int(2.0 / DT)):
        w.step(STILL, 1)
        if w.state[0, L.S_DAMAGE] > d0:
            return vz, w.state[0, L.S_VZ], w.state[0, L.S_DAMAGE] - d0
        vz = w.state[0, L.S_VZ]
    raise AssertionError("no damage")


@pytest.mark.parametrize("h", [0.1, 1.0])
def test_a_drop_onto_flat_ground_takes_the_packer_rule_in_whole_points(straight, ph, h):
    """Impact at sqrt(2 g h) within one sub-step's g dt (free fall by semi-implicit Euler; the
    packers are found at the end of a sub-step, so the last speed before them is up to a sub-step
    short of the exact impact: 1 m drops read 4.4186 m/s against 4.4287); in the sub-step
    of contact the m wheels then on their packers (1 to 4) each remove the share e (rebound) of the
    speed into the road: vz -> v (1 - e)^m within the sub-step's g dt, and the damage is
    sum over k < m of int(d e s |v| (1 - e)^k), d the road's dammage, s the semi-pro factor 0.8
    (h chosen so that no term sits within g dt of a whole point)."""
    track = straight()
    srf = track.surfaces[0]
    e, d, s = srf.rebound, srf.dammage, DAMAGE_SKILL["semi-pro"]
    w = ph.world_at(track, _rigid(ph))
    v_before, v_after, dmg = _drop(w, h)
    assert v_before == pytest.approx(-math.sqrt(2.0 * G * h), abs=G * DT)
    v_in = v_before - G * DT
    m = round(math.log(v_after / v_in) / math.log(1.0 - e))
    assert 1 <= m <= 4
    assert v_after == pytest.approx(v_in * (1.0 - e) ** m, abs=G * DT)
    assert dmg == sum(math.floor(d * e * s * abs(v_in) * (1.0 - e) ** k) for k in range(m))
    assert dmg > 0


def test_no_damage_while_the_suspension_holds_the_body_above_its_packers(straight, ph):
    """The sedan as it ships (packers 0) dropped from 10 cm: its springs and dampers stop the body
    before the packers (ride height stays above them): no damage; the rigid car resting on its
    packers for 2 s takes none either (its speed into the road is only g dt per sub-step)."""
    car = ph.sedan()
    w = ph.world_at(straight(), car)
    for _ in range(50):
        w.step(STILL)
    w.state[0, L.S_Z] += 0.1
    lowest = np.inf
    for _ in range(500):
        w.step(STILL, 1)
        lowest = min(lowest, w.state[0, L.S_RIDE:L.S_RIDE + 4].min())
    assert lowest > car.susp_packers.max()
    assert w.state[0, L.S_DAMAGE] == 0.0
    w = ph.world_at(straight(), _rigid(ph))
    for _ in range(100):
        w.step(STILL)
    assert w.state[0, L.S_DAMAGE] == 0.0


def test_damage_off_and_rookie_skill_take_no_bottoming_damage_but_the_same_rebound(straight, ph):
    """World(damage=False) and the rookie's skill factor 0: no points, and the body's velocity
    change is the same bit for bit as with damage on."""
    track = straight()
    runs = [ph.world_at(track, _rigid(ph), **kw) for kw in ({}, {"damage": False}, {"skill": "rookie"})]
    for w in runs:
        for _ in range(50):
            w.step(STILL)
        w.state[0, L.S_Z] += 0.5
        for _ in range(50):
            w.step(STILL)
    assert runs[0].state[0, L.S_DAMAGE] > 0.0
    assert runs[1].state[0, L.S_DAMAGE] == runs[2].state[0, L.S_DAMAGE] == 0.0
    for w in runs[1:]:
        assert w.state[0, L.S_VZ] == runs[0].state[0, L.S_VZ]


def test_a_car_on_its_packers_down_a_slope_keeps_its_speed_and_takes_no_damage(make_track, ph):
    """The rule takes the speed into the road along its normal (TORCS: the surface normal under
    the wheel), not the vertical speed: the rigid car rolling down a uniform 5 % slope from 25 m/s
    on its packers takes no damage, its vertical speed follows the road (within 2 %) and it
    gains speed as gravity along the slope less drag gives it (1.1 m/s in 2 s; halving the
    vertical speed per contact, the rule before this one, left 0.5 m/s and a vertical speed
    43 % short of the road's)."""
    track = make_track([segment("down", "str", lg=2000.0, z_start=100.0, z_end=0.0)], width=20.0)
    w = ph.world_at(track, _rigid(ph), s=200.0, speed=25.0)
    for _ in range(100):
        w.step(STILL)
    assert w.state[0, L.S_DAMAGE] == 0.0
    assert w.vx[0] > 25.9
    assert w.state[0, L.S_VZ] == pytest.approx(-0.05 * w.vx[0], rel=0.02)
