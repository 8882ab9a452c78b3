"""Tyre shape and engine torque map against spec/torcs-car-format.md 4.4 and 4.9."""

from __future__ import annotations

import math

import numpy as np
import pytest

from madsim.cars import load_car
from madsim.physics import kernel
from madsim.physics.tables import car_table

SLIPS = (0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 1.5)
# spec 4.9 "Shape values for testing" (B, C, E) -> F(s) without the skid term
SHAPES = {
    "car1-trb1": ((14.188, 1.4097, 0.7), (0.3738, 0.7224, 0.9213, 0.9949, 0.9785, 0.9283, 0.8981)),
    "car3-trb1": ((17.735, 1.4097, 0.7), (0.4514, 0.8006, 0.9566, 0.9998, 0.9639, 0.9113, 0.8831)),
    "car1-stock1": ((15.538, 1.2871, 0.7), (0.3710, 0.7048, 0.8953, 0.9806, 0.9971, 0.9741, 0.9576)),
    "buggy": ((15.0, 1.0, 0.7), (0.2821, 0.5597, 0.7512, 0.8712, 0.9560, 0.9842, 0.9919)),
}


@pytest.mark.parametrize("name", sorted(SHAPES))
def test_tyre_shape_matches_the_spec_table(name):
    (b, c, e), expected = SHAPES[name]
    got = [kernel.tyre_shape(s, b, c, e, 0.0)[0] for s in SLIPS]
    assert got == pytest.approx(expected, abs=1e-3)      # table printed to 4 decimals


def test_skid_term_and_slip_clamp():
    b, c, e = SHAPES["car1-trb1"][0]
    # semi-pro: 0.898 * (1 + 0.3 * 1.5) = 1.302 at s = 1.5 (spec 4.9), and the clamp holds it there
    assert kernel.tyre_shape(1.5, b, c, e, 0.3)[0] == pytest.approx(1.302, abs=1e-3)
    assert kernel.tyre_shape(7.0, b, c, e, 0.3)[0] == kernel.tyre_shape(1.5, b, c, e, 0.3)[0]
    assert kernel.tyre_shape(0.2, b, c, e, 0.3)[0] == pytest.approx(0.9949 * 1.06, abs=1e-3)


def test_tyre_shape_tends_to_the_dynamic_friction_ratio():
    # sin(C pi/2) = RF: evaluate the shape formula itself at huge slip (no clamp)
    for rf in (0.5, 0.8, 0.95):
        c = 2.0 - 2.0 / math.pi * math.asin(rf)
        b, e = 10.0 / c, 0.7
        u = b * 1e7
        assert math.sin(c * math.atan(u * (1 - e) + e * math.atan(u))) == pytest.approx(rf, abs=1e-6)


def test_tyre_slope_is_the_derivative_of_the_shape():
    b, c, e = SHAPES["car1-stock1"][0]
    for skid in (0.0, 0.3):
        for s in (0.01, 0.1, 0.3, 0.9, 1.4):
            h = 1e-6
            numeric = (kernel.tyre_shape(s + h, b, c, e, skid)[0] - kernel.tyre_shape(s - h, b, c, e, skid)[0]) / (2 * h)
            assert kernel.tyre_shape(s, b, c, e, skid)[1] == pytest.approx(numeric, rel=1e-5, abs=1e-7)


def test_tyre_forces_equal_the_plain_quotients_within_rounding():
    # `_tyre` folds its divisions (1 / (dx dv), 1 / (s den)): the same forces and slope as the
    # quotients written out, within a few ulp, over slips from rest to sliding and every sign
    b, c, e = SHAPES["car1-trb1"][0]
    skid = 0.3
    cd, sd = math.cos(0.05), math.sin(0.05)
    checked = 0
    for vwx in (-12.0, -0.5, 0.0, 0.7, 3.0, 25.0):
        for vwy in (-4.0, -0.01, 0.0, 0.3, 6.0):
            for spin in (-5.0, 0.0, 2.9, 24.0, 40.0):
                got = kernel._tyre(vwx, vwy, cd, sd, spin, b, c, e, skid)
                vt, vl = vwx * cd + vwy * sd, vwy * cd - vwx * sd
                dx = max(abs(vt), kernel.V_REG)
                sx = (vt - spin) / dx
                sy = vl / max(math.hypot(vwx, vwy), kernel.V_REG)
                s = math.hypot(sx, sy)
                f, df = kernel.tyre_shape(s, b, c, e, skid)
                if s > 1e-6:
                    want = (-f * sx / s, -f * sy / s,
                            (max(df, 0.0) * (sx / s) ** 2 + f / s * (sy / s) ** 2) / dx)
                    checked += 1
                else:
                    want = (0.0, 0.0, b * c / dx)
                assert got == pytest.approx(want, rel=1e-13, abs=1e-15)
    assert checked > 100


def test_car_table_holds_the_reciprocals_the_sub_step_multiplies_by():
    # `kernel.car_derived`: 1 / bellcrank and static load / bellcrank per wheel, 1 / roll and
    # pitch inertia, and the road gradient's 1 / (front pair x - rear pair x) = 1 / (2
    # wheelbase), 1 / (2 track)
    from madsim.physics import layout as L

    cars = [load_car("madsim-sedan"), load_car("madsim-buggy")]
    cp, _, _ = car_table(cars, ["semi-pro", "pro"])
    for i, car in enumerate(cars):
        for k in range(4):
            assert cp[i, L.C_RBELL + k] == 1.0 / cp[i, L.C_BELL + k]
            # the spring's preload as the sub-step divided it (a quotient: the same bits)
            assert cp[i, L.C_W0B + k] == cp[i, L.C_W0 + k] / cp[i, L.C_BELL + k]
        assert (cp[i, L.C_RIXX], cp[i, L.C_RIYY]) == (1.0 / car.ixx, 1.0 / car.iyy)
        assert cp[i, L.C_RWB2] == pytest.approx(0.5 / car.wheelbase, rel=1e-12)
        wy = cp[i, L.C_WY:L.C_WY + 4]
        assert cp[i, L.C_RTR2] == pytest.approx(1.0 / ((wy[1] - wy[0]) + (wy[3] - wy[2])), rel=1e-12)
        assert 0.1 < cp[i, L.C_RTR2] < 0.5                     # 2 x a 1-5 m track


@pytest.mark.parametrize("name", ["madsim-sedan", "madsim-gt", "madsim-buggy"])
def test_engine_torque_map(name):
    car = load_car(name)
    cp, cw, ct = car_table([car], ["semi-pro"])
    tick, lim, maxi, kb = car.tickover, car.revs_limiter, car.revs_maxi, car.engine_brake_coeff
    for we in np.linspace(tick, lim, 17):
        tmax = car.torque_at(we)                        # linear between the curve points
        k = kb * (we - tick) / (maxi - tick)
        assert kernel.engine_torque(cp, cw, ct, 0, we, 1.0) == pytest.approx(tmax, rel=1e-12)
        assert kernel.engine_torque(cp, cw, ct, 0, we, 0.0) == pytest.approx(-k * tmax, rel=1e-12, abs=1e-12)
        assert kernel.engine_torque(cp, cw, ct, 0, we, 0.4) == pytest.approx(tmax * (0.4 * (1 + k) - k), rel=1e-12)
    # above the red line: no torque at all; below tickover engine "braking" turns into idle torque
    assert kernel.engine_torque(cp, cw, ct, 0, lim + 1.0, 1.0) == 0.0
    assert kernel.engine_torque(cp, cw, ct, 0, 0.5 * tick, 0.0) > 0.0
