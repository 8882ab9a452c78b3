"""Every car of Debian's torcs-data 1.3.7 loads, with the files' own numbers and spec s.3-5 values."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from madsim.cars import load_car
from madsim.torcsxml import read_params

TORCS = Path("/usr/share/games/torcs")
RPM = 0.104719755   # TORCS's rpm -> rad/s factor
G = 9.80665


def _installed() -> list[str]:
    folder = TORCS / "cars"
    if not folder.is_dir():
        return ["<torcs-data not installed>"]
    return sorted(p.name for p in folder.iterdir() if (p / f"{p.name}.xml").is_file())


def _shape(B, C, E, s):
    """simuv2's magic-formula shape without the skid term (spec 4.9)."""
    return np.sin(C * np.arctan(B * s * (1 - E) + E * np.arctan(B * s)))


# Scalar fields and the element they come from: checked against the car file's own value
# whenever that value lies inside the category's range (so merging leaves it alone).
SCALARS = {
    "mass": ("Car", "mass"), "cg_height": ("Car", "GC height"),
    "weight_front": ("Car", "front-rear weight repartition"),
    "body_length": ("Car", "body length"), "body_width": ("Car", "body width"),
    "mass_repartition": ("Car", "mass repartition coefficient"),
    "fuel": ("Car", "initial fuel"), "cx": ("Aerodynamics", "Cx"),
    "front_area": ("Aerodynamics", "front area"),
    "revs_limiter": ("Engine", "revs limiter"), "revs_maxi": ("Engine", "revs maxi"),
    "tickover": ("Engine", "tickover"), "steer_lock": ("Steer", "steer lock"),
    "front_axle_x": ("Front Axle", "xpos"), "rear_axle_x": ("Rear Axle", "xpos"),
    "brake_max_pressure": ("Brake System", "max pressure"),
}


@pytest.mark.parametrize("name", _installed())
def test_every_installed_car_loads_with_its_own_numbers(torcs, name):
    spec = load_car(name)
    car = read_params(torcs / "cars" / name / f"{name}.xml")
    cat = read_params(torcs / "categories" / f"{car.sub('Car').str('category')}.xml")
    assert spec.name == name and spec.category == cat.name
    checked = 0
    for field, (section, attr) in SCALARS.items():
        own = car.sub(section).attrs.get(attr) if car.sub(section) else None
        bound = cat.sub(section).attrs.get(attr) if cat.sub(section) else None
        if own is None or (bound is not None and not bound.min <= own.value <= bound.max):
            continue
        assert getattr(spec, field) == own.value, field
        checked += 1
    assert checked >= 8
    # relations of spec section 3, independent of the car
    assert spec.a + spec.b == pytest.approx(spec.wheelbase, abs=1e-9)
    assert spec.b == pytest.approx(spec.weight_front * spec.wheelbase)
    assert spec.static_wheel_load.sum() == pytest.approx(spec.mass * G)
    assert spec.mass_total == spec.mass + spec.fuel
    assert spec.izz == pytest.approx(spec.mass * (spec.body_width ** 2 + (spec.mass_repartition
                                                                        * spec.body_length) ** 2) / 12)
    assert np.all(spec.wheel_pos[:2, 0] == spec.a) and np.all(spec.wheel_pos[2:, 0] == -spec.b)
    assert np.all(spec.wheel_pos[[0, 2], 1] < 0) and np.all(spec.wheel_pos[[1, 3], 1] > 0)
    assert spec.operating_load == pytest.approx(1.2 * spec.static_wheel_load, rel=1e-6) or \
        any(car.sub(f"{w} Wheel") and car.sub(f"{w} Wheel").has("operating load")
            for w in ("Front Right", "Front Left", "Rear Right", "Rear Left"))
    assert spec.top_gear >= 4 and spec.gear_ratios[0] < 0
    assert list(spec.gear_ratios[1:]) == sorted(spec.gear_ratios[1:], reverse=True)
    assert 150 < spec.redline_speed() * 3.6 < 400
    assert np.all(spec.wheel_radius > 0.25) and np.all(spec.wheel_radius < 0.45)


