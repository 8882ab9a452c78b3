"""Broken car files give one CarError naming the file and the element, never a traceback."""

from __future__ import annotations

import pytest

from madsim.cars import CarError, load_car

NO_POINTS = """<section name="Engine"><attnum name="revs limiter" val="700"/></section>"""
EMPTY_POINTS = """<section name="Engine"><section name="data points"></section></section>"""
BAD_ORDER = """<section name="Engine"><section name="data points">
  <section name="1"><attnum name="rpm" val="100"/><attnum name="Tq" val="100"/></section>
  <section name="2"><attnum name="rpm" val="100"/><attnum name="Tq" val="200"/></section>
</section></section>"""
MISNAMED = """<section name="Engine"><section name="data points">
  <section name="1"><attnum name="rpm" val="0"/><attnum name="Tq" val="100"/></section>
  <section name="3"><attnum name="rpm" val="500"/><attnum name="Tq" val="200"/></section>
</section></section>"""
NO_TQ = """<section name="Engine"><section name="data points">
  <section name="1"><attnum name="rpm" val="0"/><attnum name="Tq" val="100"/></section>
  <section name="2"><attnum name="rpm" val="500"/></section>
</section></section>"""
NO_GEARS = """<section name="Gearbox"><section name="gears">
  <section name="r"><attnum name="ratio" val="-3"/></section>
  <section name="1"><attnum name="ratio" val="0"/></section>
</section></section>"""
NEGATIVE_GEAR = """<section name="Gearbox"><section name="gears">
  <section name="1"><attnum name="ratio" val="3"/></section>
  <section name="2"><attnum name="ratio" val="-1"/></section>
</section></section>"""

CASES = {
    # name: (keyword arguments for car_xml, expected element, words in the reason)
    "negative mass": (dict(mass="-10"), "Car/mass", "mass must be > 0"),
    "zero mass": (dict(mass="0"), "Car/mass", "mass must be > 0"),
    "no torque curve": (dict(engine=NO_POINTS), "Engine/data points", "no torque curve"),
    "empty torque curve": (dict(engine=EMPTY_POINTS), "Engine/data points", "no torque curve"),
    "rpm not increasing": (dict(engine=BAD_ORDER), "Engine/data points/2/rpm", "increase strictly"),
    "misnamed point": (dict(engine=MISNAMED), "Engine/data points/2", "named 1..2"),
    "point without Tq": (dict(engine=NO_TQ), "Engine/data points/2/Tq", "without a numeric 'Tq'"),
    "no gears": (dict(gears=""), "Gearbox/gears", "no forward gear"),
    "only zero gears": (dict(gears=NO_GEARS), "Gearbox/gears", "no forward gear"),
    "negative forward gear": (dict(gears=NEGATIVE_GEAR), "Gearbox/gears/2/ratio", "must be > 0"),
    "bad drive type": (dict(body='<section name="Drivetrain"><attstr name="type" val="AWD"/></section>'),
                       "Drivetrain/type", "drive type must be one of"),
    "weight split out of range": (dict(car_extra='<attnum name="front-rear weight repartition" val="1.5"/>'),
                                  "Car/front-rear weight repartition", "must be in [0, 1]"),
    "non-numeric value": (dict(mass="heavy"), "attnum 'mass' in section 'Car'", "is not a number"),
    "section defined twice": (dict(body='<section name="Front Axle"><attnum name="xpos" val="-2"/></section>'),
                              None, None),   # TORCS rejects a repeated section path
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_broken_car_file(tmp_path, car_xml, write_car, case):
    kwargs, element, words = CASES[case]
    path = write_car(tmp_path, "broken", car_xml(**kwargs))
    with pytest.raises(CarError) as info:
        load_car(path)
    err = info.value
    assert err.file is not None and str(path) in err.file
    assert str(path) in str(err)
    if element is not None:
        assert err.element == element
        assert words in err.reason
    else:
        assert err.element and "defined twice" in err.reason


def test_front_axle_behind_rear_axle(tmp_path, car_xml, write_car):
    text = car_xml().replace('<attnum name="xpos" val="1.2"/>', '<attnum name="xpos" val="-2"/>')
    with pytest.raises(CarError, match="must be ahead of the rear axle") as info:
        load_car(write_car(tmp_path, "swapped", text))
    assert info.value.element == "Front Axle/xpos"


def test_malformed_xml(tmp_path, car_xml, write_car):
    path = write_car(tmp_path, "bad", car_xml()[:-40])
    with pytest.raises(CarError, match="malformed XML") as info:
        load_car(path)
    assert info.value.file == str(path) and info.value.element.startswith("line ")


def test_not_a_params_file(tmp_path):
    path = tmp_path / "x.xml"
    path.write_text("<html><body/></html>")
    with pytest.raises(CarError, match="expected <params>"):
        load_car(path)


def test_missing_file(tmp_path):
    with pytest.raises(CarError, match="car file not found") as info:
        load_car(tmp_path / "nothere.xml")
    assert info.value.file == str(tmp_path / "nothere.xml")


def test_missing_category_lists_where_it_looked(tmp_path, car_xml, write_car, monkeypatch):
    monkeypatch.setenv("TORCS_DATA", str(tmp_path / "data"))
    path = write_car(tmp_path, "orphan", car_xml(category="no-such-category"))
    with pytest.raises(CarError) as info:
        load_car(path)
    err = info.value
    assert err.file == str(path) and err.element == "Car/category"
    assert "category 'no-such-category' not found" in err.reason
    assert str(tmp_path / "categories" / "no-such-category.xml") in err.reason
    assert str(tmp_path / "data" / "categories" / "no-such-category.xml") in err.reason


def test_error_in_category_value_blames_the_category_file(tmp_path, car_xml, write_car):
    (tmp_path / "categories").mkdir()
    (tmp_path / "categories" / "badcat.xml").write_text(
        '<params name="badcat"><section name="Steer"><attnum name="steer lock" val="-0.3"/></section></params>')
    path = write_car(tmp_path, "usesbad", car_xml(category="badcat"))
    with pytest.raises(CarError) as info:
        load_car(path)
    assert info.value.element == "Steer/steer lock"
    assert info.value.file.startswith(str(tmp_path / "categories" / "badcat.xml"))


def test_broken_category_file(tmp_path, car_xml, write_car):
    (tmp_path / "categories").mkdir()
    (tmp_path / "categories" / "cut.xml").write_text('<params name="cut"><section name="Car">')
    path = write_car(tmp_path, "usescut", car_xml(category="cut"))
    with pytest.raises(CarError, match="malformed XML") as info:
        load_car(path)
    assert info.value.file == str(tmp_path / "categories" / "cut.xml")


def test_empty_name():
    with pytest.raises(CarError, match="empty car name"):
        load_car("")
