"""The three cars shipped with madsim, and how cars are found (bundled, $TORCS_DATA, paths)."""

from __future__ import annotations

import fnmatch
import sys
from pathlib import Path

import numpy as np
import pytest

from madsim.cars import CarError, load_car
from madsim.cars.catalog import list_cars
from madsim.cars.loader import bundled_cars_dir
from madsim.torcsxml import read_params

BUNDLED = ["madsim-sedan", "madsim-gt", "madsim-buggy"]


@pytest.mark.parametrize("name, drive, mass, power_kw, redline_kmh, top_kmh", [
    # power: the largest w x Tq over the curve points in [tickover, limiter)
    ("madsim-sedan", "RWD", 1400.0, (180, 220), (240, 280), (240, 280)),
    ("madsim-gt", "RWD", 1250.0, (380, 420), (320, 370), (290, 330)),
    ("madsim-buggy", "4WD", 650.0, (130, 180), (200, 250), (195, 235)),
])
def test_bundled_car_numbers_are_plausible(name, drive, mass, power_kw, redline_kmh, top_kmh):
    s = load_car(name)
    assert Path(s.source_path).parent.parent == bundled_cars_dir()
    assert s.category == "madsim"
    assert Path(s.category_path) == bundled_cars_dir() / "categories" / "madsim.xml"
    assert (s.drive_type, s.mass) == (drive, mass)
    assert power_kw[0] < s.max_power()[0] / 1000 < power_kw[1]
    assert redline_kmh[0] < s.redline_speed() * 3.6 < redline_kmh[1]
    assert top_kmh[0] < s.top_speed_estimate() * 3.6 < top_kmh[1]
    assert s.top_speed_estimate() <= s.redline_speed() + 1e-9
    speeds = [s.redline_speed(g) for g in range(1, s.top_gear + 1)]
    assert speeds == sorted(speeds) and speeds[0] * 3.6 > 50
    # weight split: front axle carries f of the weight, loads sum to m g
    w0 = s.static_wheel_load
    assert w0.sum() == pytest.approx(s.mass * 9.80665)
    assert w0[:2].sum() / w0.sum() == pytest.approx(s.weight_front)
    assert 0.4 <= s.weight_front <= 0.55
    assert 2.4 < s.wheelbase < 3.0 and 1.5 < s.track_front < 1.8
    assert np.all((s.wheel_radius > 0.3) & (s.wheel_radius < 0.36))
    assert s.track_front / (2 * s.cg_height) > 1.4   # static stability factor: rolls over only beyond 1.4 g
    assert s.revs_limiter < s.revs_maxi and s.tickover < s.revs_limiter


def test_gt_has_wings_and_downforce():
    gt = load_car("madsim-gt")
    assert np.all(gt.wing_area > 0) and np.all(gt.wing_angle > 0)
    assert gt.wing_kz == pytest.approx(4 * -1.23 * gt.wing_area)
    assert gt.wing_x[0] > gt.a and gt.wing_x[1] < -gt.b          # ahead of / behind the axles
    assert np.all(gt.clift > 0)
    assert np.all(load_car("madsim-sedan").wing_area == 0)


def test_buggy_splits_torque_by_its_central_differential():
    s = load_car("madsim-buggy")
    assert s.front_torque_share == pytest.approx(0.40, rel=1e-6)
    assert s.differential_types[2] == "VISCOUS COUPLER"
    assert s.final_drive == pytest.approx(4.8, rel=1e-6)


def test_category_supplies_what_the_car_file_omits():
    car = read_params(bundled_cars_dir() / "madsim-sedan" / "madsim-sedan.xml")
    assert not car.sub("Front Right Brake").has("piston area")
    assert not car.sub("Engine").has("inertia")
    s = load_car("madsim-sedan")
    assert s.brake_piston_area == pytest.approx([0.004, 0.004, 0.003, 0.003])   # 40 / 30 cm2
    assert s.engine_inertia == pytest.approx(0.2)


def test_bundled_files_are_package_data():
    """Every bundled car file matches a package-data glob of pyproject.toml (non-editable installs)."""
    if sys.version_info < (3, 11):
        pytest.skip("tomllib needs Python 3.11")
    import tomllib
    root = bundled_cars_dir().parent
    pyproject = root.parent.parent / "pyproject.toml"
    if not pyproject.is_file():
        pytest.skip("not running from a source tree")
    globs = tomllib.loads(pyproject.read_text())["tool"]["setuptools"]["package-data"]["madsim.assets"]
    files = [p.relative_to(root).as_posix() for p in bundled_cars_dir().rglob("*.xml")]
    assert len(files) >= 4
    for f in files:
        assert any(fnmatch.fnmatch(f, g) and f.count("/") == g.count("/") for g in globs), f


def test_torcs_data_env_root_is_searched(tmp_path, monkeypatch, car_xml, write_car):
    write_car(tmp_path, "envcar", car_xml(category="envcat"))
    (tmp_path / "categories").mkdir()
    (tmp_path / "categories" / "envcat.xml").write_text(
        '<params name="envcat"><section name="Car"><attnum name="mass" min="500" max="900" val="800"/>'
        '<attnum name="GC height" val="0.33"/></section></params>')
    monkeypatch.setenv("TORCS_DATA", str(tmp_path))
    s = load_car("envcar")
    assert s.category == "envcat" and s.mass == 900.0 and s.cg_height == pytest.approx(0.33)
    entry = next(e for e in list_cars() if e["name"] == "envcar")
    assert entry["source"] == "torcs" and entry["mass_kg"] == 900.0 and "error" not in entry


def test_unknown_car_lists_where_it_looked(monkeypatch, tmp_path):
    monkeypatch.setenv("TORCS_DATA", str(tmp_path))
    with pytest.raises(CarError) as info:
        load_car("no-such-car")
    text = str(info.value)
    assert "no-such-car" in text and str(tmp_path) in text
    assert str(bundled_cars_dir() / "no-such-car") in text and "/usr/share/games/torcs" in text


def test_list_cars_bundled_first_and_complete():
    cars = list_cars()
    names = [c["name"] for c in cars]
    assert names[:3] == sorted(BUNDLED)
    assert len(names) == len(set(names))
    for c in cars[:3]:
        assert c["source"] == "bundled" and c["category"] == "madsim" and c["power_kw"] > 100
        assert Path(c["path"]).is_file()
