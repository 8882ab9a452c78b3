"""CarSpec value semantics, JSON and standalone-XML round trips, and car_info."""

from __future__ import annotations

import dataclasses
import json
import pickle
from pathlib import Path

import numpy as np
import pytest

from madsim.cars import CarError, CarSpec, load_car
from madsim.cars.catalog import car_from_json, car_info, car_to_json, car_to_xml, list_cars
from madsim.torcsxml import read_params


def _all_names() -> list[str]:
    return [c["name"] for c in list_cars() if "error" not in c]


@pytest.mark.parametrize("name", _all_names())
def test_json_round_trip_is_exact(name):
    spec = load_car(name)
    text = car_to_json(spec)
    back = car_from_json(text)
    assert back == spec
    assert back.source_path == spec.source_path
    assert car_to_json(back) == text
    assert "\n" not in text and "mf_b" not in text   # compact: inputs only


@pytest.mark.parametrize("name", _all_names())
def test_standalone_xml_round_trip(tmp_path, name):
    spec = load_car(name)
    path = tmp_path / "anywhere" / "converted.xml"
    path.parent.mkdir()
    path.write_text(car_to_xml(spec), encoding="utf-8")
    back = load_car(path)
    assert back == spec
    assert back.name == spec.name and back.category == spec.category
    assert back.category_path == ""          # no category was read
    tree = read_params(path)                 # and the file really is standalone
    assert tree.sub("madsim").str("merged") == "yes"


def test_equality_sees_every_difference():
    spec = load_car("madsim-gt")
    assert spec == load_car("madsim-gt")
    assert spec != dataclasses.replace(spec, tyre_mu=spec.tyre_mu * 1.01)
    assert spec != dataclasses.replace(spec, gear_ratios=spec.gear_ratios[:-1],
                                       gear_inertias=spec.gear_inertias[:-1],
                                       gear_efficiencies=spec.gear_efficiencies[:-1])
    assert spec == dataclasses.replace(spec, source_path="elsewhere.xml")   # provenance not compared
    assert spec != "madsim-gt"


def test_replace_recomputes_derived_quantities():
    spec = load_car("madsim-sedan")
    heavier = dataclasses.replace(spec, mass=2 * spec.mass)
    assert heavier.izz == pytest.approx(2 * spec.izz)
    assert heavier.static_wheel_load == pytest.approx(2 * spec.static_wheel_load)
    assert heavier.mass_total == 2 * spec.mass + spec.fuel
    shifted = dataclasses.replace(spec, weight_front=0.6)
    assert shifted.b == pytest.approx(0.6 * spec.wheelbase) and shifted.a == pytest.approx(0.4 * spec.wheelbase)


def test_spec_is_immutable_and_picklable():
    spec = load_car("madsim-buggy")
    with pytest.raises(dataclasses.FrozenInstanceError):
        spec.mass = 1.0
    with pytest.raises(ValueError):
        spec.tyre_mu[0] = 2.0
    assert pickle.loads(pickle.dumps(spec)) == spec


def test_json_errors_name_the_key():
    text = car_to_json(load_car("madsim-sedan"))
    doc = json.loads(text)
    doc["car"]["mas"] = doc["car"].pop("mass")
    with pytest.raises(CarError, match=r"car\.mas.*did you mean 'mass'"):
        car_from_json(json.dumps(doc))
    doc = json.loads(text)
    del doc["car"]["tyre_mu"]
    with pytest.raises(CarError, match="missing field.*tyre_mu"):
        car_from_json(json.dumps(doc))
    doc = json.loads(text)
    doc["car"]["tyre_mu"] = [1.0, 1.0]
    with pytest.raises(CarError, match=r"tyre_mu must have shape \(4,\)"):
        car_from_json(json.dumps(doc))
    doc = json.loads(text)
    doc["car"]["mass"] = -5
    with pytest.raises(CarError, match="Car/mass.*mass must be > 0"):
        car_from_json(json.dumps(doc))
    with pytest.raises(CarError, match="malformed JSON"):
        car_from_json(text[:-3], source="x.json")
    with pytest.raises(CarError, match="format"):
        car_from_json('{"car": {}}')


def test_car_info_summary():
    info = car_info("madsim-gt")
    json.dumps(info)   # JSON-serialisable
    spec = load_car("madsim-gt")
    assert info["name"] == "madsim-gt" and info["source"] == "bundled" and info["drive_type"] == "RWD"
    assert info["mass_kg"] == 1250.0
    assert info["max_power_kw"] == pytest.approx(spec.max_power()[0] / 1000, abs=0.01)
    assert info["max_power_rpm"] == pytest.approx(8000.0, abs=0.5)     # the file's own point
    assert info["max_torque_nm"] == pytest.approx(515.0) and info["max_torque_rpm"] == pytest.approx(6000, abs=0.5)
    assert info["revs_limiter_rpm"] == pytest.approx(8600, abs=0.5)
    assert info["gears"] == pytest.approx([3.15, 2.18, 1.64, 1.30, 1.07, 0.89])
    assert info["top_gear_redline_kmh"] == pytest.approx(spec.redline_speed() * 3.6, abs=0.05)
    assert info["tyre_radius_rear_m"] == pytest.approx(0.2413 + 0.305 * 0.30, abs=1e-4)
    path_info = car_info(Path(spec.source_path))
    assert path_info["mass_kg"] == 1250.0 and car_info(spec)["name"] == "madsim-gt"


def test_hand_built_spec_with_non_float32_values_still_writes_valid_xml(tmp_path):
    spec = dataclasses.replace(load_car("madsim-sedan"), mass=1400.123456789)
    path = tmp_path / "x.xml"
    path.write_text(car_to_xml(spec))
    back = load_car(path)
    assert back.mass == pytest.approx(1400.123456789, rel=1e-7)   # float32 storage in the dialect
    assert isinstance(back, CarSpec) and np.array_equal(back.tyre_mu, spec.tyre_mu)


def test_version_1_json_with_tire_keys_still_loads():
    """Car JSON written before the tyre_* rename (version 1, keys tire_*) loads to the same car;
    a version this madsim does not know is refused by name."""
    spec = load_car("madsim-gt")
    doc = json.loads(car_to_json(spec))
    assert doc["version"] == 2 and "tyre_mu" in doc["car"]
    doc["version"] = 1
    doc["car"] = {k.replace("tyre_", "tire_"): v for k, v in doc["car"].items()}
    assert "tire_mu" in doc["car"]
    assert car_from_json(json.dumps(doc)) == spec
    doc["version"] = 3
    with pytest.raises(CarError, match="unsupported version 3"):
        car_from_json(json.dumps(doc))
