"""From a merged params tree to a `CarSpec`: simuv2's parameter names, defaults and clamps.

Defaults are simuv2's (spec/torcs-car-format.md section 2); they are rounded to float32 like
every number read from a file, so a spec written back to XML reads back identically.
"""

from __future__ import annotations

import numpy as np

from madsim.cars.errors import CarError
from madsim.cars.spec import AXLES, WHEELS, CarSpec, static_wheel_loads
from madsim.torcsxml import Section

__all__ = ["build_spec"]

_FORWARD_GEARS = 8  # simuv2 knows r, n and 1..8
_DIFFS = ("Front Differential", "Rear Differential", "Central Differential")


def _f32(x: float) -> float:
    return float(np.float32(x))


class _Reader:
    """Typed look-ups with simuv2 defaults on a merged tree."""

    def __init__(self, tree: Section):
        self.tree = tree

    def num(self, section: str, attr: str, default: float) -> float:
        sec = self.tree.sub(section)
        value = sec.num(attr) if sec is not None else None
        return _f32(default) if value is None else value

    def has(self, section: str, attr: str) -> bool:
        sec = self.tree.sub(section)
        return sec is not None and sec.num(attr) is not None

    def str(self, section: str, attr: str, default: str) -> str:
        sec = self.tree.sub(section)
        value = sec.str(attr) if sec is not None else None
        return default if value is None else value

    def wheels(self, suffix: str, attr: str, default: float) -> list[float]:
        return [self.num(f"{w} {suffix}", attr, default) for w in WHEELS]

    def axles(self, suffix: str, attr: str, default: float) -> list[float]:
        return [self.num(f"{a} {suffix}", attr, default) for a in AXLES]


def build_spec(tree: Section, *, name: str, display_name: str = "", category: str = "",
               source_path: str = "", category_path: str = "") -> CarSpec:
    """Read every simuv2 parameter of a merged tree into a CarSpec (raises CarError).

    `tree` is the car merged over its category (or a standalone car). The CarError's element
    names the XML section/attribute; the caller adds the file.
    """
    r = _Reader(tree)
    car = "Car"
    mass = r.num(car, "mass", 1500.0)
    front = r.num(car, "front-rear weight repartition", 0.5)
    front_right = r.num(car, "front right-left weight repartition", 0.5)
    rear_right = r.num(car, "rear right-left weight repartition", 0.5)
    body_length = r.num(car, "body length", 4.7)
    body_width = r.num(car, "body width", 1.9)

    speeds, torques = _torque_curve(tree)
    revs_maxi = r.num("Engine", "revs maxi", 1000.0)
    drive_type = r.str("Drivetrain", "type", "RWD")
    final_section = {"FWD": "Front Differential", "4WD": "Central Differential"}.get(drive_type,
                                                                                     "Rear Differential")
    ratios, inertias, efficiencies = _gears(r)
    lock = r.axles("Differential", "locking input torque", 3000.0)

    w0 = static_wheel_loads(mass, front, front_right, rear_right)
    op_load = [r.num(f"{w} Wheel", "operating load", 1.2 * w0[i]) for i, w in enumerate(WHEELS)]

    return CarSpec(
        name=name, display_name=display_name, category=category,
        source_path=source_path, category_path=category_path,
        mass=mass,
        fuel=r.num(car, "initial fuel", 80.0),
        fuel_tank=r.num(car, "fuel tank", 80.0),
        cg_height=r.num(car, "GC height", 0.5),
        weight_front=front, weight_front_right=front_right, weight_rear_right=rear_right,
        mass_repartition=r.num(car, "mass repartition coefficient", 1.0),
        body_length=body_length, body_width=body_width,
        body_height=r.num(car, "body height", 1.2),
        overall_length=r.num(car, "overall length", body_length),
        overall_width=r.num(car, "overall width", body_width),
        front_axle_x=r.num("Front Axle", "xpos", 0.0),
        rear_axle_x=r.num("Rear Axle", "xpos", 0.0),
        wheel_ypos=r.wheels("Wheel", "ypos", 0.0),
        axle_inertia=r.axles("Axle", "inertia", 0.15),
        roll_center_height=r.axles("Axle", "roll center height", 0.15),
        engine_speeds_rad_s=speeds, engine_torques_nm=torques,
        tickover=r.num("Engine", "tickover", 150.0),
        revs_limiter=r.num("Engine", "revs limiter", 800.0),
        revs_maxi=revs_maxi,
        engine_inertia=r.num("Engine", "inertia", 0.2423),
        engine_brake_coeff=r.num("Engine", "brake coefficient", 0.33),
        fuel_cons_factor=r.num("Engine", "fuel cons factor", 0.0622),
        drive_type=drive_type,
        gear_ratios=ratios, gear_inertias=inertias, gear_efficiencies=efficiencies,
        final_drive=r.num(final_section, "ratio", 1.0),
        shift_time=r.num("Gearbox", "shift time", 0.2),
        differential_types=tuple(r.str(d, "type", "NONE") for d in _DIFFS),
        central_min_torque_bias=r.num("Central Differential", "min torque bias", 0.05),
        central_max_torque_bias=r.num("Central Differential", "max torque bias", 0.8),
        central_viscosity=r.num("Central Differential", "viscosity factor", 1.0),
        diff_min_torque_bias=r.axles("Differential", "min torque bias", 0.05),
        diff_max_torque_bias=r.axles("Differential", "max torque bias", 0.8),
        diff_viscosity=r.axles("Differential", "viscosity factor", 1.0),
        diff_max_slip_bias=r.axles("Differential", "max slip bias", 0.03),
        diff_locking_torque=lock,
        diff_locking_brake_torque=[r.num(f"{a} Differential", "locking brake input torque", 0.33 * lock[i])
                                   for i, a in enumerate(AXLES)],
        steer_lock=r.num("Steer", "steer lock", 0.43),
        max_steer_speed=r.num("Steer", "max steer speed", 1.0),
        brake_front_share=r.num("Brake System", "front-rear brake repartition", 0.5),
        brake_max_pressure=r.num("Brake System", "max pressure", 1e6),
        brake_disk_diameter=r.wheels("Brake", "disk diameter", 0.2),
        brake_piston_area=r.wheels("Brake", "piston area", 0.002),
        brake_mu=r.wheels("Brake", "mu", 0.3),
        brake_inertia=r.wheels("Brake", "inertia", 0.13),
        rim_diameter=r.wheels("Wheel", "rim diameter", 0.33),
        tyre_width=r.wheels("Wheel", "tire width", 0.145),
        tyre_aspect=r.wheels("Wheel", "tire height-width ratio", 0.75),
        tyre_mu=r.wheels("Wheel", "mu", 1.0),
        tyre_stiffness=r.wheels("Wheel", "stiffness", 30.0),
        tyre_dynamic_friction=[min(max(v, _f32(0.1)), 1.0) for v in r.wheels("Wheel", "dynamic friction", 0.8)],
        tyre_elasticity=[min(v, 1.0) for v in r.wheels("Wheel", "elasticity factor", 0.7)],
        load_factor_min=[min(v, _f32(0.8)) for v in r.wheels("Wheel", "load factor min", 0.8)],
        load_factor_max=[max(v, _f32(1.6)) for v in r.wheels("Wheel", "load factor max", 1.6)],
        operating_load=op_load,
        camber=r.wheels("Wheel", "camber", 0.0),
        toe=r.wheels("Wheel", "toe", 0.0),
        wheel_inertia=r.wheels("Wheel", "inertia", 1.5),
        wheel_mass=r.wheels("Wheel", "mass", 20.0),
        ride_height=r.wheels("Wheel", "ride height", 0.2),
        susp_spring=r.wheels("Suspension", "spring", 175000.0),
        susp_course=r.wheels("Suspension", "suspension course", 0.5),
        susp_bellcrank=r.wheels("Suspension", "bellcrank", 1.0),
        susp_packers=r.wheels("Suspension", "packers", 0.0),
        susp_slow_bump=r.wheels("Suspension", "slow bump", 0.0),
        susp_slow_rebound=r.wheels("Suspension", "slow rebound", 0.0),
        susp_fast_bump=r.wheels("Suspension", "fast bump", 0.0),
        susp_fast_rebound=r.wheels("Suspension", "fast rebound", 0.0),
        susp_bump_threshold=r.wheels("Suspension", "fast bump threshold", 0.5),
        susp_rebound_threshold=r.wheels("Suspension", "fast rebound threshold", 0.5),
        anti_roll_spring=r.axles("Anti-Roll Bar", "spring", 0.0),
        cx=r.num("Aerodynamics", "Cx", 0.4),
        front_area=r.num("Aerodynamics", "front area", 2.5),
        clift=[r.num("Aerodynamics", "front Clift", 0.0), r.num("Aerodynamics", "rear Clift", 0.0)],
        wing_area=r.axles("Wing", "area", 0.0),
        wing_angle=r.axles("Wing", "angle", 0.0),
        wing_xpos=r.axles("Wing", "xpos", 0.0),
        wing_zpos=r.axles("Wing", "zpos", 0.0),
    )


