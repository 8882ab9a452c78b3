"""The TORCS "params" XML dialect shared by track, car and category files.

Reads a file into a tree of `Section`s holding numbers (converted to SI, rounded to float32 as
TORCS stores them) and strings, following spec/torcs-track-format.md section 1:
external SYSTEM entities are inlined textually, undeclared entities read as empty, UTF-8 with a
Latin-1 fallback, first occurrence of a repeated attribute wins, a repeated section path is an
error, lists keep document order.

This module sits below both `madsim.tracks` and `madsim.cars` and imports nothing of madsim.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = [
    "ParamsError",
    "Num",
    "Str",
    "Section",
    "read_params",
    "parse_params",
    "unit_factor",
    "parse_c_number",
]


class ParamsError(ValueError):
    """A params file cannot be read; carries the file and the element at fault."""

    def __init__(self, message: str, *, file: str | None = None, element: str | None = None):
        self.file = file
        self.element = element
        where = ", ".join(p for p in (file, element and f"at {element}") if p)
        super().__init__(f"{where}: {message}" if where else message)


# --- units --------------------------------------------------------------------------------

_UNIT_WORDS: dict[str, float] = {
    "m": 1.0, "kg": 1.0, "s": 1.0, "rad": 1.0, "Pa": 1.0,
    "deg": math.pi / 180.0,
    "ft": 0.304801, "feet": 0.304801,
    "km": 1000.0, "cm": 0.01, "mm": 0.001,
    "in": 0.0254, "inch": 0.0254, "inches": 0.0254,
    "lb": 0.45359237, "lbs": 0.45359237,
    "lbf": 0.45359237 * 9.80665,
    "slug": 14.59484546, "slugs": 14.59484546,
    "kPa": 1000.0, "MPa": 1e6,
    "psi": 6894.76, "PSI": 6894.76,
    "rpm": 0.104719755, "RPM": 0.104719755,
    "%": 0.01, "percent": 0.01,
    "mph": 0.44704, "MPH": 0.44704,
    "h": 3600.0, "hour": 3600.0, "hours": 3600.0,
    "day": 86400.0, "days": 86400.0,
}


def unit_factor(unit: str) -> float:
    """Factor that converts a value in `unit` to SI, as TORCS's unit scanner computes it.

    Words are separated by `.` (multiply) and `/` (every word after the first `/` divides);
    the character `2` applies the preceding word once more. Unknown words count as 1.
    """
    factor = 1.0
    dividing = False
    word = ""
    last = 1.0

    def apply(w: str) -> float:
        nonlocal factor
        f = _UNIT_WORDS.get(w, 1.0)
        factor = factor / f if dividing else factor * f
        return f

    for ch in unit:
        if ch in "./":
            if word:
                last = apply(word)
                word = ""
            if ch == "/":
                dividing = True
        elif ch == "2":
            if word:
                last = apply(word)
                word = ""
            factor = factor / last if dividing else factor * last
        else:
            word += ch
    if word:
        apply(word)
    return factor


_NUMBER_RE = re.compile(r"\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)")
_HEX_RE = re.compile(r"\s*([+-]?)0[xX]([0-9a-fA-F]+)")


def parse_c_number(text: str) -> float | None:
    """Leading number of `text` as C's scanf("%g") reads it (hex with 0x); '' is 0.

    Returns None when the text does not start with a number.
    """
    if text.strip() == "":
        return 0.0
    m = _HEX_RE.match(text)
    if m:
        value = float(int(m.group(2), 16))
        return -value if m.group(1) == "-" else value
    m = _NUMBER_RE.match(text)
    if m:
        return float(m.group(1))
    low = text.strip().lower()
    for word, value in (("nan", math.nan), ("inf", math.inf), ("+inf", math.inf), ("-inf", -math.inf)):
        if low.startswith(word):
            return value
    return None


def _f32(value: float) -> float:
    return float(np.float32(value))


# --- tree ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class Num:
    """A number attribute: value in SI (float32-rounded), the unit it was written in, bounds."""

    value: float
    unit: str | None
    min: float
    max: float


@dataclass(frozen=True)
class Str:
    """A string attribute with its allowed values (`in`, split on commas without trimming)."""

    value: str
    allowed: tuple[str, ...] | None


@dataclass
class Section:
    """One `<section>`: attributes (first occurrence wins) and sub-sections in document order."""

    name: str
    path: str
    attrs: dict[str, Num | Str] = field(default_factory=dict)
    children: dict[str, "Section"] = field(default_factory=dict)

    def sub(self, path: str) -> "Section | None":
        """The descendant section at a `/`-separated relative path, or None."""
        node: Section | None = self
        for part in path.split("/"):
            if node is None:
                return None
            node = node.children.get(part)
        return node

    def num(self, name: str, default: float | None = None) -> float | None:
        """Number attribute in SI units, or `default` when absent (or a string)."""
        a = self.attrs.get(name)
        return a.value if isinstance(a, Num) else default

    def str(self, name: str, default: str | None = None) -> str | None:
        """String attribute, or `default` when absent (or a number)."""
        a = self.attrs.get(name)
        return a.value if isinstance(a, Str) else default

    def has(self, name: str) -> bool:
        return name in self.attrs

    def __iter__(self):
        return iter(self.children.values())


# --- reading ------------------------------------------------------------------------------

_DOCTYPE_RE = re.compile(r"<!DOCTYPE\b[^\[>]*(\[(?P<subset>.*?)\])?\s*>", re.S)
_ENTITY_DECL_RE = re.compile(r"<!ENTITY\s+(?P<name>[\w.-]+)\s+SYSTEM\s+(['\"])(?P<path>[^'\"]*)\2\s*>", re.S)
_ENTITY_REF_RE = re.compile(r"&(?P<name>[A-Za-z_][\w.-]*);")
_XML_DECL_RE = re.compile(r"^\s*<\?xml[^>]*\?>", re.S)
_STANDARD_ENTITIES = {"amp", "lt", "gt", "quot", "apos"}
_MAX_ENTITY_DEPTH = 8


def _decode(data: bytes) -> str:
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        text = data.decode("latin-1")
    return text.lstrip("\ufeff")


def _inline_entities(text: str, base_dir: Path | None, source: str, depth: int = 0) -> str:
    """Strip the XML declaration and DOCTYPE, substituting SYSTEM entities textually."""
    if depth > _MAX_ENTITY_DEPTH:
        raise ParamsError("external entities nest too deeply (a cycle?)", file=source)
    text = _XML_DECL_RE.sub("", text, count=1)
    entities: dict[str, str] = {}
    m = _DOCTYPE_RE.search(text)
    if m:
        for decl in _ENTITY_DECL_RE.finditer(m.group("subset") or ""):
            name, rel = decl.group("name"), decl.group("path")
            if base_dir is None:
                raise ParamsError(f"entity '{name}' refers to file '{rel}' but the text has no folder",
                                  file=source, element=f"<!ENTITY {name}>")
            target = (base_dir / rel)
            try:
                included = _decode(target.read_bytes())
            except OSError as exc:
                raise ParamsError(f"cannot read entity file '{target}': {exc.strerror or exc}",
                                  file=source, element=f"<!ENTITY {name}>") from None
            entities[name] = _inline_entities(included, target.parent, str(target), depth + 1)
        text = text[: m.start()] + text[m.end():]

    def substitute(ref: re.Match) -> str:
        name = ref.group("name")
        if name in _STANDARD_ENTITIES:
            return ref.group(0)
        return entities.get(name, "")  # undeclared entities read as empty (TORCS does so)

    return _ENTITY_REF_RE.sub(substitute, text)


def read_params(path: str | Path) -> Section:
    """Read a params file; raises ParamsError naming the file and element on any fault."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ParamsError(f"cannot read file: {exc.strerror or exc}", file=str(path)) from None
    return parse_params(_decode(data), source=str(path), base_dir=path.parent)


