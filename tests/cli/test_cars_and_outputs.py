"""Issue 14 items 2 and 4: `madsim cars list` shows what the data has; `madsim convert car`
writes files that load back; `-o dir/file` creates the folder."""

from madsim.cars import load_car
from madsim.cars.catalog import list_cars
from madsim.cli import main


def test_cars_list_shows_drive_and_mass_of_every_bundled_car(capsys):
    assert main(["cars", "list"]) == 0
    out = capsys.readouterr().out.splitlines()
    rows = {line.split()[0]: line.split() for line in out[1:]}
    for entry in list_cars():
        if entry["source"] != "bundled":
            continue
        row = rows[entry["name"]]
        assert row[2] == entry["drive_type"] and row[2] in ("RWD", "FWD", "4WD")
        assert float(row[3]) == round(entry["mass_kg"])
    assert "nan" not in "\n".join(out)


def test_convert_car_json_and_xml_load_back_equal(tmp_path, capsys):
    json_path, xml_path = tmp_path / "new" / "gt.json", tmp_path / "gt.xml"
    assert main(["convert", "car", "madsim-gt", "-o", str(json_path)]) == 0   # folder created
    assert main(["cars", "info", str(json_path)]) == 0
    assert "madsim-gt" in capsys.readouterr().out
    assert main(["convert", "car", str(json_path), "-o", str(xml_path)]) == 0  # JSON -> XML
    original = load_car("madsim-gt")
    assert load_car(json_path) == original
    assert load_car(xml_path) == original


def test_track_outputs_create_their_folder(tmp_path):
    gen = tmp_path / "gen" / "gen.xml"
    assert main(["tracks", "generate", "--seed", "7", "--length", "1500", "-o", str(gen)]) == 0
    compiled = tmp_path / "c.mtrack"
    assert main(["convert", "track", str(gen), "-o", str(compiled)]) == 0
    back = tmp_path / "back" / "gen.xml"
    assert main(["convert", "track", str(compiled), "-o", str(back)]) == 0
    assert back.read_text().startswith("<?xml")
