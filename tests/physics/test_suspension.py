"""TORCS's suspension and the body's heave, roll and pitch (docs/physics.md, "Suspension and
vertical dynamics"): closed-form checks of the static ride, the heave's spring-mass response,
the roll angle of a steady turn, crests and dips, and World == WorldBatch on a hilly road."""

from __future__ import annotations

import math

import numpy as np
import pytest

from madsim.physics import layout as L
from madsim.physics.kernel import G
from madsim.physics.world_batch import WorldBatch
from tests.support.trackfiles import segment

STILL = np.array([[0.0, 0.0, 0.0, 0.0, 0.0]])


def _symmetric(ph, **changes):
    """The sedan with its CG midway between the axles, equal springs and linear dampers (bump =
    rebound, threshold above any speed reached), so heave does not couple into pitch."""
    kw = dict(weight_front=0.5, susp_spring=np.full(4, 60000.0), susp_slow_bump=np.full(4, 3500.0),
              susp_slow_rebound=np.full(4, 3500.0), susp_bump_threshold=np.full(4, 5.0),
              susp_rebound_threshold=np.full(4, 5.0), ride_height=np.full(4, 0.12))
    kw.update(changes)
    return ph.sedan(**kw)


def test_car_at_rest_settles_to_the_static_ride_height_and_loads(straight, ph):
    """Each wheel at ride0 - (W - W0) / (k bellcrank^2), W its share of the dynamic mass's weight
    (fuel included; W0 from the dry mass as TORCS configures F0); loads within 0.5 %."""
    car = ph.sedan()
    w = ph.world_at(straight(), car)
    for _ in range(100):
        w.step(STILL)
    st = w.state[0]
    load = car.static_wheel_load * car.mass_total / car.mass
    rate = car.susp_spring * car.susp_bellcrank ** 2
    ride = car.ride_height - (load - car.static_wheel_load) / rate
    np.testing.assert_allclose(st[L.S_FZ:L.S_FZ + 4], load, rtol=5e-3)
    np.testing.assert_allclose(st[L.S_RIDE:L.S_RIDE + 4], ride, atol=2e-4)
    assert float(np.sum(st[L.S_FZ:L.S_FZ + 4])) == pytest.approx(car.mass_total * G, rel=1e-4)
    # the z sensor: CG height + the ride interpolated to the CG (ride heights 3-4 cm under ride0 here)
    at_cg = (car.b * ride[:2].mean() + car.a * ride[2:].mean()) / car.wheelbase
    assert st[L.S_Z] - st[L.S_ROADZ] == pytest.approx(car.cg_height + at_cg, abs=3e-4)
    assert abs(st[L.S_VZ]) < 1e-4 and abs(st[L.S_PITCHR]) < 1e-4


def test_heave_rings_at_the_spring_mass_frequency_with_the_damper_decay(straight, ph):
    """Lift the settled body 1 cm and let go: z follows a damped oscillator with stiffness
    K = 4 k bellcrank^2, damping C = 4 c bellcrank^2 and the dynamic mass: period within 2 %,
    the decay over one period within 10 % of exp(-2 pi zeta / sqrt(1 - zeta^2))."""
    car = _symmetric(ph)
    w = ph.world_at(straight(), car)
    for _ in range(150):
        w.step(STILL)
    z0 = w.state[0, L.S_Z]
    w.state[0, L.S_Z] += 0.01
    zs = []
    for _ in range(1200):
        w.step(STILL, 1)
        zs.append(w.state[0, L.S_Z] - z0)
    zs = np.array(zs)
    m = car.mass_total
    k = 4.0 * 60000.0 * car.susp_bellcrank[0] ** 2
    c = 4.0 * 3500.0 * car.susp_bellcrank[0] ** 2
    omega = math.sqrt(k / m)
    zeta = c / (2.0 * math.sqrt(k * m))
    period = 2.0 * math.pi / (omega * math.sqrt(1.0 - zeta ** 2))
    peaks = [j for j in range(1, len(zs) - 1) if zs[j] > zs[j - 1] and zs[j] >= zs[j + 1] and zs[j] > 0]
    assert len(peaks) >= 2
    assert (peaks[1] - peaks[0]) * 0.002 == pytest.approx(period, rel=0.02)
    decay = math.exp(-2.0 * math.pi * zeta / math.sqrt(1.0 - zeta ** 2))
    assert zs[peaks[1]] / zs[peaks[0]] == pytest.approx(decay, rel=0.10)


def test_roll_angle_in_a_steady_turn_is_the_roll_moment_over_the_roll_stiffness(make_track, ph):
    """A steady left turn on a flat circle: the tyres' lateral force acts through the roll
    centres (here both at 0.1 m), so roll = m a_y h_rc / K_roll with K_roll = sum over the axles
    of t^2 (k bellcrank^2 / 2 + k_arb bellcrank); each axle's right-left load difference is
    2 K_axle roll / t. Both within 3 %."""
    car = ph.sedan(roll_center_height=np.array([0.1, 0.1]))
    track = make_track([segment("c", "lft", radius=100.0, arc=360)], width=20.0)
    w = ph.world_at(track, car, speed=20.0, gear=3)
    ph.drive_steady(w, speed=20.0, gear=3, ticks=250, gain=2.0)
    st = w.state[0]
    ay = st[L.S_AY]
    assert ay > 3.0
    tracks = np.array([car.track_front, car.track_rear])
    bell = car.susp_bellcrank[[0, 2]]
    k_axle = tracks ** 2 * (car.susp_spring[[0, 2]] * bell ** 2 / 2.0 + car.anti_roll_spring * bell)
    roll = car.mass_total * ay * 0.1 / k_axle.sum()
    assert math.sin(st[L.S_ROLLA]) == pytest.approx(roll, rel=0.03)
    fz = st[L.S_FZ:L.S_FZ + 4]
    np.testing.assert_allclose([fz[0] - fz[1], fz[2] - fz[3]], 2.0 * k_axle * roll / tracks, rtol=0.03)


