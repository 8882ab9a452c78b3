"""Finding and loading cars: `load_car(name_or_path) -> CarSpec`.

Where a car is looked for, in order:
1. a path to an XML file (anything ending in `.xml`, containing a path separator, or an
   existing file);
2. a bundled car, `madsim/assets/cars/<name>/<name>.xml`;
3. an installed TORCS car, `<root>/cars/<name>/<name>.xml` for the data roots `$TORCS_DATA`,
   `/usr/share/games/torcs`, `/usr/local/share/games/torcs`.

The category named by `Car/category` is looked for as `<category>.xml` in: the TORCS-layout
folder next to the car (`<car folder>/../categories`, `<car folder>/../../categories`), the
bundled categories (`madsim/assets/cars/categories`), then every TORCS data root. A car file
without `Car/category` is used as it stands. A file written by `car_to_xml` carries a
`madsim` section marking it as already merged; it is used as it stands too.
"""

from __future__ import annotations

import os
from pathlib import Path

from madsim.cars.build import build_spec
from madsim.cars.errors import CarError
from madsim.cars.merge import merge_sections
from madsim.cars.spec import CarSpec
from madsim.torcsxml import ParamsError, Section, read_params

__all__ = ["load_car", "load_car_file", "bundled_cars_dir", "torcs_data_roots", "find_car",
           "COMPILED_SECTION"]

COMPILED_SECTION = "madsim"
"""Top-level section of a compiled (already merged) car file: attrs `merged`, `name`."""

_DEFAULT_ROOTS = ("/usr/share/games/torcs", "/usr/local/share/games/torcs")


def bundled_cars_dir() -> Path:
    """Folder of the cars shipped with madsim (`madsim/assets/cars`)."""
    return Path(__file__).resolve().parent.parent / "assets" / "cars"


def torcs_data_roots() -> list[Path]:
    """TORCS data folders to search, in order: $TORCS_DATA (if set), then the usual installs."""
    roots = []
    env = os.environ.get("TORCS_DATA")
    if env:
        roots.append(Path(env))
    roots.extend(Path(p) for p in _DEFAULT_ROOTS)
    return roots


def _looks_like_path(text: str) -> bool:
    return text.endswith((".xml", ".json")) or "/" in text or os.sep in text or Path(text).is_file()


def find_car(name_or_path: str | os.PathLike) -> Path:
    """The car file for a name or path; CarError listing the places searched if none."""
    text = os.fspath(name_or_path)
    if not text:
        raise CarError("empty car name")
    if _looks_like_path(text):
        path = Path(text)
        if not path.is_file():
            raise CarError("car file not found", file=str(path))
        return path
    candidates = [bundled_cars_dir() / text / f"{text}.xml"]
    candidates += [root / "cars" / text / f"{text}.xml" for root in torcs_data_roots()]
    for path in candidates:
        if path.is_file():
            return path
    looked = "\n  ".join(str(p) for p in candidates)
    raise CarError(f"car '{text}' not found; looked in:\n  {looked}\n"
                   "(install TORCS data with `apt-get install torcs-data`, set $TORCS_DATA, "
                   "or pass the path of a car XML file)")


def _category_candidates(car_file: Path, category: str) -> list[Path]:
    folder = car_file.resolve().parent
    dirs = [folder.parent / "categories", folder.parent.parent / "categories",
            bundled_cars_dir() / "categories"]
    dirs += [root / "categories" for root in torcs_data_roots()]
    out: list[Path] = []
    for d in dirs:
        p = d / f"{category}.xml"
        if p not in out:
            out.append(p)
    return out


def _read(path: Path) -> Section:
    try:
        return read_params(path)
    except ParamsError as exc:
        raise CarError.from_params(exc) from None


def load_car(name_or_path: str | os.PathLike) -> CarSpec:
    """Load a car by name (bundled, then installed TORCS) or by path; raises CarError."""
    return load_car_file(find_car(name_or_path))


def load_car_file(path: str | os.PathLike) -> CarSpec:
    """Load one car XML file, merged over its category when it names one, or a `madsim convert
    car` JSON file (`.json`)."""
    path = Path(path)
    if path.suffix.lower() == ".json":
        from madsim.cars.convert import car_from_json

        try:
            text = path.read_text(encoding="utf-8")
        except OSError as exc:
            raise CarError(f"cannot read: {exc.strerror}", file=str(path)) from None
        return car_from_json(text, source=str(path))
    car_tree = _read(path)
    car_sec = car_tree.sub("Car")
    category = (car_sec.str("category") if car_sec is not None else None) or ""
    compiled = car_tree.sub(COMPILED_SECTION)
    name = path.stem
    cat_tree, cat_path = None, None
    if compiled is not None and compiled.str("merged") == "yes":
        name = compiled.str("name") or name
        tree = car_tree
    elif category:
        candidates = _category_candidates(path, category)
        cat_path = next((p for p in candidates if p.is_file()), None)
        if cat_path is None:
            looked = "\n  ".join(str(p) for p in candidates)
            raise CarError(f"category '{category}' not found; looked in:\n  {looked}",
                           file=str(path), element="Car/category")
        cat_tree = _read(cat_path)
        tree = merge_sections(cat_tree, car_tree)
    else:
        tree = car_tree
    try:
        return build_spec(tree, name=name, display_name=car_tree.name, category=category,
                          source_path=str(path), category_path=str(cat_path or ""))
    except CarError as exc:
        raise CarError(exc.reason, file=_blame(exc.element, path, car_tree, cat_path, cat_tree),
                       element=exc.element) from None


def _blame(element: str | None, car_path: Path, car_tree: Section,
           cat_path: Path | None, cat_tree: Section | None) -> str:
    """The file an element's value came from: the car's unless only the category has it."""
    if element and cat_tree is not None and not _defines(car_tree, element) and _defines(cat_tree, element):
        return f"{cat_path} (category of {car_path})"
    return str(car_path)


def _defines(tree: Section, element: str) -> bool:
    if tree.sub(element) is not None:
        return True
    section, _, attr = element.rpartition("/")
    sec = tree.sub(section) if section else tree
    return sec is not None and sec.has(attr)
