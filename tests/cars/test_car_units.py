"""Units as TORCS converts them (track spec 1.3) arrive in CarSpec in SI; defaults are simuv2's."""

from __future__ import annotations

import math

import numpy as np
import pytest

from madsim.cars import load_car

WHEEL = """
  <section name="{w} Wheel">
    <attnum name="ypos" unit="ft" val="{y}"/>
    <attnum name="rim diameter" unit="in" val="16"/>
    <attnum name="tire width" unit="mm" val="250"/>
    <attnum name="tire height-width ratio" unit="%" val="50"/>
    <attnum name="dynamic friction" unit="%" val="90"/>
    <attnum name="camber" unit="deg" val="-2"/>
    <attnum name="ride height" unit="cm" val="11"/>
  </section>
  <section name="{w} Suspension"><attnum name="spring" unit="lbs/in" val="5000"/></section>"""


@pytest.fixture
def unit_car(tmp_path, car_xml, write_car):
    wheels = "".join(WHEEL.format(w=w, y=y) for w, y in
                     (("Front Right", -2.5), ("Front Left", 2.5), ("Rear Right", -2.5), ("Rear Left", 2.5)))
    body = wheels + """
  <section name="Brake System"><attnum name="max pressure" unit="psi" val="1000"/></section>
  <section name="Steer">
    <attnum name="steer lock" unit="deg" val="30"/>
    <attnum name="max steer speed" unit="deg/s" val="180"/>
  </section>
  <section name="Central Differential"><attnum name="min torque bias" unit="%" val="35"/></section>
  <section name="Drivetrain"><attstr name="type" val="4WD"/></section>"""
    extra = ('<attnum name="initial fuel" unit="l" val="40"/>'
             '<attnum name="front-rear weight repartition" unit="%" val="55"/>')
    text = car_xml(mass="2204.6226", car_extra=extra, body=body).replace('unit="kg" val="2204.6226"',
                                                                          'unit="lbs" val="2204.6226"')
    return load_car(write_car(tmp_path, "unitcar", text))


def test_mass_in_lbs_and_fuel_litres_as_kg(unit_car):
    assert unit_car.mass == pytest.approx(1000.0, rel=1e-6)      # 2204.6226 lbs x 0.45359237
    assert unit_car.fuel == 40.0                                   # "l" counts as kg
    assert unit_car.weight_front == pytest.approx(0.55, rel=1e-6)  # %


def test_rpm_to_rad_s(unit_car):
    assert unit_car.revs_limiter == pytest.approx(7000 * 0.104719755, rel=1e-6)
    assert unit_car.engine_speeds_rad_s == pytest.approx(np.array([0, 4000, 8000]) * 0.104719755, rel=1e-6)


def test_psi_deg_percent_lengths(unit_car):
    assert unit_car.brake_max_pressure == pytest.approx(6894760.0, rel=1e-6)
    assert unit_car.steer_lock == pytest.approx(math.radians(30), rel=1e-6)
    assert unit_car.max_steer_speed == pytest.approx(math.pi, rel=1e-6)
    assert unit_car.camber == pytest.approx([math.radians(-2)] * 4, rel=1e-6)
    assert unit_car.tyre_aspect == pytest.approx([0.5] * 4)
    assert unit_car.tyre_dynamic_friction == pytest.approx([0.9] * 4, rel=1e-6)
    assert unit_car.ride_height == pytest.approx([0.11] * 4, rel=1e-6)
    assert unit_car.track_front == pytest.approx(5 * 0.304801, rel=1e-6)   # ft
    assert unit_car.wheel_radius == pytest.approx([0.2032 + 0.125] * 4, rel=1e-6)
    assert unit_car.front_torque_share == pytest.approx(0.35, rel=1e-6)


def test_lbs_per_inch_spring_reads_as_kg_per_m(unit_car):
    # TORCS quirk kept: lbs is a mass, so 5000 lbs/in = 5000 x 0.45359237 / 0.0254 "N/m"
    assert unit_car.susp_spring == pytest.approx([5000 * 0.45359237 / 0.0254] * 4, rel=1e-6)


def test_simuv2_defaults_when_absent(unit_car):
    s = unit_car
    assert (s.cg_height, s.body_length, s.body_width, s.body_height) == pytest.approx((0.5, 4.7, 1.9, 1.2))
    assert s.overall_width == s.body_width and s.fuel_tank == 80.0
    assert (s.cx, s.front_area, s.scx2) == pytest.approx((0.4, 2.5, 0.645 * 0.4 * 2.5))
    assert (s.engine_inertia, s.engine_brake_coeff, s.fuel_cons_factor) == pytest.approx((0.2423, 0.33, 0.0622))
    assert (s.shift_time, s.final_drive) == pytest.approx((0.2, 1.0))
    assert s.brake_front_share == 0.5
    assert s.tyre_mu == pytest.approx([1.0] * 4) and s.tyre_stiffness == pytest.approx([30.0] * 4)
    assert s.tyre_elasticity == pytest.approx([0.7] * 4)
    assert s.wheel_inertia == pytest.approx([1.5] * 4) and s.axle_inertia == pytest.approx([0.15] * 2)
    # kb = disk/2 x piston area x mu = 0.1 x 0.002 x 0.3
    assert s.brake_kb == pytest.approx([6e-5] * 4, rel=1e-6)
    assert s.gear_efficiencies == (1.0, 1.0, 1.0) and s.gear_inertias == (0.0, 0.0, 0.0)
    assert s.differential_types == ("NONE", "NONE", "NONE")
    assert s.wing_area == pytest.approx([0, 0]) and s.clift == pytest.approx([0, 0])


def test_clamps_of_spec_3(tmp_path, car_xml, write_car):
    body = "".join(f"""<section name="{w} Wheel">
      <attnum name="dynamic friction" unit="%" val="130"/><attnum name="elasticity factor" val="1.4"/>
      <attnum name="load factor min" val="0.9"/><attnum name="load factor max" val="1.2"/>
    </section>""" for w in ("Front Right", "Front Left", "Rear Right", "Rear Left"))
    s = load_car(write_car(tmp_path, "clamped", car_xml(body=body)))
    assert s.tyre_dynamic_friction == pytest.approx([1.0] * 4)   # RF clamped to [0.1, 1]
    assert s.mf_c == pytest.approx([1.0] * 4)
    assert s.tyre_elasticity == pytest.approx([1.0] * 4)         # EF <= 1
    assert s.load_factor_min == pytest.approx([0.8] * 4)         # lfMin <= 0.8
    assert s.load_factor_max == pytest.approx([1.6] * 4)         # lfMax >= 1.6
