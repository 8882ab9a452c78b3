"""Merging a car's params tree over its category's, as TORCS does (spec/torcs-car-format.md s. 1).

Rules, in short (the spec has the reasons):
- the result holds every section and attribute of either tree, the category's first (in its
  order), then what only the car has;
- a number in both: the car's value clamped into the intersection of the two ranges,
  lower bound first, then upper bound. A car value without its own range has min = max = value,
  so such a value above the category maximum is pulled down, one below the minimum is kept;
- a string in both: the car's value if it is in the category's `in` list (split on commas
  without trimming), otherwise the category's (also when the category has no list);
- an attribute that is a number in one tree and a string in the other keeps the category's;
- list entries (sections) only the category has survive, e.g. torque points 12-21 of stock1.
"""

from __future__ import annotations

import numpy as np

from madsim.torcsxml import Num, Section, Str

__all__ = ["merge_sections", "merge_num", "merge_str"]


def merge_num(cat: Num, car: Num) -> Num:
    """The merged number: the car's value clamped into both ranges (lower bound first)."""
    lo = max(cat.min, car.min)
    hi = min(cat.max, car.max)
    value = car.value
    if value < lo:
        value = lo
    if value > hi:
        value = hi
    value = float(np.float32(value))
    return Num(value, car.unit, min(lo, value), max(hi, value))


def merge_str(cat: Str, car: Str) -> Str:
    """The merged string: the car's value only if the category's `in` list allows it."""
    if cat.allowed is not None and car.value in cat.allowed:
        return Str(car.value, cat.allowed)
    return cat


def merge_sections(category: Section, car: Section, *, _path: str = "") -> Section:
    """A new tree merging `car` over `category`; neither input is modified.

    The result's root takes the car's name; section paths are rebuilt from the root.
    """
    out = Section(name=car.name, path=_path)
    for name, cat_attr in category.attrs.items():
        car_attr = car.attrs.get(name)
        if car_attr is None:
            out.attrs[name] = cat_attr
        elif isinstance(cat_attr, Num) and isinstance(car_attr, Num):
            out.attrs[name] = merge_num(cat_attr, car_attr)
        elif isinstance(cat_attr, Str) and isinstance(car_attr, Str):
            out.attrs[name] = merge_str(cat_attr, car_attr)
        else:
            out.attrs[name] = cat_attr
    for name, car_attr in car.attrs.items():
        if name not in category.attrs:
            out.attrs[name] = car_attr
    for name, cat_child in category.children.items():
        path = f"{_path}/{name}" if _path else name
        car_child = car.children.get(name)
        if car_child is None:
            out.children[name] = _copy(cat_child, path)
        else:
            out.children[name] = merge_sections(cat_child, car_child, _path=path)
    for name, car_child in car.children.items():
        if name not in category.children:
            path = f"{_path}/{name}" if _path else name
            out.children[name] = _copy(car_child, path)
    return out


def _copy(section: Section, path: str) -> Section:
    """A copy of `section` placed at `path` (attributes are immutable and shared)."""
    out = Section(name=section.name, path=path, attrs=dict(section.attrs))
    for name, child in section.children.items():
        out.children[name] = _copy(child, f"{path}/{name}")
    return out