def parse_params(text: str, *, source: str = "<string>", base_dir: Path | None = None) -> Section:
    """Parse params XML text into its root Section (name = the `<params name=...>`)."""
    body = _inline_entities(text, base_dir, source)
    try:
        root = ET.fromstring(body.encode("utf-8"))
    except ET.ParseError as exc:
        line, col = exc.position
        raise ParamsError(f"malformed XML: {exc.msg if hasattr(exc, 'msg') else exc}",
                          file=source, element=f"line {line}, column {col}") from None
    if root.tag != "params":
        raise ParamsError(f"root element is <{root.tag}>, expected <params>", file=source,
                          element=f"<{root.tag}>")
    top = Section(name=root.get("name", ""), path="")
    seen: set[str] = set()
    _fill(top, root, source, seen)
    return top


def _fill(section: Section, elem: ET.Element, source: str, seen: set[str]) -> None:
    for child in elem:
        tag = child.tag
        if tag == "section":
            name = child.get("name")
            if name is None:
                raise ParamsError("<section> without a name", file=source,
                                  element=f"{section.path or '/'}/<section>")
            path = f"{section.path}/{name}" if section.path else name
            if path in seen:
                raise ParamsError("section defined twice", file=source, element=f"section '{path}'")
            seen.add(path)
            sub = Section(name=name, path=path)
            section.children[name] = sub
            _fill(sub, child, source, seen)
        elif tag in ("attnum", "attstr"):
            name = child.get("name")
            where = f"{tag} '{name}' in section '{section.path}'"
            if name is None:
                raise ParamsError(f"<{tag}> without a name", file=source, element=f"section '{section.path}'")
            if name in section.attrs:
                continue  # first occurrence wins, as TORCS looks attributes up
            val = child.get("val")
            if val is None:
                raise ParamsError("attribute without 'val'", file=source, element=where)
            if tag == "attstr":
                allowed = child.get("in")
                section.attrs[name] = Str(val, tuple(allowed.split(",")) if allowed is not None else None)
                continue
            section.attrs[name] = _read_num(child, val, source, where)
        # other elements (comments are dropped by the parser) carry nothing TORCS reads


def _read_num(elem: ET.Element, val: str, source: str, where: str) -> Num:
    unit = elem.get("unit")
    factor = unit_factor(unit) if unit else 1.0
    raw = parse_c_number(val)
    if raw is None:
        raise ParamsError(f"'{val}' is not a number", file=source, element=where)
    bounds = []
    for key in ("min", "max"):
        text = elem.get(key)
        if text is None:
            bounds.append(raw)
            continue
        b = parse_c_number(text)
        if b is None:
            raise ParamsError(f"{key}='{text}' is not a number", file=source, element=where)
        bounds.append(b)
    lo, hi = min(bounds[0], raw), max(bounds[1], raw)
    return Num(_f32(raw * factor), unit, _f32(lo * factor), _f32(hi * factor))
