"""Gravity on slopes and banking, and steady cornering, against closed forms.

Track heights follow TORCS's in-piece rule (track spec 5.4); the model is TORCS's planar one
(car spec 4.11): gravity along the road is m g times the road gradient (height difference over
the distance between the wheels: tan(slope), not sin) and the wheels carry the whole weight m g
(no cos). Until issue 12 madsim used m g sin and m g cos; the real-TORCS traces on the banked
speedways agree better with TORCS's (speed RMS 0.52 -> 0.25 km/h).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from trackfiles import segment

from madsim.cars.spec import G
from madsim.physics import layout as L


def free_mass(car):
    """Mass plus the wheels' rotating mass I/R^2, as below kernel.SPIN_AVG_SPEED (3 m/s): the
    slope tests roll at walking pace, where the spin takes the implicit step (above it TORCS's
    spin average makes the wheels count 1.5 x, test_longitudinal.py)."""
    i_wheel = car.wheel_inertia + np.repeat(car.axle_inertia, 2) / 2.0
    return car.mass_total + float(np.sum(i_wheel / car.wheel_radius ** 2))


@pytest.mark.parametrize("grade", [0.05, 0.10])
def test_car_rolls_down_a_slope_as_gravity_says(make_track, ph, grade):
    roll = 0.01
    track = make_track([segment("up", "str", lg=1000, grade=grade * 100, profil="linear")], rolling=roll)
    assert track.grade_at(500.0) == pytest.approx(grade, rel=1e-5)
    car = ph.sedan()
    w = ph.world_at(track, car, s=500.0, speed=0.0, gear=0)       # facing uphill, neutral
    u = np.zeros((1, 5))
    for _ in range(25):
        w.step(u)
    v1, t1 = float(w.vx[0]), w.time
    for _ in range(50):
        w.step(u)
    v2, t2 = float(w.vx[0]), w.time
    theta = math.atan(grade)
    m = car.mass_total
    # rolling backwards: gravity minus rolling resistance minus drag at the mean speed
    vm = 0.5 * (v1 + v2)
    expected = -(m * G * math.tan(theta) - roll * m * G - car.scx2 * vm * vm) / free_mass(car)
    assert (v2 - v1) / (t2 - t1) == pytest.approx(expected, rel=0.01)
    assert w.s[0] < 500.0                                           # it went down


def test_parked_car_with_brakes_holds_on_a_slope(make_track, ph):
    track = make_track([segment("up", "str", lg=1000, grade=10, profil="linear")])
    w = ph.world_at(track, ph.sedan(), s=500.0, speed=0.0, gear=0)
    u = np.array([[0.0, 0.0, 1.0, 0.0, 0.0]])
    for _ in range(100):
        w.step(u)
    # locked wheels on a 10 % grade, mu 1.35: held by the tyres (slip regularised below 2 m/s,
    # so the car creeps at most a few millimetres per second)
    assert abs(w.s[0] - 500.0) < 0.02
    assert abs(w.vx[0]) < 0.01


def test_frictionless_bank_slides_down_at_g_tan_beta(make_track, ph):
    bank = 8.0
    track = make_track([segment("b", "str", lg=500, banking_start=bank, banking_end=bank)],
                       friction=0.0, rolling=0.0, width=30.0)
    assert math.degrees(track.banking_at(250.0)) == pytest.approx(bank, rel=1e-4)
    w = ph.world_at(track, ph.sedan(), s=250.0, n=5.0, speed=0.0, gear=0)
    u = np.zeros((1, 5))
    for _ in range(25):
        w.step(u)
    n1, t1 = float(w.n[0]), w.time
    vy1 = float(w.vy[0])
    for _ in range(25):
        w.step(u)
    vy2, t2 = float(w.vy[0]), w.time
    # left edge higher: the car slides to the right (towards -n) at g tan(beta) (TORCS's planar
    # gravity: g x the cross gradient)
    assert w.n[0] < n1
    assert (vy2 - vy1) / (t2 - t1) == pytest.approx(-G * math.tan(math.radians(bank)), rel=0.005)


def test_car_holds_on_a_bank_with_grip(make_track, ph):
    track = make_track([segment("b", "str", lg=500, banking_start=10, banking_end=10)], width=30.0)
    w = ph.world_at(track, ph.sedan(), s=250.0, n=5.0, speed=0.0, gear=0)
    u = np.zeros((1, 5))
    for _ in range(100):
        w.step(u)
    # tan 10 deg = 0.18 << mu: the tyres hold it; the slip regularisation below V_REG lets it creep
    # at F_side V_REG / (B C K) ~ 1.5 cm/s (documented in kernel.py)
    assert abs(w.n[0] - 5.0) < 0.05
    assert abs(w.vy[0]) < 0.03


def test_banked_curve_adds_no_normal_load_as_in_torcs(make_track, ph):
    """TORCS's model has no extra load from following a banked curve (issue 12): the wheels
    carry m g at any speed and bank (it was m (g cos b + v^2/R sin b) before)."""
    radius, bank, v = 100.0, -15.0, 25.0     # left turn, right (outer) edge higher
    track = make_track([segment("c", "lft", radius=radius, arc=360, banking_start=bank, banking_end=bank)],
                       width=20.0)
    car = ph.sedan()
    w = ph.world_at(track, car, s=100.0, n=0.0, speed=v, gear=3)
    u = np.zeros((1, 5))
    u[0, 3] = 3
    loads = []
    for _ in range(100):
        u[0, 0] = ph.hold_line(w)[0]
        u[0, 1] = float(np.clip((v - w.vx[0]) * 2.0, 0.0, 1.0))
        w.step(u)
        loads.append(w.wheel_load.sum())
    b = math.radians(-bank)
    speed = float(w.speed[0])
    assert speed ** 2 / radius * math.sin(b) > 0.5      # the old term would add > 5 % here
    expected = car.mass_total * G
    assert np.mean(loads[-20:]) == pytest.approx(expected, rel=0.01)


def test_steady_cornering_saturates_near_mu_g(make_track, ph):
    """Constant radius, slowly rising speed: the lateral acceleration grows like v^2/R, then
    saturates near mu_eff g (pro skill: no skid term, so the tyre peak is 1.0) and the car can no
    longer hold the line."""
    radius, friction = 40.0, 1.0
    track = make_track([segment("c", "lft", radius=radius, arc=360)], width=40.0, friction=friction)
    car = ph.sedan()
    w = ph.world_at(track, car, s=10.0, n=0.0, speed=10.0, gear=3, skill="pro")
    u = np.zeros((1, 5))
    u[0, 3] = 3
    best, held_until = 0.0, None
    for k in range(4000):
        target = 10.0 + 0.005 * k               # +0.25 m/s per second
        u[0, 0] = ph.hold_line(w, gain=1.0)[0]
        u[0, 1] = float(np.clip((target - w.vx[0]) * 0.5, 0.0, 1.0))
        w.step(u)
        if abs(w.n[0]) < 3.0:
            best = max(best, abs(float(w.state[0, L.S_AY])))   # lateral specific force
        elif held_until is None and k > 50:
            held_until = target
            break
    assert held_until is not None, "the car never lost the line"
    m = car.mass_total
    kmu = car.tyre_mu * (1 + 0.05 * np.sin(-18 * car.camber))
    wb = car.wheelbase
    # TORCS's roll (issue 12): the lateral forces act through the roll centres and the roll
    # moment is split by roll stiffness (springs, anti-roll bars), closed form per axle
    t = np.array([car.track_front, car.track_rear])
    k_wheel = car.susp_spring * car.susp_bellcrank ** 2
    k_roll = t ** 2 * (np.array([k_wheel[:2].mean(), k_wheel[2:].mean()]) / 2.0
                       + car.anti_roll_spring * np.array([car.susp_bellcrank[:2].mean(), car.susp_bellcrank[2:].mean()]))
    arm = (car.b * car.roll_center_height[0] + car.a * car.roll_center_height[1]) / wb

    def grip(a_lat):
        """Sum of the wheels' peak forces / m with quasi-static lateral load transfer (outer =
        right wheels in a left turn), spec 5.2 step 4."""
        fz_f, fz_r = m * G * car.b / wb, m * G * car.a / wb
        d_f, d_r = m * a_lat * arm * k_roll / k_roll.sum() / t
        fz = np.array([fz_f * car.weight_front_right + d_f, 0.0, fz_r * car.weight_rear_right + d_r, 0.0])
        fz = np.minimum(np.maximum(fz, 0.0), [fz_f, 0, fz_r, 0])
        fz[1], fz[3] = fz_f - fz[0], fz_r - fz[2]
        lf = car.load_factor_min + (car.load_factor_max - car.load_factor_min) * np.exp(
            car.load_factor_k * fz / car.operating_load)
        return float(np.sum(fz * kmu * lf)) * friction / m

    a_max = 10.0
    for _ in range(100):                                  # fixed point a = grip(a)
        a_max = grip(a_max)
    # transfer costs grip (the sedan's low roll centres: 0.4 %; with the CG height as the arm
    # before issue 12 it was > 5 %)
    assert a_max < 0.999 * grip(0.0)
    # the rear also carries the drive force and saturates first (the car spins): a few % lower
    assert 0.88 * a_max <= best <= 1.01 * a_max
    assert held_until ** 2 / radius > 0.88 * a_max


@pytest.mark.parametrize("arb_front", [0.0, 60000.0])
def test_lateral_load_transfer_through_roll_centres_split_by_roll_stiffness(make_track, ph, arb_front):
    """TORCS's roll (issue 12): the tyres' lateral forces act through the roll centres (0.25 m
    here, not the CG height), the roll moment is shared by the axles' roll stiffness
    t^2 (k / 2 + k_arb): with a front bar as stiff as k the front axle takes 2/3 of it."""
    radius, k, rc = 60.0, 60000.0, 0.25
    track = make_track([segment("c", "lft", radius=radius, arc=360)], width=40.0)
    car = ph.sedan(susp_spring=np.full(4, k), roll_center_height=np.array([rc, rc]),
                   anti_roll_spring=np.array([arb_front, 0.0]))
    w = ph.world_at(track, car, s=10.0, n=0.0, speed=15.0, gear=2)
    ph.drive_steady(w, speed=15.0, gear=2, ticks=150, gain=0.5)
    m_ay = car.mass_total * float(w.state[0, L.S_AY])
    assert m_ay > 0.3 * car.mass_total * G                 # a real corner: 0.38 g
    fz = w.wheel_load[0]
    t_f, t_r = car.track_front, car.track_rear
    kf, kr = t_f ** 2 * (k / 2 + arb_front), t_r ** 2 * k / 2
    # right minus left per axle = twice the transfer (the sedan's static loads are symmetric)
    assert (fz[0] - fz[1]) / 2 == pytest.approx(m_ay * rc * kf / (kf + kr) / t_f, rel=0.02)
    assert (fz[2] - fz[3]) / 2 == pytest.approx(m_ay * rc * kr / (kf + kr) / t_r, rel=0.02)


def test_gravity_from_the_road_under_the_four_wheels(make_track, ph):
    """TORCS takes the slope from the road heights under the wheels (front pair minus rear pair
    over the wheelbase, SimCarUpdateForces), not from the road at the CG: with the CG on the
    flat 0.1 m before a 10 % ramp and the front axle on the ramp, gravity pulls the car back by
    m g 0.10 (a - 0.1) / (a + b), where the road at the CG is flat."""
    grade, d = 0.10, 0.1
    track = make_track([segment("flat", "str", lg=500), segment("up", "str", lg=500, grade=grade * 100,
                                                                profil="linear")], rolling=0.0)
    assert track.grade_at(499.0) == pytest.approx(0.0, abs=1e-9)
    assert track.grade_at(501.0) == pytest.approx(grade, rel=1e-5)
    car = ph.sedan()
    a, b = float(car.wheel_pos[0, 0]), float(-car.wheel_pos[2, 0])
    w = ph.world_at(track, car, s=500.0 - d, speed=0.0, gear=0)      # neutral, no brake
    u = np.zeros((1, 5))
    w.step(u)                                                        # the wheels take up the roll
    v1 = float(w.vx[0])
    for _ in range(4):
        w.step(u)
    expected = -G * grade * (a - d) / (a + b) * car.mass_total / free_mass(car)
    assert (float(w.vx[0]) - v1) / 0.08 == pytest.approx(expected, rel=0.02)
    assert abs(w.s[0] - (500.0 - d)) < 0.01                          # still straddling the kink