@pytest.mark.parametrize("name, drive, mass, cg", [
    ("car1-stock1", "RWD", 1550.0, 0.3),   # car1-stock1.xml: mass 1550 kg, GC height 0.3 m
    ("155-DTM", "4WD", 1100.0, 0.2),       # 155-DTM.xml: 1100 kg, 0.20 m; Track-4WD-GrB: type 4WD
    ("buggy", "RWD", 650.0, 0.45),         # buggy.xml: 650 kg, 0.45 m; Offroad-RWD-GrA: RWD
    ("p406", "FWD", 1500.0, 0.33),
])
def test_drive_mass_and_cg_from_the_files(torcs, name, drive, mass, cg):
    spec = load_car(name)
    assert (spec.drive_type, spec.mass) == (drive, mass)
    assert spec.cg_height == pytest.approx(cg, abs=1e-7)   # float32 storage


def test_car1_stock1_geometry_and_gearing(torcs):
    s = load_car("car1-stock1")
    # axles 1.602 / -1.198 m, f = 0.48: L = 2.8, a = 0.52 L, b = 0.48 L
    assert s.wheelbase == pytest.approx(2.8, abs=1e-6)
    assert (s.a, s.b) == (pytest.approx(1.456, abs=1e-6), pytest.approx(1.344, abs=1e-6))
    assert s.track_front == pytest.approx(1.59, abs=1e-6)
    assert s.steer_lock == pytest.approx(math.radians(21), rel=1e-6)
    # top gear: the car's 0.8 (category says 0.75, the car's value is inside [0.5, 5])
    assert s.gear_ratios == pytest.approx((-4.0, 3.82, 2.15, 1.56, 1.21, 0.97, 0.8), abs=1e-6)
    assert s.final_drive == pytest.approx(4.5) and s.overall_ratio(6) == pytest.approx(3.6, abs=1e-6)
    # tyre 15" rim, 304 mm, 0.54: R = 0.1905 + 0.16416 m
    assert s.wheel_radius == pytest.approx([0.35466] * 4, abs=1e-6)
    assert s.izz == pytest.approx(1550 * (1.92 ** 2 + 0.8 ** 2 * 4.9 ** 2) / 12, rel=1e-6)
    assert s.fuel == 60.0 and s.mass_total == 1610.0


def test_155_dtm_4wd_split_and_central_final_drive(torcs):
    s = load_car("155-DTM")
    assert s.front_torque_share == pytest.approx(0.30, abs=1e-7)   # min torque bias 30 %
    assert s.final_drive == 6.0                                     # Central Differential ratio
    assert s.differential_types == ("LIMITED SLIP", "LIMITED SLIP", "VISCOUS COUPLER")
    assert s.driven_wheels.tolist() == [True] * 4


@pytest.mark.parametrize("name, B, C, E", [
    ("car1-trb1", 14.188, 1.4097, 0.7),
    ("car3-trb1", 17.735, 1.4097, 0.7),
    ("car1-stock1", 15.538, 1.2871, 0.7),
    ("buggy", 15.0, 1.0, 0.7),
])
def test_magic_formula_constants_spec_3(torcs, name, B, C, E):
    s = load_car(name)
    assert s.mf_b == pytest.approx([B] * 4, abs=6e-4)
    assert s.mf_c == pytest.approx([C] * 4, abs=6e-5)
    assert s.mf_e == pytest.approx([E] * 4, abs=1e-6)
    assert np.sin(s.mf_c * np.pi / 2) == pytest.approx(s.tyre_dynamic_friction, abs=1e-6)


