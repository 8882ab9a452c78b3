"""Converting a CarSpec: compact JSON (exact round trip) and a standalone TORCS car XML.

`car_to_json` stores the input fields only (derived quantities are recomputed on load);
floats are written with Python's shortest exact repr, so `car_from_json(car_to_json(s)) == s`.

`car_to_xml` writes every parameter simuv2 reads, in SI with unit labels whose TORCS factor
is 1 (`m`, `kg`, `rad/s`, `Pa`, `N.m`, ...), into one file that needs no category: a top-level
`madsim` section marks it as merged and keeps the car's name. Values are written as the
shortest text that reads back to the same float32, so a spec loaded from TORCS files
(all float32) survives `load_car(file) == spec`. Such a file still names its category, so real
TORCS can use it when the category exists there.
"""

from __future__ import annotations

import difflib
import json
from dataclasses import MISSING, fields
from xml.sax.saxutils import escape, quoteattr

import numpy as np

from madsim.cars.errors import CarError
from madsim.cars.loader import COMPILED_SECTION
from madsim.cars.spec import AXLES, WHEELS, CarSpec

__all__ = ["car_to_json", "car_from_json", "car_to_xml", "JSON_FORMAT"]

JSON_FORMAT = "madsim-car"
JSON_VERSION = 2
# Version 1 spelt the tyre fields "tire_*"; its documents still load (the keys renamed on read).
_V1_RENAMED = {f"tire_{k}": f"tyre_{k}" for k in
               ("width", "aspect", "mu", "stiffness", "dynamic_friction", "elasticity")}


def _input_fields() -> list[str]:
    return [f.name for f in fields(CarSpec) if f.init]


def car_to_json(spec: CarSpec) -> str:
    """One-line JSON of the spec's input fields (derived fields are recomputed on load)."""
    data = {}
    for name in _input_fields():
        value = getattr(spec, name)
        if isinstance(value, np.ndarray):
            value = value.tolist()
        elif isinstance(value, tuple):
            value = list(value)
        data[name] = value
    return json.dumps({"format": JSON_FORMAT, "version": JSON_VERSION, "car": data},
                      separators=(",", ":"), allow_nan=False)


def car_from_json(text: str, *, source: str = "<json>") -> CarSpec:
    """The CarSpec of `car_to_json` text; CarError names the bad key."""
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise CarError(f"malformed JSON: {exc.msg}", file=source,
                       element=f"line {exc.lineno}, column {exc.colno}") from None
    if not isinstance(doc, dict) or doc.get("format") != JSON_FORMAT:
        raise CarError(f"not a madsim car JSON document (expected \"format\": \"{JSON_FORMAT}\")",
                       file=source, element="format")
    if doc.get("version") not in (1, JSON_VERSION):
        raise CarError(f"unsupported version {doc.get('version')!r} (this madsim reads 1 and {JSON_VERSION})",
                       file=source, element="version")
    data = doc.get("car")
    if not isinstance(data, dict):
        raise CarError("'car' must be an object", file=source, element="car")
    if doc["version"] == 1:
        data = {_V1_RENAMED.get(key, key): value for key, value in data.items()}
    valid = _input_fields()
    for key in data:
        if key not in valid:
            near = difflib.get_close_matches(key, valid, n=1)
            hint = f" (did you mean '{near[0]}'?)" if near else ""
            raise CarError(f"unknown field{hint}", file=source, element=f"car.{key}")
    missing = [f.name for f in fields(CarSpec) if f.init and f.name not in data
               and f.default is MISSING and f.default_factory is MISSING]
    if missing:
        raise CarError(f"missing field(s): {', '.join(missing)}", file=source, element="car")
    try:
        return CarSpec(**data)
    except CarError as exc:
        raise CarError(exc.reason, file=source, element=f"car ({exc.element})" if exc.element else "car") from None
    except (TypeError, ValueError) as exc:
        raise CarError(f"bad value: {exc}", file=source, element="car") from None


# --- XML ------------------------------------------------------------------------------------


