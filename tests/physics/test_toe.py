"""Static toe (car spec 4.5): each wheel's heading is its steer angle plus its `toe`.

A car running straight with toe-in on one axle: the two wheels of that axle see slip angles
equal and opposite (sin toe), so their lateral forces cancel, the car keeps its line, and the
pair costs a drag 2 K F(sin toe) sin toe (K = Fz mu camber lf(Fz) friction, F the tyre shape)
on top of the coast-down of the same car without toe.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from madsim.physics import kernel
from madsim.physics import layout as L

TOE = math.radians(1.0)


def _coast(ph, track, car, ticks=20):
    w = ph.world_at(track, car, speed=25.0, gear=0)
    u = np.zeros((1, 5))
    for _ in range(5):
        w.step(u)
    v1 = float(w.vx[0])
    for _ in range(ticks):
        w.step(u)
    return w, (v1 - float(w.vx[0])) / (ticks * 0.02)


@pytest.mark.parametrize("axle", [0, 1])
def test_toe_in_pair_runs_straight_with_the_drag_its_slip_angle_gives(straight, ph, axle):
    track = straight(rolling=0.0)
    car = ph.sedan()
    toe = np.zeros(4)
    toe[2 * axle], toe[2 * axle + 1] = TOE, -TOE       # right wheel points left: toe-in
    w_toe, decel_toe = _coast(ph, track, dataclasses.replace(car, toe=toe))
    _, decel = _coast(ph, track, car)
    st = w_toe.state
    k0, k1 = 2 * axle, 2 * axle + 1
    # equal and opposite lateral forces: no side force, no yaw, the car keeps its line
    fn = st[0, L.S_FNRAW + k0], st[0, L.S_FNRAW + k1]
    assert fn[0] > 0.0 and fn[0] == pytest.approx(-fn[1], rel=1e-9)
    assert abs(st[0, L.S_R]) < 1e-9 and abs(w_toe.n[0]) < 1e-6
    # the drag of the pair at the loads it runs with (free-rolling: longitudinal slip ~ 0)
    fz = st[0, L.S_FZ + k0], st[0, L.S_FZ + k1]
    kmu = car.tyre_mu * (1.0 + 0.05 * np.sin(-18.0 * car.camber))
    lf = car.load_factor_min + (car.load_factor_max - car.load_factor_min) * np.exp(
        car.load_factor_k * np.array(fz + fz) / car.operating_load)
    j = 2 * axle
    shape = kernel.tyre_shape(math.sin(TOE), car.mf_b[j], car.mf_c[j], car.mf_e[j],
                               w_toe._cp[0, L.C_SKID])[0]
    drag = sum(fz[m] * kmu[k0 + m] * lf[k0 + m] for m in range(2)) * shape * math.sin(TOE)
    assert fn[0] == pytest.approx(fz[0] * kmu[k0] * lf[k0] * shape, rel=1e-5)   # measured 2e-7
    # the extra deceleration: drag over the mass with the wheels' rotating mass (x 1.5 above
    # 3 m/s, test_longitudinal.py); the wheels turn with the car in both runs
    i_wheel = car.wheel_inertia + np.repeat(car.axle_inertia, 2) / 2.0
    m_eff = car.mass_total + 1.5 * float(np.sum(i_wheel / car.wheel_radius ** 2))
    assert decel_toe - decel == pytest.approx(drag / m_eff, rel=0.01)   # measured -0.4 %


def test_car_file_toe_reaches_the_kernel_per_wheel(need_torcs):
    # car1-stock1 sets 0.3 deg of rear toe-in (right +0.3, left -0.3; torcs-data), no front toe
    from madsim.cars import load_car
    from madsim.physics.tables import car_table

    car = load_car("car1-stock1")
    np.testing.assert_allclose(np.degrees(car.toe), [0.0, 0.0, 0.3, -0.3], atol=1e-6)
    cp, _, _ = car_table([car], ["semi-pro"])
    np.testing.assert_array_equal(cp[0, L.C_TOE:L.C_TOE + 4], car.toe)


def test_car_table_holds_the_sines_and_cosines_of_toe_and_wing_angles_bit_for_bit():
    # advance_car reads them from the table instead of forming them at every call: they must
    # be libm's sin / cos of the angles exactly (math.sin and numba's call the same libm)
    from madsim.cars import load_car
    from madsim.physics.tables import car_table

    car = load_car("madsim-gt")
    toe = np.array([0.0, -1e-9, math.radians(0.3), -math.radians(0.3)])
    car = dataclasses.replace(car, toe=toe, wing_angle=np.array([0.0872664626, 0.2094395102]))
    cp, _, _ = car_table([car, load_car("madsim-sedan")], ["semi-pro", "semi-pro"])
    for k in range(4):
        assert cp[0, L.C_TOESIN + k] == math.sin(toe[k])
        assert cp[0, L.C_TOECOS + k] == math.cos(toe[k])
        assert (cp[1, L.C_TOESIN + k], cp[1, L.C_TOECOS + k]) == (0.0, 1.0)
    for k in range(2):
        assert cp[0, L.C_WGSIN + k] == math.sin(car.wing_angle[k])
        assert cp[0, L.C_WGCOS + k] == math.cos(car.wing_angle[k])
    assert cp[0, L.C_WGSIN] != 0.0 and cp[0, L.C_TOESIN + 2] != 0.0