@pytest.mark.parametrize("name, values", [
    ("car1-trb1", [0.3738, 0.7224, 0.9213, 0.9949, 0.9785, 0.9283, 0.8981]),
    ("car3-trb1", [0.4514, 0.8006, 0.9566, 0.9998, 0.9639, 0.9113, 0.8831]),
    ("car1-stock1", [0.3710, 0.7048, 0.8953, 0.9806, 0.9971, 0.9741, 0.9576]),
    ("buggy", [0.2821, 0.5597, 0.7512, 0.8712, 0.9560, 0.9842, 0.9919]),
])
def test_tyre_shape_table_spec_4_9(torcs, name, values):
    s = load_car(name)
    slips = np.array([0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 1.5])
    got = _shape(s.mf_b[0], s.mf_c[0], s.mf_e[0], slips)
    assert got == pytest.approx(values, abs=1.5e-4)   # table printed to 4 decimals


@pytest.mark.parametrize("name, peak", [("155-DTM", 0.18), ("car3-trb1", 0.21), ("car1-trb1", 0.26),
                                        ("car1-stock1", 0.38), ("baja-bug", 0.53)])
def test_tyre_peak_slip_spec_4_9(torcs, name, peak):
    s = load_car(name)
    grid = np.linspace(0.001, 1.5, 15000)
    got = grid[np.argmax(_shape(s.mf_b[0], s.mf_c[0], s.mf_e[0], grid))]
    assert got == pytest.approx(peak, abs=0.006)


def test_load_sensitivity_and_camber_car1_trb1(torcs):
    s = load_car("car1-trb1")
    # default operating load 1.2 x static: factor at the static load = 0.8 + 0.8 exp(lfK / 1.2) ~ 1.05
    lf = s.load_factor_min + (s.load_factor_max - s.load_factor_min) * np.exp(
        s.load_factor_k * s.static_wheel_load / s.operating_load)
    assert lf == pytest.approx([1.052] * 4, abs=1e-3)
    assert s.load_factor_k == pytest.approx([math.log(0.25)] * 4, rel=1e-6)
    # camber -4 deg at the front: 1 + 0.05 sin(-18 camber) = +4.8 % grip
    assert 1 + 0.05 * math.sin(-18 * s.camber[0]) == pytest.approx(1.048, abs=5e-4)


def test_redline_and_top_speeds_spec_5_5(torcs):
    # car1-stock1 is red-line limited at 334 km/h; car1-trb1 (~302) and buggy (~228) drag limited.
    stock = load_car("car1-stock1")
    assert stock.redline_speed() * 3.6 == pytest.approx(9000 * RPM * 0.35466 / 3.6 * 3.6, rel=1e-5)
    assert stock.redline_speed() * 3.6 == pytest.approx(334.3, abs=0.1)
    assert stock.top_speed_estimate() * 3.6 == pytest.approx(334, abs=1)
    assert load_car("car1-trb1").top_speed_estimate() * 3.6 == pytest.approx(302, abs=1.5)
    assert load_car("buggy").top_speed_estimate() * 3.6 == pytest.approx(228, abs=1.5)


def test_engine_curve_queries(torcs):
    s = load_car("car1-stock1")
    # points 7000 rpm -> 710 N m and 8000 rpm -> 690 N m: halfway is 700 N m
    assert s.torque_at(7500 * RPM) == pytest.approx(700.0, rel=1e-5)
    out = s.torque_at(np.array([0.0, 7000 * RPM, 1e9]))
    assert out.shape == (3,) and out == pytest.approx([100.0, 710.0, 534.0])
    # spec 3: max over points with tickover <= w < limiter (1500..9000 rpm; 9000 itself excluded)
    assert s.max_torque() == pytest.approx((710.0, 7000 * RPM), rel=1e-6)
    assert s.max_power() == pytest.approx((8000 * RPM * 690.0, 8000 * RPM), rel=1e-6)
    assert s.top_gear == 6
    with pytest.raises(ValueError):
        s.overall_ratio(7)
    assert s.overall_ratio(-1) == pytest.approx(-18.0) and s.overall_ratio(0) == 0.0