def test_a_crest_unloads_the_car_and_a_dip_loads_it(make_track, ph):
    """30 m/s over a 5 % crest, then from a 5 % descent onto the flat: the body cannot follow
    the road's kink at once, so the wheel loads drop well below m g over the crest and rise well
    above it in the dip; on each slope they settle back to m g (within 1 %), the body's vertical
    speed to the road's (v x slope, within 2 %)."""
    car = ph.sedan()
    track = make_track([segment("up", "str", lg=300.0, z_start=0.0, z_end=15.0),
                        segment("down", "str", lg=300.0, z_start=15.0, z_end=0.0),
                        segment("flat", "str", lg=1400.0, z_start=0.0, z_end=0.0)], width=20.0)
    w = ph.world_at(track, car, s=250.0, speed=30.0, gear=4)
    u = np.array([[0.0, 0.0, 0.0, 4.0, 0.0]])
    weight = car.mass_total * G
    loads, s, vz, vx = [], [], [], []
    while w.state[0, L.S_S] < 720.0:
        u[0, 0] = ph.hold_line(w)[0]
        u[0, 1] = float(np.clip((30.0 - w.vx[0]) * 2.0, 0.0, 1.0))
        w.step(u, 2)
        loads.append(w.state[0, L.S_FZ:L.S_FZ + 4].sum())
        s.append(w.state[0, L.S_S])
        vz.append(w.state[0, L.S_VZ])
        vx.append(w.vx[0])
    loads, s, vz, vx = map(np.array, (loads, s, vz, vx))
    crest = (s > 300.0) & (s < 310.0)
    dip = (s > 600.0) & (s < 610.0)
    assert loads[crest].min() < 0.5 * weight
    assert loads[dip].max() > 1.5 * weight
    for lo, hi, slope in ((520.0, 595.0, -0.05), (680.0, 700.0, 0.0)):
        j = (s > lo) & (s < hi)
        assert np.mean(loads[j]) == pytest.approx(weight, rel=0.01)
        assert np.mean(vz[j]) == pytest.approx(slope * np.mean(vx[j]), abs=0.02 * 30.0 * 0.05)


def test_world_batch_equals_the_world_bit_for_bit_over_hills(make_track, ph):
    """The suspension lives in the shared car kernel: a WorldBatch slot and a World driven with
    the same controls over a crest agree bit for bit every tick; two Worlds likewise
    (determinism)."""
    from madsim.physics.world import World
    car = ph.sedan()
    track = make_track([segment("up", "str", lg=200.0, z_start=0.0, z_end=10.0),
                        segment("down", "str", lg=200.0, z_start=10.0, z_end=0.0),
                        segment("flat", "str", lg=600.0, z_start=0.0, z_end=0.0)], width=20.0)
    where = np.array([[150.0, 0.5, 25.0]])
    worlds = [World(track, [car], np.random.default_rng(0), contact=False) for _ in range(2)]
    for x in worlds:
        x.reset(where)
    batch = WorldBatch(1, 1)
    batch.start(0, ("hills", (car.name,)), track, [car], where)
    assert np.array_equal(batch.state[batch.rows(0)], worlds[0].state)
    rng = np.random.default_rng(5)
    mask = np.ones(1, dtype=bool)
    for _ in range(120):
        u = np.array([[rng.uniform(-0.1, 0.1), rng.uniform(0.0, 1.0), 0.0, 3.0, 0.0]])
        batch.controls[batch.rows(0)] = u
        batch.step(mask)
        for x in worlds:
            x.step(u)
        assert np.array_equal(batch.state[batch.rows(0)], worlds[0].state)
        assert np.array_equal(worlds[1].state, worlds[0].state)
    assert worlds[0].state[0, L.S_S] > 205.0      # over the crest at 200 m


def test_a_wheel_at_full_extension_alternates_as_in_torcs_1_3_7(straight, ph):
    """Hard braking lifts the sedan's rear (2.5 cm of travel left at rest) to its suspension
    course. TORCS 1.3.7 then alternates every 2 ms: the wheel's inertia pulls the body (tyre
    load 0), next step the spring force at full extension, F0 - k (course - x0) times the
    bellcrank, reaches the tyre again (its in-the-air flag is cleared before it is read)."""
    car = ph.sedan(brake_max_pressure=1.0e8)
    w = ph.world_at(straight(), car, speed=100.0 / 3.6)
    u = np.array([[0.0, 0.0, 1.0, 0.0, 0.0]])
    for _ in range(10):
        w.step(u)
    bell, k = car.susp_bellcrank[2], car.susp_spring[2]
    at_course = (car.static_wheel_load[2] / bell - k * (car.susp_course[2] - bell * car.ride_height[2])) * bell
    rear = []
    for _ in range(6):
        w.step(u, 1)
        rear.append(w.state[0, L.S_FZ + 2])
        assert w.state[0, L.S_SUSP + 2] == pytest.approx(car.susp_course[2], abs=1e-9)
    rear = np.array(rear)
    assert at_course > 500.0
    zero, full = rear[rear < 1.0], rear[rear >= 1.0]
    assert len(zero) == len(full) == 3 and np.all(np.diff(rear > 1.0) != 0)
    np.testing.assert_allclose(full, at_course, rtol=1e-6)
