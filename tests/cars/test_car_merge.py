"""Merging car over category (spec/torcs-car-format.md section 1)."""

from __future__ import annotations

import pytest

from madsim.cars import load_car, merge_sections
from madsim.torcsxml import parse_params

CATEGORY = """<params name="cat">
  <section name="Car">
    <attnum name="mass" min="1000" max="1200" val="1100"/>
    <attnum name="GC height" min="0.2" max="0.4" val="0.3"/>
    <attnum name="width" min="1.5" max="2.0" val="1.8"/>
    <attnum name="only in category" val="7"/>
    <attstr name="free text" val="category text"/>
    <attstr name="type" in="RWD, FWD, 4WD" val="RWD"/>
    <attstr name="diff" in="SPOOL,FREE" val="FREE"/>
  </section>
  <section name="List">
    <section name="1"><attnum name="x" min="0" max="100" val="10"/></section>
    <section name="2"><attnum name="x" min="0" max="100" val="20"/></section>
    <section name="3"><attnum name="x" min="0" max="100" val="30"/></section>
  </section>
  <section name="Category Section"><attnum name="y" val="1"/></section>
</params>"""


def merged(car_body: str):
    car = parse_params(f'<params name="mycar">{car_body}</params>')
    return merge_sections(parse_params(CATEGORY), car)


def test_number_above_category_max_is_pulled_down():
    out = merged('<section name="Car"><attnum name="mass" val="1500"/></section>')
    assert out.sub("Car").num("mass") == 1200.0


def test_number_below_category_min_is_kept_quirk():
    # lower bound max(min_cat, v) = 1000 lifts v to 1000, then the upper bound min(max_cat, v) = 900
    # pulls it back: the car's own value survives (spec s.1 "quirk").
    out = merged('<section name="Car"><attnum name="mass" val="900"/></section>')
    assert out.sub("Car").num("mass") == 900.0


def test_number_with_own_range_is_clamped_both_ways():
    low = merged('<section name="Car"><attnum name="GC height" min="0.1" max="0.5" val="0.15"/></section>')
    high = merged('<section name="Car"><attnum name="GC height" min="0.1" max="0.5" val="0.45"/></section>')
    inside = merged('<section name="Car"><attnum name="GC height" min="0.1" max="0.5" val="0.25"/></section>')
    assert low.sub("Car").num("GC height") == pytest.approx(0.2)
    assert high.sub("Car").num("GC height") == pytest.approx(0.4)
    assert inside.sub("Car").num("GC height") == pytest.approx(0.25)


def test_car_value_above_a_category_value_without_range_is_pulled_down():
    # A category number without min/max has min = max = its value (spec s.1).
    out = merged('<section name="Car"><attnum name="only in category" val="9"/></section>')
    low = merged('<section name="Car"><attnum name="only in category" val="5"/></section>')
    assert out.sub("Car").num("only in category") == 7.0
    assert low.sub("Car").num("only in category") == 5.0


def test_string_rules():
    out = merged('<section name="Car">'
                 '<attstr name="free text" val="car text"/>'   # category has no `in` list
                 '<attstr name="type" val="FWD"/>'             # list holds " FWD", not "FWD"
                 '<attstr name="diff" val="SPOOL"/>'           # allowed
                 '</section>')
    car = out.sub("Car")
    assert car.str("free text") == "category text"
    assert car.str("type") == "RWD"
    assert car.str("diff") == "SPOOL"
    out2 = merged('<section name="Car"><attstr name="type" val="RWD"/></section>')
    assert out2.sub("Car").str("type") == "RWD"


def test_union_of_entries_category_first_and_list_entries_survive():
    out = merged('<section name="Car"><attnum name="car only" val="3"/></section>'
                 '<section name="List"><section name="1"><attnum name="x" val="11"/></section>'
                 '<section name="4"><attnum name="x" val="40"/></section></section>'
                 '<section name="Car Section"><attnum name="z" val="2"/></section>')
    assert list(out.children) == ["Car", "List", "Category Section", "Car Section"]
    assert list(out.sub("Car").attrs)[-1] == "car only"
    assert out.sub("Car").num("only in category") == 7.0
    assert list(out.sub("List").children) == ["1", "2", "3", "4"]
    assert [out.sub(f"List/{i}").num("x") for i in "1234"] == [11.0, 20.0, 30.0, 40.0]
    assert out.sub("List/4").path == "List/4"
    assert out.name == "mycar"


def test_merge_leaves_inputs_untouched():
    cat = parse_params(CATEGORY)
    car = parse_params('<params name="c"><section name="Car"><attnum name="mass" val="1500"/></section></params>')
    merge_sections(cat, car)
    assert car.sub("Car").num("mass") == 1500.0
    assert "only in category" not in car.sub("Car").attrs
    assert "Car Section" not in cat.children


def test_stock1_gets_category_torque_points(torcs):
    # car1-stock1 defines points 1-11 (0-10000 rpm); stock1 adds 12-21 (up to 20000 rpm).
    spec = load_car("car1-stock1")
    assert len(spec.engine_speeds_rad_s) == 21
    assert spec.engine_speeds_rad_s[-1] == pytest.approx(20000 * 0.104719755, rel=1e-6)
    assert spec.engine_torques_nm[10] == pytest.approx(590.0)   # the car's own point 11
    assert spec.engine_torques_nm[11] == pytest.approx(971.0)   # stock1's point 12


def test_buggy_front_disk_clamped_to_category_max(torcs):
    # buggy.xml: front disks 250 mm; Offroad-RWD-GrA max 200 mm. Rear 100 mm is in range.
    spec = load_car("buggy")
    assert spec.brake_disk_diameter.tolist() == pytest.approx([0.2, 0.2, 0.1, 0.1])


def test_trb1_drive_type_list_with_spaces(torcs):
    # trb1 allows "RWD, FWD, 4WD": only "RWD" matches exactly; every trb1 car is RWD.
    assert load_car("car1-trb1").drive_type == "RWD"