def _torque_curve(tree: Section) -> tuple[list[float], list[float]]:
    """Points 1..count of `Engine/data points`, looked up by name as TORCS does."""
    points = tree.sub("Engine/data points")
    if points is None or not points.children:
        raise CarError("no torque curve (section 'Engine/data points' is missing or empty)",
                       element="Engine/data points")
    speeds, torques = [], []
    for i in range(1, len(points.children) + 1):
        point = points.children.get(str(i))
        where = f"Engine/data points/{i}"
        if point is None:
            names = ", ".join(points.children)
            raise CarError(f"torque curve points must be named 1..{len(points.children)}; "
                           f"point '{i}' is missing (found: {names})", element=where)
        rpm, tq = point.num("rpm"), point.num("Tq")
        if rpm is None or tq is None:
            missing = "rpm" if rpm is None else "Tq"
            raise CarError(f"torque curve point without a numeric '{missing}'", element=f"{where}/{missing}")
        speeds.append(rpm)
        torques.append(tq)
    bad = [i for i in range(1, len(speeds)) if not speeds[i] > speeds[i - 1]]
    if bad:
        raise CarError("torque curve rpm must increase strictly from point to point",
                       element=f"Engine/data points/{bad[0] + 1}/rpm")
    return speeds, torques


def _gears(r: _Reader) -> tuple[list[float], list[float], list[float]]:
    """(ratios, inertias, efficiencies) for reverse, 1..top; top = highest non-zero ratio."""
    names = ["r"] + [str(i) for i in range(1, _FORWARD_GEARS + 1)]
    ratio = {n: r.num(f"Gearbox/gears/{n}", "ratio", 0.0) for n in names}
    top = max((i for i in range(1, _FORWARD_GEARS + 1) if ratio[str(i)] != 0.0), default=0)
    if top == 0:
        raise CarError("no forward gear with a non-zero ratio (Gearbox/gears/1..8/ratio)",
                       element="Gearbox/gears")
    used = names[: top + 1]
    return ([ratio[n] for n in used],
            [r.num(f"Gearbox/gears/{n}", "inertia", 0.0) for n in used],
            [r.num(f"Gearbox/gears/{n}", "efficiency", 1.0) for n in used])
