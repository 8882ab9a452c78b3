"""`CarSpec`: one car's parameters, merged from category and car files, in SI units.

Frames and conventions (spec/torcs-car-format.md): body frame x forward, y left, z up, origin
at the centre of gravity (CG). "File frame" means the car file's own frame (axle and wing
`xpos`, wheel `ypos`), which has its origin wherever the car's author put it. Angles in rad,
engine speeds in rad/s, pressures in Pa, masses in kg, forces in N.

Per-wheel arrays have shape (4,) in the wheel order used everywhere:
0 front-right, 1 front-left, 2 rear-right, 3 rear-left. Per-axle arrays have shape (2,):
0 front, 1 rear. Wing arrays have shape (2,): 0 front wing, 1 rear wing.
All arrays are read-only float64 numpy arrays.

Fields fall in two groups: *inputs* (what the files say, after merging, clamping and defaults)
and *derived* quantities (computed in `__post_init__` from the inputs exactly as spec section 3
says, so `dataclasses.replace(spec, mass=...)` keeps them consistent).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np

from madsim.cars.errors import CarError

__all__ = ["CarSpec", "G", "WHEELS", "AXLES", "DRIVE_TYPES", "static_wheel_loads"]

G = 9.80665
"""Gravity used by TORCS, m/s^2."""
WHEELS = ("Front Right", "Front Left", "Rear Right", "Rear Left")
AXLES = ("Front", "Rear")
DRIVE_TYPES = ("RWD", "FWD", "4WD")


def static_wheel_loads(mass: float, front: float, front_right: float, rear_right: float) -> np.ndarray:
    """Static wheel loads W0 (N), shape (4,), from the weight splits (spec section 3)."""
    w = mass * G
    return np.array([w * front * front_right, w * front * (1.0 - front_right),
                     w * (1.0 - front) * rear_right, w * (1.0 - front) * (1.0 - rear_right)])


def _wheels(doc: str):
    return field(metadata={"shape": (4,), "doc": doc})


def _pair(doc: str, default: tuple[float, float] | None = None):
    if default is None:
        return field(metadata={"shape": (2,), "doc": doc})
    return field(default=default, metadata={"shape": (2,), "doc": doc})


def _derived(doc: str, shape: tuple | None = None):
    return field(init=False, metadata={"derived": True, "shape": shape, "doc": doc})


@dataclass(frozen=True, kw_only=True, eq=False, repr=False)
class CarSpec:
    """A car ready for the physics: every simuv2 parameter in SI units, plus derived constants.

    See the module docstring for frames, wheel order and array shapes. Equality compares every
    field except `source_path` and `category_path` (arrays element-wise, exactly).
    """

    # --- identity ---------------------------------------------------------------------------
    name: str                       # car id: the car's folder/file name, e.g. "car1-stock1"
    display_name: str = ""          # the file's <params name=...>, e.g. "Alfa Romeo 155 DTM"
    category: str = ""              # category name ("" if the car has none)
    source_path: str = field(default="", metadata={"compare": False})
    category_path: str = field(default="", metadata={"compare": False})

    # --- mass and body (Car section) ----------------------------------------------------------
    mass: float                     # dry mass, kg
    fuel: float                     # initial fuel, kg (TORCS reads litres as kg)
    fuel_tank: float                # tank capacity, kg
    cg_height: float                # CG height above the road reference, m ("GC height")
    weight_front: float             # fraction of weight on the front axle (f)
    weight_front_right: float       # fraction of the front axle's weight on the right wheel
    weight_rear_right: float        # fraction of the rear axle's weight on the right wheel
    mass_repartition: float         # k in the yaw inertia (smaller = mass more centred)
    body_length: float              # m; inertia box, car-car collision box, wall corners
    body_width: float               # m
    body_height: float              # m
    overall_length: float           # m; collision box (simuv2 uses body length for corners)
    overall_width: float            # m; corner points for wall collisions

    # --- axles and wheel placement ------------------------------------------------------------
    front_axle_x: float             # front axle x, file frame, m
    rear_axle_x: float              # rear axle x, file frame, m
    wheel_ypos: np.ndarray = _wheels("wheel y, file frame, m (right < 0)")
    axle_inertia: np.ndarray = _pair("axle spin inertia, kg m^2 (half to each wheel)")
    roll_center_height: np.ndarray = _pair("roll centre height, m")

    # --- engine -------------------------------------------------------------------------------
    engine_speeds_rad_s: np.ndarray = field(metadata={"shape": (None,), "doc": "torque curve x, rad/s"})
    engine_torques_nm: np.ndarray = field(metadata={"shape": (None,), "doc": "full-throttle torque, N m"})
    tickover: float                 # idle speed, rad/s
    revs_limiter: float             # red line: no torque above it, rad/s
    revs_maxi: float                # absolute engine-speed clamp, rad/s
    engine_inertia: float           # kg m^2, only while the engine is not coupled
    engine_brake_coeff: float       # engine-braking coefficient ("brake coefficient")
    fuel_cons_factor: float         # fuel use factor (consumption |T| we factor 1e-7 dt kg)

    # --- transmission -------------------------------------------------------------------------
    drive_type: str                 # "RWD", "FWD" or "4WD"
    gear_ratios: tuple[float, ...]  # (reverse, 1st, ..., top); reverse <= 0 (0: none)
    gear_inertias: tuple[float, ...]     # same order, kg m^2 (inertia bookkeeping only)
    gear_efficiencies: tuple[float, ...]  # same order (divides wheel inertia only, spec 4.10)
    final_drive: float              # ratio of the differential the drive type uses
    shift_time: float               # s of zero drive torque after a gear change
    differential_types: tuple[str, str, str]  # (front, rear, central) type, "NONE" if absent
    central_min_torque_bias: float  # 4WD centre diff: front share while front not slower
    central_max_torque_bias: float  # 4WD centre diff: largest front share
    central_viscosity: float        # 4WD viscous coupler factor (1/(rad/s))
    # the two axle differentials (front, rear), spec 4.10; TORCS's defaults
    diff_min_torque_bias: np.ndarray = _pair("viscous coupler: right wheel's share while not slower", (0.05, 0.05))
    diff_max_torque_bias: np.ndarray = _pair("viscous coupler: right wheel's largest share", (0.8, 0.8))
    diff_viscosity: np.ndarray = _pair("viscous coupler factor, 1/(rad/s)", (1.0, 1.0))
    diff_max_slip_bias: np.ndarray = _pair("limited slip: largest |w0 - w1| / (|w0| + |w1|) at no torque",
                                           (0.03, 0.03))
    diff_locking_torque: np.ndarray = _pair("limited slip: input torque above which it locks, N m",
                                            (3000.0, 3000.0))
    diff_locking_brake_torque: np.ndarray = _pair("limited slip: braking input torque above which it locks, "
                                                  "N m (TORCS default 0.33 x locking torque)", (990.0, 990.0))

    # --- steering ------------------------------------------------------------------------------
    steer_lock: float               # steering angle at command 1, rad
    max_steer_speed: float          # steering angle rate limit, rad/s

    # --- brakes ---------------------------------------------------------------------------------
    brake_front_share: float        # front share of the brake pressure ("repartition")
    brake_max_pressure: float       # pressure at brake command 1, Pa
    brake_disk_diameter: np.ndarray = _wheels("m")
    brake_piston_area: np.ndarray = _wheels("m^2")
    brake_mu: np.ndarray = _wheels("pad friction coefficient")
    brake_inertia: np.ndarray = _wheels("kg m^2 (read, unused by simuv2)")

    # --- wheels and tyres -----------------------------------------------------------------------
    rim_diameter: np.ndarray = _wheels("m")
    tyre_width: np.ndarray = _wheels("m")
    tyre_aspect: np.ndarray = _wheels("tyre height/width ratio")
    tyre_mu: np.ndarray = _wheels("tyre friction coefficient")
    tyre_stiffness: np.ndarray = _wheels("Ca, magic-formula stiffness")
    tyre_dynamic_friction: np.ndarray = _wheels("RF, clamped to [0.1, 1]")
    tyre_elasticity: np.ndarray = _wheels("EF, clamped to <= 1")
    load_factor_min: np.ndarray = _wheels("lfMin, clamped to <= 0.8")
    load_factor_max: np.ndarray = _wheels("lfMax, clamped to >= 1.6")
    operating_load: np.ndarray = _wheels("N; default 1.2 x static wheel load")
    camber: np.ndarray = _wheels("rad")
    toe: np.ndarray = _wheels("rad")
    wheel_inertia: np.ndarray = _wheels("spin inertia, kg m^2")
    wheel_mass: np.ndarray = _wheels("kg")
    ride_height: np.ndarray = _wheels("static ride height, m")

    # --- suspension (TORCS units as converted: lbs/in reads as kg/m, used as N/m) -----------------
    susp_spring: np.ndarray = _wheels("spring rate, N/m (as TORCS uses it)")
    susp_course: np.ndarray = _wheels("suspension travel, m")
    susp_bellcrank: np.ndarray = _wheels("bellcrank ratio")
    susp_packers: np.ndarray = _wheels("packer thickness, m")
    susp_slow_bump: np.ndarray = _wheels("damper rate, N s/m")
    susp_slow_rebound: np.ndarray = _wheels("damper rate, N s/m")
    susp_fast_bump: np.ndarray = _wheels("damper rate, N s/m")
    susp_fast_rebound: np.ndarray = _wheels("damper rate, N s/m")
    susp_bump_threshold: np.ndarray = _wheels("slow/fast switch, m/s")
    susp_rebound_threshold: np.ndarray = _wheels("slow/fast switch, m/s")
    anti_roll_spring: np.ndarray = _pair("anti-roll bar rate (front, rear), N/m as TORCS uses it")

    # --- aerodynamics -------------------------------------------------------------------------
    cx: float                       # body drag coefficient
    front_area: float               # m^2
    clift: np.ndarray = _pair("body lift coefficients (front, rear); positive = downforce")
    wing_area: np.ndarray = _pair("wing area (front, rear), m^2")
    wing_angle: np.ndarray = _pair("wing angle of attack (front, rear), rad")
    wing_xpos: np.ndarray = _pair("wing x, file frame, m")
    wing_zpos: np.ndarray = _pair("wing z, m")

    # --- derived (spec section 3) -------------------------------------------------------------
    mass_total: float = _derived("mass + fuel, kg (the dynamic mass)")
    izz: float = _derived("yaw inertia m (W^2 + k^2 Lb^2)/12 from the dry mass, kg m^2")
    ixx: float = _derived("roll inertia m (W^2 + H^2)/12, kg m^2")
    iyy: float = _derived("pitch inertia m (Lb^2 + H^2)/12, kg m^2")
    cg_x: float = _derived("CG x in the file frame, m")
    cg_y: float = _derived("CG y in the file frame, m")
    wheelbase: float = _derived("L = front_axle_x - rear_axle_x, m")
    a: float = _derived("CG to front axle, (1 - f) L, m")
    b: float = _derived("CG to rear axle, f L, m")
    track_front: float = _derived("|ypos_FL - ypos_FR|, m")
    track_rear: float = _derived("|ypos_RL - ypos_RR|, m")
    wheel_pos: np.ndarray = _derived("wheel (x, y) relative to the CG, m", (4, 2))
    static_wheel_load: np.ndarray = _derived("W0 from the dry mass, N", (4,))
    wheel_radius: np.ndarray = _derived("R = rim/2 + width * aspect, m", (4,))
    mf_b: np.ndarray = _derived("magic formula B = Ca / C", (4,))
    mf_c: np.ndarray = _derived("magic formula C = 2 - (2/pi) asin(RF)", (4,))
    mf_e: np.ndarray = _derived("magic formula E = EF", (4,))
    load_factor_k: np.ndarray = _derived("lfK = ln((1 - lfMin)/(lfMax - lfMin))", (4,))
    brake_kb: np.ndarray = _derived("brake torque per Pa: disk/2 * piston area * mu, N m/Pa", (4,))
    scx2: float = _derived("body drag constant 0.645 Cx A, kg/m (drag = scx2 vx^2)")
    wing_x: np.ndarray = _derived("wing x relative to the CG, m", (2,))
    wing_kx: np.ndarray = _derived("wing drag constant -1.23 area, kg/m", (2,))
    wing_kz: np.ndarray = _derived("wing lift constant 4 Kx, kg/m", (2,))
    overall_ratios: tuple = _derived("gear_ratios x final_drive, same order")
    front_torque_share: float = _derived("front share of drive torque: RWD 0, FWD 1, 4WD min bias")
    driven_wheels: np.ndarray = _derived("True for driven wheels", (4,))
    driven_wheel_radius: float = _derived("mean radius of the driven wheels, m")

    def __post_init__(self) -> None:
        for f in fields(self):
            shape = f.metadata.get("shape")
            if f.init and shape is not None:
                self._set(f.name, _array(getattr(self, f.name), shape, f.name))
            elif f.init and f.type == "float":
                self._set(f.name, _scalar(getattr(self, f.name), f.name))
        for name in ("gear_ratios", "gear_inertias", "gear_efficiencies"):
            self._set(name, tuple(_scalar(x, name) for x in _sequence(getattr(self, name), name)))
        self._set("differential_types", tuple(str(x) for x in _sequence(self.differential_types,
                                                                      "differential_types")))
        _validate(self)
        self._derive()

    def _set(self, name: str, value) -> None:
        object.__setattr__(self, name, value)

    def _derive(self) -> None:
        m, f = self.mass, self.weight_front
        frl, rrl = self.weight_front_right, self.weight_rear_right
        L, W, H = self.body_length, self.body_width, self.body_height
        k = self.mass_repartition
        s = self._set
        s("mass_total", m + self.fuel)
        s("izz", m * (W * W + k * k * L * L) / 12.0)
        s("ixx", m * (W * W + H * H) / 12.0)
        s("iyy", m * (L * L + H * H) / 12.0)
        cg_x = self.front_axle_x * f + self.rear_axle_x * (1.0 - f)
        cg_y = W / 2.0 - W * (f * frl + (1.0 - f) * rrl)
        s("cg_x", cg_x)
        s("cg_y", cg_y)
        s("wheelbase", self.front_axle_x - self.rear_axle_x)
        s("a", self.front_axle_x - cg_x)
        s("b", cg_x - self.rear_axle_x)
        y = self.wheel_ypos
        s("track_front", abs(float(y[1] - y[0])))
        s("track_rear", abs(float(y[3] - y[2])))
        xs = np.array([self.front_axle_x] * 2 + [self.rear_axle_x] * 2) - cg_x
        s("wheel_pos", _ro(np.stack([xs, y - cg_y], axis=1)))
        s("static_wheel_load", _ro(static_wheel_loads(m, f, frl, rrl)))
        s("wheel_radius", _ro(self.rim_diameter / 2.0 + self.tyre_width * self.tyre_aspect))
        c = 2.0 - (2.0 / math.pi) * np.arcsin(self.tyre_dynamic_friction)
        s("mf_c", _ro(c))
        s("mf_b", _ro(self.tyre_stiffness / c))
        s("mf_e", _ro(self.tyre_elasticity.copy()))
        lf_min, lf_max = self.load_factor_min, self.load_factor_max
        s("load_factor_k", _ro(np.log((1.0 - lf_min) / (lf_max - lf_min))))
        s("brake_kb", _ro(self.brake_disk_diameter / 2.0 * self.brake_piston_area * self.brake_mu))
        s("scx2", 0.645 * self.cx * self.front_area)
        s("wing_x", _ro(self.wing_xpos - cg_x))
        kx = -1.23 * self.wing_area
        s("wing_kx", _ro(kx))
        s("wing_kz", _ro(4.0 * kx))
        s("overall_ratios", tuple(r * self.final_drive for r in self.gear_ratios))
        share = {"RWD": 0.0, "FWD": 1.0, "4WD": self.central_min_torque_bias}[self.drive_type]
        s("front_torque_share", share)
        driven = np.array([self.drive_type != "RWD"] * 2 + [self.drive_type != "FWD"] * 2)
        driven.flags.writeable = False
        s("driven_wheels", driven)
        s("driven_wheel_radius", float(self.wheel_radius[driven].mean()))

    # --- engine and gearing --------------------------------------------------------------------

    def torque_at(self, omega):
        """Full-throttle engine torque (N m) at engine speed `omega` (rad/s), scalar or array.

        Linear interpolation between the curve points; constant beyond the first/last point.
        """
        out = np.interp(omega, self.engine_speeds_rad_s, self.engine_torques_nm)
        return float(out) if np.ndim(out) == 0 else out

    def _curve_in_range(self) -> np.ndarray:
        w = self.engine_speeds_rad_s
        return (w >= self.tickover) & (w < self.revs_limiter)

    def max_torque(self) -> tuple[float, float]:
        """(torque N m, engine speed rad/s) of the largest curve point with tickover <= w < limiter.

        As TORCS reports it (spec section 3): data points only, no interpolation; (0, 0) if none.
        """
        ok = self._curve_in_range()
        if not ok.any():
            return 0.0, 0.0
        tq = np.where(ok, self.engine_torques_nm, -np.inf)
        i = int(np.argmax(tq))
        return float(self.engine_torques_nm[i]), float(self.engine_speeds_rad_s[i])

    def max_power(self) -> tuple[float, float]:
        """(power W, engine speed rad/s) of the curve point with the largest w * Tq in range."""
        ok = self._curve_in_range()
        if not ok.any():
            return 0.0, 0.0
        p = np.where(ok, self.engine_speeds_rad_s * self.engine_torques_nm, -np.inf)
        i = int(np.argmax(p))
        return float(p[i]), float(self.engine_speeds_rad_s[i])

    @property
    def top_gear(self) -> int:
        """Highest forward gear (gear numbers: -1 reverse, 0 neutral, 1..top_gear)."""
        return len(self.gear_ratios) - 1

    def overall_ratio(self, gear: int) -> float:
        """G = gear ratio x final drive for gear -1 (reverse), 0 (neutral: 0) or 1..top_gear."""
        if gear == 0:
            return 0.0
        if gear == -1:
            return self.overall_ratios[0]
        if 1 <= gear <= self.top_gear:
            return self.overall_ratios[gear]
        raise ValueError(f"gear {gear} not in -1..{self.top_gear}")

    def redline_speed(self, gear: int | None = None) -> float:
        """Car speed (m/s) at the rev limiter in `gear` (default top gear): w_lim R / |G|.

        R is the mean radius of the driven wheels; inf for neutral or a zero ratio.
        """
        ratio = abs(self.overall_ratio(self.top_gear if gear is None else gear))
        return math.inf if ratio == 0.0 else self.revs_limiter * self.driven_wheel_radius / ratio

    def top_speed_estimate(self, points_per_gear: int = 4000) -> float:
        """Highest speed (m/s) at which full-throttle drive force beats aero drag in some gear.

        An estimate for catalogues and tests, not the physics: drive force
        `torque_at(v G / R) G / R` (zero above the rev limiter), drag `(scx2 - sum Kx sin(angle)) v^2`
        (body and wings at zero pitch), no rolling resistance, grip or downforce.
        """
        drag = self.scx2 - float(np.sum(self.wing_kx * np.sin(self.wing_angle)))
        best = 0.0
        for gear in range(1, self.top_gear + 1):
            ratio = self.overall_ratio(gear)
            v = np.linspace(0.0, self.redline_speed(gear), points_per_gear)
            force = self.torque_at(v * ratio / self.driven_wheel_radius) * ratio / self.driven_wheel_radius
            ok = force >= drag * v * v
            if ok.any():
                best = max(best, float(v[ok].max()))
        return best

    # --- value semantics -----------------------------------------------------------------------

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, CarSpec):
            return NotImplemented
        for f in fields(self):
            if not f.metadata.get("compare", True):
                continue
            x, y = getattr(self, f.name), getattr(other, f.name)
            if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
                if not (np.shape(x) == np.shape(y) and np.array_equal(x, y)):
                    return False
            elif x != y:
                return False
        return True

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return (f"CarSpec(name={self.name!r}, category={self.category!r}, mass={self.mass:g}, "
                f"drive_type={self.drive_type!r}, top_gear={self.top_gear}, "
                f"source_path={self.source_path!r})")


# --- helpers ---------------------------------------------------------------------------------


def _ro(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    a.flags.writeable = False
    return a


def _scalar(value, name: str) -> float:
    if isinstance(value, (bool, str)) or np.ndim(value) != 0:
        raise CarError(f"{name} must be a number, got {value!r}")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise CarError(f"{name} must be a number, got {value!r}") from None


def _sequence(value, name: str) -> tuple:
    if isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
        raise CarError(f"{name} must be a sequence, got {value!r}")
    return tuple(value)


def _array(value, shape: tuple, name: str) -> np.ndarray:
    try:
        a = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise CarError(f"{name} must be numeric, got {value!r}") from None
    if a.ndim != len(shape) or any(n is not None and n != m for n, m in zip(shape, a.shape)):
        raise CarError(f"{name} must have shape {shape}, got {a.shape}")
    a.flags.writeable = False
    return a


def _validate(c: CarSpec) -> None:
    """Reject values no physics can use; the CarError names the XML element of the field."""

    def need(ok: bool, element: str, reason: str) -> None:
        if not ok:
            raise CarError(reason, element=element)

    finite = [f.name for f in fields(c) if f.init and isinstance(getattr(c, f.name), (float, np.ndarray))
              and not np.all(np.isfinite(getattr(c, f.name)))]
    need(not finite, finite[0] if finite else "", f"{finite[0] if finite else ''} is not finite")
    for attr in ("name", "display_name", "category", "drive_type"):
        need(isinstance(getattr(c, attr), str), attr, f"{attr} must be a string")
    need(c.name != "", "name", "the car needs a name")
    need(c.mass > 0, "Car/mass", f"mass must be > 0 kg, got {c.mass:g}")
    need(c.fuel >= 0, "Car/initial fuel", f"initial fuel must be >= 0, got {c.fuel:g}")
    for attr in ("body length", "body width", "body height"):
        v = getattr(c, attr.replace(" ", "_"))
        need(v > 0, f"Car/{attr}", f"{attr} must be > 0 m, got {v:g}")
    for attr, v in (("front-rear weight repartition", c.weight_front),
                    ("front right-left weight repartition", c.weight_front_right),
                    ("rear right-left weight repartition", c.weight_rear_right)):
        need(0.0 <= v <= 1.0, f"Car/{attr}", f"{attr} must be in [0, 1], got {v:g}")
    need(c.front_axle_x > c.rear_axle_x, "Front Axle/xpos",
         f"front axle x ({c.front_axle_x:g} m) must be ahead of the rear axle x ({c.rear_axle_x:g} m)")
    w, tq = c.engine_speeds_rad_s, c.engine_torques_nm
    need(len(w) >= 2 and len(w) == len(tq), "Engine/data points",
         f"the torque curve needs at least 2 points with rpm and Tq, got {len(w)}")
    need(bool(np.all(np.diff(w) > 0)), "Engine/data points", "torque curve rpm must increase strictly")
    need(c.revs_limiter > 0, "Engine/revs limiter", f"revs limiter must be > 0, got {c.revs_limiter:g}")
    need(c.revs_maxi > 0, "Engine/revs maxi", f"revs maxi must be > 0, got {c.revs_maxi:g}")
    need(0 <= c.tickover < c.revs_maxi, "Engine/tickover",
         f"tickover must be in [0, revs maxi), got {c.tickover:g} rad/s")
    need(c.drive_type in DRIVE_TYPES, "Drivetrain/type",
         f"drive type must be one of {', '.join(DRIVE_TYPES)}, got {c.drive_type!r}")
    n = len(c.gear_ratios)
    need(n >= 2, "Gearbox/gears", "no forward gear with a non-zero ratio")
    need(len(c.gear_inertias) == n and len(c.gear_efficiencies) == n, "Gearbox/gears",
         "gear_inertias and gear_efficiencies must match gear_ratios")
    need(c.gear_ratios[0] <= 0, "Gearbox/gears/r/ratio", f"reverse ratio must be <= 0, got {c.gear_ratios[0]:g}")
    bad = [i for i in range(1, n) if not c.gear_ratios[i] > 0]
    need(not bad, f"Gearbox/gears/{bad[0] if bad else 1}/ratio", "forward gear ratios must be > 0")
    diff = {"RWD": "Rear", "FWD": "Front", "4WD": "Central"}.get(c.drive_type, "Rear")
    need(c.final_drive > 0, f"{diff} Differential/ratio", f"final drive must be > 0, got {c.final_drive:g}")
    need(len(c.differential_types) == 3, "Drivetrain", "differential_types must be (front, rear, central)")
    need(c.shift_time >= 0, "Gearbox/shift time", f"shift time must be >= 0, got {c.shift_time:g}")
    need(c.steer_lock > 0, "Steer/steer lock", f"steer lock must be > 0, got {c.steer_lock:g}")
    need(c.max_steer_speed > 0, "Steer/max steer speed", "max steer speed must be > 0")
    need(0 <= c.brake_front_share <= 1, "Brake System/front-rear brake repartition",
         "brake repartition must be in [0, 1]")
    need(c.brake_max_pressure >= 0, "Brake System/max pressure", "max pressure must be >= 0")
    radius = c.rim_diameter / 2.0 + c.tyre_width * c.tyre_aspect
    for attr, ok in (("rim diameter", radius > 0), ("mu", c.tyre_mu > 0),
                     ("stiffness", c.tyre_stiffness > 0), ("operating load", c.operating_load > 0),
                     ("dynamic friction", (c.tyre_dynamic_friction >= 0.1) & (c.tyre_dynamic_friction <= 1)),
                     ("load factor min", c.load_factor_min < 1.0),
                     ("load factor max", c.load_factor_max > 1.0)):
        i = int(np.argmin(ok))
        need(bool(ok.all()), f"{WHEELS[i]} Wheel/{attr}", f"{attr} out of range: {_wheel_value(c, attr, i)}")
    need(c.front_area >= 0 and c.cx >= 0, "Aerodynamics", "Cx and front area must be >= 0")


def _wheel_value(c: CarSpec, attr: str, i: int) -> str:
    table = {"rim diameter": c.rim_diameter, "mu": c.tyre_mu, "stiffness": c.tyre_stiffness,
             "operating load": c.operating_load, "dynamic friction": c.tyre_dynamic_friction,
             "load factor min": c.load_factor_min, "load factor max": c.load_factor_max}
    return f"{table[attr][i]:g}"
