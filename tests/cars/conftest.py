"""Shared helpers for the car tests: the installed TORCS data, and tiny car files."""

from __future__ import annotations

from pathlib import Path

import pytest

TORCS = Path("/usr/share/games/torcs")


@pytest.fixture
def torcs():
    """The TORCS data root; skips the test when torcs-data is absent."""
    if not (TORCS / "cars").is_dir():
        pytest.skip("TORCS data not installed: apt-get install torcs-data")
    return TORCS


def _minimal_car(category: str | None = None, *, car_extra: str = "", engine: str | None = None,
                gears: str | None = None, mass: str = "1000", body: str = "") -> str:
    """A small but complete car XML; pieces can be replaced to make broken variants."""
    cat = f'<attstr name="category" val="{category}"/>' if category else ""
    if engine is None:
        engine = """
    <section name="Engine">
      <attnum name="revs limiter" unit="rpm" val="7000"/>
      <attnum name="revs maxi" unit="rpm" val="7500"/>
      <attnum name="tickover" unit="rpm" val="1000"/>
      <section name="data points">
        <section name="1"><attnum name="rpm" unit="rpm" val="0"/><attnum name="Tq" val="100"/></section>
        <section name="2"><attnum name="rpm" unit="rpm" val="4000"/><attnum name="Tq" val="300"/></section>
        <section name="3"><attnum name="rpm" unit="rpm" val="8000"/><attnum name="Tq" val="200"/></section>
      </section>
    </section>"""
    if gears is None:
        gears = """
    <section name="Gearbox">
      <section name="gears">
        <section name="r"><attnum name="ratio" val="-3.0"/></section>
        <section name="1"><attnum name="ratio" val="3.0"/></section>
        <section name="2"><attnum name="ratio" val="1.5"/></section>
      </section>
    </section>"""
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<params name="Test Car" type="template">
  <section name="Car">
    {cat}
    <attnum name="mass" unit="kg" val="{mass}"/>
    {car_extra}
  </section>
  {body}
  {engine}
  {gears}
  <section name="Front Axle"><attnum name="xpos" val="1.2"/></section>
  <section name="Rear Axle"><attnum name="xpos" val="-1.3"/></section>
</params>
"""


def _write_car(folder: Path, name: str, text: str) -> Path:
    """Write `text` as `<folder>/cars/<name>/<name>.xml` (TORCS layout) and return the path."""
    path = folder / "cars" / name / f"{name}.xml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture
def car_xml():
    """`car_xml(category=None, car_extra=..., engine=..., gears=..., mass=..., body=...)` -> XML."""
    return _minimal_car


@pytest.fixture
def write_car():
    """`write_car(folder, name, text)` -> path of `<folder>/cars/<name>/<name>.xml`."""
    return _write_car
