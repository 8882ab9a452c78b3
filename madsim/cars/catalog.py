"""What the CLI shows about cars: listing, one car's summary, and conversions.

`list_cars()` and `car_info()` return plain JSON-serialisable dicts; display units are in the
key names (`mass_kg`, `power_kw`, `rpm`, `speed_kmh`). Conversions live in `convert.py` and are
re-exported here for `madsim convert car`.
"""

from __future__ import annotations

import os
from pathlib import Path

from madsim.cars.convert import car_from_json, car_to_json, car_to_xml
from madsim.cars.errors import CarError
from madsim.cars.loader import bundled_cars_dir, load_car, load_car_file, torcs_data_roots
from madsim.cars.spec import CarSpec

__all__ = ["list_cars", "car_info", "car_to_json", "car_from_json", "car_to_xml", "RPM"]

RPM = 0.104719755
"""TORCS's rpm -> rad/s factor; dividing by it gives back the rpm written in the files."""


def _car_files() -> list[tuple[str, str, Path]]:
    """(name, source, path) of every bundled car, then every installed TORCS car; names unique."""
    found: list[tuple[str, str, Path]] = []
    seen: set[str] = set()
    places = [("bundled", bundled_cars_dir())] + [("torcs", root / "cars") for root in torcs_data_roots()]
    for source, folder in places:
        if not folder.is_dir():
            continue
        for sub in sorted(folder.iterdir()):
            path = sub / f"{sub.name}.xml"
            if sub.name not in seen and path.is_file():
                seen.add(sub.name)
                found.append((sub.name, source, path))
    return found


def list_cars() -> list[dict]:
    """Every car load_car can find by name, bundled first, in the order load_car prefers them.

    Each dict: name, category, drive_type, mass_kg, power_kw, source ('bundled' | 'torcs'),
    path; a car that fails to load has None values and an 'error' message instead.
    """
    out = []
    for name, source, path in _car_files():
        entry = {"name": name, "category": None, "drive_type": None, "mass_kg": None,
                 "power_kw": None, "source": source, "path": str(path)}
        try:
            spec = load_car_file(path)
        except CarError as exc:
            entry["error"] = str(exc)
        else:
            entry.update(category=spec.category, drive_type=spec.drive_type, mass_kg=spec.mass,
                         power_kw=round(spec.max_power()[0] / 1000.0, 1))
        out.append(entry)
    return out


def _source_of(path: str) -> str:
    p = Path(path).resolve()
    if p.is_relative_to(bundled_cars_dir().resolve()):
        return "bundled"
    for root in torcs_data_roots():
        if root.is_dir() and p.is_relative_to(root.resolve()):
            return "torcs"
    return "file"


def car_info(name_or_path: str | os.PathLike | CarSpec) -> dict:
    """A JSON-serialisable summary of one car (a name, a path or a loaded CarSpec)."""
    s = name_or_path if isinstance(name_or_path, CarSpec) else load_car(name_or_path)
    power, power_w = s.max_power()
    torque, torque_w = s.max_torque()
    r = s.wheel_radius
    return {
        "name": s.name,
        "display_name": s.display_name,
        "category": s.category,
        "source": _source_of(s.source_path) if s.source_path else "spec",
        "path": s.source_path,
        "category_path": s.category_path,
        "drive_type": s.drive_type,
        "mass_kg": s.mass,
        "fuel_kg": s.fuel,
        "mass_total_kg": s.mass_total,
        "weight_front": round(s.weight_front, 4),
        "cg_height_m": round(s.cg_height, 4),
        "wheelbase_m": round(s.wheelbase, 4),
        "track_front_m": round(s.track_front, 4),
        "track_rear_m": round(s.track_rear, 4),
        "body_length_m": round(s.body_length, 4),
        "body_width_m": round(s.body_width, 4),
        "max_power_kw": round(power / 1000.0, 2),
        "max_power_rpm": round(power_w / RPM, 1),
        "max_torque_nm": round(torque, 2),
        "max_torque_rpm": round(torque_w / RPM, 1),
        "tickover_rpm": round(s.tickover / RPM, 1),
        "revs_limiter_rpm": round(s.revs_limiter / RPM, 1),
        "revs_maxi_rpm": round(s.revs_maxi / RPM, 1),
        "gears": [round(g, 4) for g in s.gear_ratios[1:]],
        "reverse_ratio": round(s.gear_ratios[0], 4),
        "final_drive": round(s.final_drive, 4),
        "shift_time_s": round(s.shift_time, 4),
        "front_torque_share": round(s.front_torque_share, 4),
        "tyre_radius_front_m": round(float(r[:2].mean()), 4),
        "tyre_radius_rear_m": round(float(r[2:].mean()), 4),
        "tyre_mu": [round(float(x), 4) for x in s.tyre_mu],
        "steer_lock_deg": round(s.steer_lock * 180.0 / 3.141592653589793, 2),
        "drag_scx2": round(s.scx2, 4),
        "top_gear": s.top_gear,
        "top_gear_redline_kmh": round(s.redline_speed() * 3.6, 1),
        "top_speed_estimate_kmh": round(s.top_speed_estimate() * 3.6, 1),
    }