def _fmt(x: float) -> str:
    """Shortest text that reads back (through float32 rounding) to exactly `x` when possible."""
    x = float(x)
    f = np.float32(x)
    if float(f) == x:
        return np.format_float_positional(f, unique=True, trim="-")
    return repr(x)


class _Writer:
    def __init__(self) -> None:
        self.lines: list[str] = []
        self.depth = 1

    def open(self, name: str) -> None:
        self.lines.append(f"{'  ' * self.depth}<section name={quoteattr(name)}>")
        self.depth += 1

    def close(self) -> None:
        self.depth -= 1
        self.lines.append(f"{'  ' * self.depth}</section>")

    def num(self, name: str, value: float, unit: str | None = None) -> None:
        u = f" unit={quoteattr(unit)}" if unit else ""
        self.lines.append(f"{'  ' * self.depth}<attnum name={quoteattr(name)}{u} val=\"{_fmt(value)}\"/>")

    def str(self, name: str, value: str) -> None:
        self.lines.append(f"{'  ' * self.depth}<attstr name={quoteattr(name)} val={quoteattr(value)}/>")

    def section(self, name: str, items: list[tuple]) -> None:
        self.open(name)
        for item in items:
            self.num(*item)
        self.close()


def car_to_xml(spec: CarSpec) -> str:
    """A standalone TORCS car XML (already merged, no category needed) for `spec`."""
    s, w = spec, _Writer()
    w.open(COMPILED_SECTION)
    w.str("merged", "yes")
    w.str("name", s.name)
    w.close()
    w.open("Car")
    w.str("category", s.category)
    for name, value, unit in (
            ("body length", s.body_length, "m"), ("body width", s.body_width, "m"),
            ("body height", s.body_height, "m"), ("overall length", s.overall_length, "m"),
            ("overall width", s.overall_width, "m"), ("mass", s.mass, "kg"),
            ("GC height", s.cg_height, "m"),
            ("front-rear weight repartition", s.weight_front, None),
            ("front right-left weight repartition", s.weight_front_right, None),
            ("rear right-left weight repartition", s.weight_rear_right, None),
            ("mass repartition coefficient", s.mass_repartition, None),
            ("fuel tank", s.fuel_tank, "kg"), ("initial fuel", s.fuel, "kg")):
        w.num(name, value, unit)
    w.close()
    w.section("Aerodynamics", [("Cx", s.cx), ("front area", s.front_area, "m2"),
                               ("front Clift", s.clift[0]), ("rear Clift", s.clift[1])])
    for i, axle in enumerate(AXLES):
        w.section(f"{axle} Wing", [("area", s.wing_area[i], "m2"), ("angle", s.wing_angle[i], "rad"),
                                   ("xpos", s.wing_xpos[i], "m"), ("zpos", s.wing_zpos[i], "m")])
    w.open("Engine")
    for name, value, unit in (("revs maxi", s.revs_maxi, "rad/s"), ("revs limiter", s.revs_limiter, "rad/s"),
                              ("tickover", s.tickover, "rad/s"), ("inertia", s.engine_inertia, "kg.m2"),
                              ("brake coefficient", s.engine_brake_coeff, None),
                              ("fuel cons factor", s.fuel_cons_factor, None)):
        w.num(name, value, unit)
    w.open("data points")
    for i, (rpm, tq) in enumerate(zip(s.engine_speeds_rad_s, s.engine_torques_nm), start=1):
        w.section(str(i), [("rpm", rpm, "rad/s"), ("Tq", tq, "N.m")])
    w.close()
    w.close()
    w.open("Gearbox")
    w.num("shift time", s.shift_time, "s")
    w.open("gears")
    for i, (ratio, inertia, eff) in enumerate(zip(s.gear_ratios, s.gear_inertias, s.gear_efficiencies)):
        w.section("r" if i == 0 else str(i), [("ratio", ratio), ("inertia", inertia, "kg.m2"),
                                              ("efficiency", eff)])
    w.close()
    w.close()
    w.open("Drivetrain")
    w.str("type", s.drive_type)
    w.close()
    used = {"RWD": "Rear", "FWD": "Front", "4WD": "Central"}[s.drive_type]
    for diff, kind in zip(("Front", "Rear", "Central"), s.differential_types):
        w.open(f"{diff} Differential")
        w.str("type", kind)
        w.num("ratio", s.final_drive if diff == used else 1.0)
        if diff == "Central":
            w.num("min torque bias", s.central_min_torque_bias)
            w.num("max torque bias", s.central_max_torque_bias)
            w.num("viscosity factor", s.central_viscosity)
        else:
            j = 0 if diff == "Front" else 1
            w.num("min torque bias", s.diff_min_torque_bias[j])
            w.num("max torque bias", s.diff_max_torque_bias[j])
            w.num("viscosity factor", s.diff_viscosity[j])
            w.num("max slip bias", s.diff_max_slip_bias[j])
            w.num("locking input torque", s.diff_locking_torque[j])
            w.num("locking brake input torque", s.diff_locking_brake_torque[j])
        w.close()
    w.section("Steer", [("steer lock", s.steer_lock, "rad"), ("max steer speed", s.max_steer_speed, "rad/s")])
    w.section("Brake System", [("front-rear brake repartition", s.brake_front_share),
                               ("max pressure", s.brake_max_pressure, "Pa")])
    for i, axle in enumerate(AXLES):
        w.section(f"{axle} Axle", [("xpos", s.front_axle_x if i == 0 else s.rear_axle_x, "m"),
                                   ("inertia", s.axle_inertia[i], "kg.m2"),
                                   ("roll center height", s.roll_center_height[i], "m")])
        w.section(f"{axle} Anti-Roll Bar", [("spring", s.anti_roll_spring[i], "N/m")])
    for i, wheel in enumerate(WHEELS):
        w.section(f"{wheel} Wheel", [
            ("ypos", s.wheel_ypos[i], "m"), ("rim diameter", s.rim_diameter[i], "m"),
            ("tire width", s.tyre_width[i], "m"), ("tire height-width ratio", s.tyre_aspect[i]),
            ("mu", s.tyre_mu[i]), ("stiffness", s.tyre_stiffness[i]),
            ("dynamic friction", s.tyre_dynamic_friction[i]), ("elasticity factor", s.tyre_elasticity[i]),
            ("load factor min", s.load_factor_min[i]), ("load factor max", s.load_factor_max[i]),
            ("operating load", s.operating_load[i], "N"), ("camber", s.camber[i], "rad"),
            ("toe", s.toe[i], "rad"), ("inertia", s.wheel_inertia[i], "kg.m2"),
            ("mass", s.wheel_mass[i], "kg"), ("ride height", s.ride_height[i], "m")])
        w.section(f"{wheel} Suspension", [
            ("spring", s.susp_spring[i], "N/m"), ("suspension course", s.susp_course[i], "m"),
            ("bellcrank", s.susp_bellcrank[i]), ("packers", s.susp_packers[i], "m"),
            ("slow bump", s.susp_slow_bump[i], "N.s/m"), ("slow rebound", s.susp_slow_rebound[i], "N.s/m"),
            ("fast bump", s.susp_fast_bump[i], "N.s/m"), ("fast rebound", s.susp_fast_rebound[i], "N.s/m"),
            ("fast bump threshold", s.susp_bump_threshold[i], "m/s"),
            ("fast rebound threshold", s.susp_rebound_threshold[i], "m/s")])
        w.section(f"{wheel} Brake", [
            ("disk diameter", s.brake_disk_diameter[i], "m"), ("piston area", s.brake_piston_area[i], "m2"),
            ("mu", s.brake_mu[i]), ("inertia", s.brake_inertia[i], "kg.m2")])
    origin = (s.source_path or "a CarSpec").replace("--", "- -")
    head = (f'<?xml version="1.0" encoding="UTF-8"?>\n'
            f"<!-- {escape(s.name)}: written by madsim from {escape(origin)};"
            f" category already merged, SI units -->\n"
            f"<params name={quoteattr(s.display_name or s.name)} type=\"template\">")
    return "\n".join([head, *w.lines, "</params>", ""])
