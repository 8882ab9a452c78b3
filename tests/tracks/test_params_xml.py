"""The TORCS params dialect (spec/torcs-track-format.md section 1)."""

import math

import numpy as np
import pytest

from madsim.torcsxml import ParamsError, parse_c_number, parse_params, read_params, unit_factor


@pytest.mark.parametrize("unit, factor", [
    ("m", 1.0), ("deg", math.pi / 180), ("ft", 0.304801), ("km/h", 1000 / 3600),
    ("lbs", 0.45359237), ("lbf", 0.45359237 * 9.80665), ("psi", 6894.76), ("rpm", 0.104719755),
    ("%", 0.01), ("mph", 0.44704), ("mm", 0.001), ("m2", 1.0), ("cm2", 1e-4), ("in2", 0.0254 ** 2),
    ("lbs/in", 0.45359237 / 0.0254), ("N.m", 1.0), ("deg/s", math.pi / 180), ("kg.m2", 1.0),
    ("l", 1.0),  # litres read as kg: TORCS counts unknown words as 1
])
def test_unit_factor_matches_torcs_table(unit, factor):
    assert unit_factor(unit) == pytest.approx(factor, rel=1e-12)


@pytest.mark.parametrize("text, value", [
    ("12.5", 12.5), (" -3e2", -300.0), ("7abc", 7.0), ("0x1F", 31.0), ("", 0.0), (".5", 0.5),
    ("+4.", 4.0),
])
def test_numbers_parse_like_scanf(text, value):
    assert parse_c_number(text) == value


def test_non_numbers_are_not_numbers():
    assert parse_c_number("abc") is None


def test_units_convert_to_si_and_round_to_float32():
    root = parse_params('<params name="p"><section name="A">'
                        '<attnum name="a" unit="deg" val="90"/>'
                        '<attnum name="b" unit="ft" val="10" min="5" max="20"/>'
                        '<attnum name="c" val="0.1"/></section></params>')
    a = root.sub("A")
    assert a.num("a") == float(np.float32(math.pi / 2))
    assert a.num("c") == float(np.float32(0.1)) != 0.1
    b = a.attrs["b"]
    assert (b.min, b.max) == pytest.approx((5 * 0.304801, 20 * 0.304801), rel=1e-6)


def test_bounds_widen_to_the_value():
    root = parse_params('<params name="p"><section name="A">'
                        '<attnum name="x" val="30" min="0" max="10"/></section></params>')
    x = root.sub("A").attrs["x"]
    assert (x.min, x.value, x.max) == (0.0, 30.0, 30.0)


def test_first_occurrence_of_an_attribute_wins():
    root = parse_params('<params name="p"><section name="S">'
                        '<attnum name="profil steps length" val="4"/>'
                        '<attnum name="profil steps length" val="6"/></section></params>')
    assert root.sub("S").num("profil steps length") == 4.0


def test_repeated_section_path_is_an_error():
    with pytest.raises(ParamsError, match="section 'A/B'"):
        parse_params('<params name="p"><section name="A"><section name="B"/>'
                     '<section name="B"/></section></params>', source="f.xml")


def test_lists_keep_document_order():
    root = parse_params('<params name="p"><section name="L">' +
                        "".join(f'<section name="{n}"/>' for n in ["z", "a", "m", "b"]) +
                        "</section></params>")
    assert [s.name for s in root.sub("L")] == ["z", "a", "m", "b"]


def test_string_allowed_list_is_split_without_trimming():
    root = parse_params('<params name="p"><section name="D">'
                        '<attstr name="type" in="RWD, FWD, 4WD" val="RWD"/></section></params>')
    assert root.sub("D").attrs["type"].allowed == ("RWD", " FWD", " 4WD")


def test_system_entities_are_inlined_and_undeclared_ones_are_empty(tmp_path):
    shared = tmp_path / "shared"
    shared.mkdir()
    (shared / "surf.xml").write_text('<?xml version="1.0"?>\n<section name="asphalt">'
                                     '<attnum name="friction" val="1.2"/></section>')
    track = tmp_path / "t" / "t.xml"
    track.parent.mkdir()
    track.write_text('<?xml version="1.0" encoding="UTF-8"?>\n'
                     '<!DOCTYPE params SYSTEM "params.dtd" [\n'
                     '<!ENTITY default-surfaces SYSTEM "../shared/surf.xml">\n]>\n'
                     '<params name="t"><section name="Surfaces">&default-surfaces;</section>'
                     '<section name="Objects">&default-objects;</section></params>')
    root = read_params(track)
    assert root.sub("Surfaces/asphalt").num("friction") == pytest.approx(1.2, rel=1e-6)
    assert root.sub("Objects").children == {}


def test_latin1_bytes_in_a_utf8_file_are_read(tmp_path):
    p = tmp_path / "x.xml"
    p.write_bytes('<?xml version="1.0" encoding="UTF-8"?><params name="p"><section name="Header">'
                  '<attstr name="author" val="Eric Espi\xe9"/></section></params>'.encode("latin-1"))
    assert read_params(p).sub("Header").str("author") == "Eric Espi\xe9"


def test_unreadable_entity_file_names_the_entity(tmp_path):
    p = tmp_path / "x.xml"
    p.write_text('<!DOCTYPE params [<!ENTITY s SYSTEM "nope.xml">]><params name="p">&s;</params>')
    with pytest.raises(ParamsError, match="ENTITY s") as err:
        read_params(p)
    assert err.value.file == str(p)


def test_malformed_xml_reports_line_and_column():
    with pytest.raises(ParamsError, match="line 2") as err:
        parse_params('<params name="p">\n<section name="A"></params>', source="bad.xml")
    assert err.value.file == "bad.xml"
