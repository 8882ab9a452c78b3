"""Flatten `CarSpec`s and a `Track` into the constant arrays the kernels read (layout.py).

Approximation made here (spec/torcs-car-format.md 5.4): one tyre shape per axle (the right
wheel's B, C, E; TORCS cars use the same values left and right).
"""

from __future__ import annotations

import math

import numpy as np

from madsim.cars.spec import CarSpec
from madsim.physics import layout as L
from madsim.physics.kernel import car_derived
from madsim.tracks.build import COL, LEFT, STYLE_CURB
from madsim.tracks.track import Track

SKID = {"rookie": 0.40, "amateur": 0.35, "semi-pro": 0.30, "pro": 0.0}
"""Skid term of the tyre formula per TORCS driver skill level (spec 4.9)."""
DAMAGE_SKILL = {"rookie": 0.0, "amateur": 0.5, "semi-pro": 0.8, "pro": 1.0}
"""TORCS's damage factor per skill level (spec 4.12; simuv2's simDammageFactor): the contact
solver's and the bottoming's (`suspension.ground_contact`)."""


def car_table(cars: list[CarSpec], skills: list[str],
              damage: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(cp (N, N_CAR), curve_w (N, M), curve_t (N, M)): per-car constants and torque curves.
    damage: False sets every car's damage factor (C_DMGK) to 0 (no bottoming damage)."""
    n = len(cars)
    m = max(len(c.engine_speeds_rad_s) for c in cars)
    cp = np.zeros((n, L.N_CAR))
    curve_w = np.zeros((n, m))
    curve_t = np.zeros((n, m))
    for i, (car, skill) in enumerate(zip(cars, skills)):
        cp[i] = _car_row(car, SKID[skill])
        cp[i, L.C_DMGK] = DAMAGE_SKILL[skill] if damage else 0.0
        k = len(car.engine_speeds_rad_s)
        curve_w[i, :k] = car.engine_speeds_rad_s
        curve_t[i, :k] = car.engine_torques_nm
        curve_w[i, k:] = car.engine_speeds_rad_s[-1]
        curve_t[i, k:] = car.engine_torques_nm[-1]
    car_derived(cp)
    return cp, curve_w, curve_t


def _car_row(c: CarSpec, skid: float) -> np.ndarray:
    row = np.zeros(L.N_CAR)
    if c.top_gear + 2 > L.MAX_GEAR_SLOTS:
        raise ValueError(f"car {c.name}: {c.top_gear} forward gears, at most {L.MAX_GEAR_SLOTS - 2} supported")
    wl = c.wheelbase
    row[L.C_MASS] = c.mass
    row[L.C_IZZ] = c.izz
    row[L.C_A], row[L.C_B], row[L.C_L] = c.a, c.b, wl
    row[L.C_H] = c.cg_height
    row[L.C_TF], row[L.C_TR] = c.track_front, c.track_rear
    row[L.C_WF], row[L.C_WFR], row[L.C_WRR] = c.weight_front, c.weight_front_right, c.weight_rear_right
    row[L.C_SKID] = skid
    row[L.C_BF], row[L.C_CF], row[L.C_EF] = c.mf_b[0], c.mf_c[0], c.mf_e[0]
    row[L.C_BR], row[L.C_CR], row[L.C_ER] = c.mf_b[2], c.mf_c[2], c.mf_e[2]
    row[L.C_TICK], row[L.C_LIMIT], row[L.C_MAXI] = c.tickover, c.revs_limiter, c.revs_maxi
    row[L.C_IENG], row[L.C_EBRAKE], row[L.C_FUELCONS] = c.engine_inertia, c.engine_brake_coeff, c.fuel_cons_factor
    row[L.C_NCURVE] = len(c.engine_speeds_rad_s)
    row[L.C_TOP], row[L.C_SHIFT] = c.top_gear, c.shift_time
    row[L.C_FSHARE] = c.front_torque_share
    # TORCS's 4WD chain feeds each axle's tyre torque back twice: to the centre differential
    # (divided by its ratio), whose net output drives the axle differential, and again to the
    # axle differential, so the axle feels it (1 + 1 / centre ratio) times (spec 4.10; the
    # kernel's _axle_spin takes the 1 / ratio off the axle's input); one or two-wheel drive once
    row[L.C_REACT] = 1.0 + 1.0 / c.final_drive if c.drive_type == "4WD" else 1.0
    if c.drive_type == "4WD" and c.differential_types[2] == "VISCOUS COUPLER":
        # the centre viscous coupler (spec 4.10): front share from min to max torque bias as the
        # front axle falls behind the rear; viscosity 0 keeps the min bias
        row[L.C_VISC_MAX] = max(c.central_max_torque_bias, c.central_min_torque_bias)
        row[L.C_VISC] = max(c.central_viscosity, 0.0)
    driven = c.driven_wheels
    row[L.C_DRIVEN_F], row[L.C_DRIVEN_R] = float(driven[0]), float(driven[2])
    for j in range(2):      # the axle differentials (spec 4.10); a non-driven axle has none
        kind = c.differential_types[j] if driven[2 * j] else "NONE"
        row[L.C_DKIND + j] = L.DIFF_KINDS.index(kind) if kind in L.DIFF_KINDS else L.DIFF_NONE
        row[L.C_DSLIP + j] = c.diff_max_slip_bias[j]
        row[L.C_DLOCK + j] = c.diff_locking_torque[j]
        row[L.C_DLOCKB + j] = c.diff_locking_brake_torque[j]
        row[L.C_DMIN + j] = c.diff_min_torque_bias[j]
        row[L.C_DSPAN + j] = max(c.diff_max_torque_bias[j] - c.diff_min_torque_bias[j], 0.0)
        row[L.C_DVISC + j] = c.diff_viscosity[j]
    wheel_i = c.wheel_inertia + np.repeat(c.axle_inertia, 2) / 2.0   # I_free per wheel (spec 4.10)
    row[L.C_IFREE_F] = wheel_i[0] + wheel_i[1]
    row[L.C_IFREE_R] = wheel_i[2] + wheel_i[3]
    row[L.C_LOCK], row[L.C_STEERSPD] = c.steer_lock, c.max_steer_speed
    row[L.C_BRAKE_FRONT], row[L.C_PMAX] = c.brake_front_share, c.brake_max_pressure
    row[L.C_SCX2] = c.scx2
    # TORCS's drag coefficient for the slipstream (spec 4.6): SCx2 + the rear wing's drag
    row[L.C_CD] = c.scx2 - float(c.wing_kx[1] * np.sin(c.wing_angle[1]))
    row[L.C_CLIFT_F], row[L.C_CLIFT_R] = c.clift
    row[L.C_HALF_LEN], row[L.C_HALF_WID] = c.body_length / 2.0, c.body_width / 2.0
    row[L.C_REACH] = float(np.max(np.hypot(c.wheel_pos[:, 0], c.wheel_pos[:, 1])))   # CG to farthest wheel
    bell = np.maximum(c.susp_bellcrank, 1e-6)
    per_wheel = (      # (first column, its four values in wheel order FR FL RR RL)
        (L.C_WY, c.wheel_pos[:, 1]), (L.C_RAD, c.wheel_radius),
        (L.C_KMU, c.tyre_mu * (1.0 + 0.05 * np.sin(-18.0 * c.camber))),
        (L.C_OPLOAD, c.operating_load), (L.C_LFMIN, c.load_factor_min),
        (L.C_LFMAX, c.load_factor_max), (L.C_LFK, c.load_factor_k),
        (L.C_W0, c.static_wheel_load), (L.C_RIDE0, c.ride_height), (L.C_KB, c.brake_kb),
        (L.C_TOE, c.toe),
        # suspension of the vertical dynamics (docs/physics.md)
        (L.C_SPRING, np.maximum(c.susp_spring, 1.0 / bell ** 2)), (L.C_BELL, bell),
        (L.C_COURSE, c.susp_course), (L.C_PACK, c.susp_packers),
        (L.C_DBUMP1, c.susp_slow_bump), (L.C_DBUMP2, c.susp_fast_bump),
        (L.C_VBUMP, c.susp_bump_threshold), (L.C_DREB1, c.susp_slow_rebound),
        (L.C_DREB2, c.susp_fast_rebound), (L.C_VREB, c.susp_rebound_threshold),
        (L.C_WMASS, np.maximum(c.wheel_mass, 1e-3)), (L.C_WX, c.wheel_pos[:, 0]),
    )
    for col, values in per_wheel:
        row[col:col + 4] = values
    per_axle = (       # (first column, front and rear): anti-roll bars, roll centres, wings
        (L.C_ARB, c.anti_roll_spring), (L.C_RC, c.roll_center_height), (L.C_WGKX, c.wing_kx),
        (L.C_WGKZ, c.wing_kz), (L.C_WGANG, c.wing_angle), (L.C_WGX, c.wing_x),
        (L.C_WGZ, c.wing_zpos),
    )
    for col, values in per_axle:
        row[col:col + 2] = values
    row[L.C_IXX], row[L.C_IYY] = c.ixx, c.iyy
    # overall ratios and drive inertias per gear slot (slot = gear + 1; slot 1 = neutral)
    share_i = 0.25 if c.drive_type == "4WD" else 0.5
    for gear in range(-1, c.top_gear + 1):
        slot = gear + 1
        if gear == 0:
            row[L.C_IDRIVE_F + slot] = row[L.C_IFREE_F]
            row[L.C_IDRIVE_R + slot] = row[L.C_IFREE_R]
            continue
        idx = 0 if gear == -1 else gear
        ratio = c.overall_ratios[idx]
        row[L.C_RATIO + slot] = ratio
        gear_i = c.gear_inertias[idx] * ratio * ratio * share_i
        eff = c.gear_efficiencies[idx] if c.gear_efficiencies[idx] > 0 else 1.0
        row[L.C_IDRIVE_F + slot] = 2.0 * gear_i + (wheel_i[0] + wheel_i[1]) / eff
        row[L.C_IDRIVE_R + slot] = 2.0 * gear_i + (wheel_i[2] + wheel_i[3]) / eff
    return row


def piece_table(track: Track) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(pt (P, N_PIECE), surf (S, 6), tsc (4,)) for the kernels. surf's columns: friction, rolling
    resistance, roughness amplitude (m: half the file's roughness, as TORCS) and wave number
    (rad/m: 2 pi / roughness wavelength), see `suspension.relief`; rebound and dammage (the
    packers' ground contact, `suspension.ground_contact`)."""
    p = track.pieces
    w = track.width
    npc = p.shape[0]
    pt = np.zeros((npc, L.N_PIECE))
    pt[:, :L.N_GEO] = track.geo
    pt[:, L.P_ZR0] = p[:, COL["zr0"]]
    pt[:, L.P_ZR1] = p[:, COL["zr1"]]
    pt[:, L.P_B0] = np.arctan2(p[:, COL["zl0"]] - p[:, COL["zr0"]], w)
    pt[:, L.P_B1] = np.arctan2(p[:, COL["zl1"]] - p[:, COL["zr1"]], w)
    pt[:, L.P_TB0] = np.tan(pt[:, L.P_B0])
    pt[:, L.P_SURF] = p[:, COL["surface"]]
    for dst, src in ((L.P_BW_R, "border_w_r"), (L.P_BW_L, "border_w_l"), (L.P_BSURF_R, "border_surf_r"),
                     (L.P_BSURF_L, "border_surf_l"), (L.P_SW0_R, "side_w0_r"), (L.P_SW1_R, "side_w1_r"),
                     (L.P_SW0_L, "side_w0_l"), (L.P_SW1_L, "side_w1_l"), (L.P_SSURF_R, "side_surf_r"),
                     (L.P_SSURF_L, "side_surf_l"), (L.P_WSURF_R, "barrier_surf_r"),
                     (L.P_WSURF_L, "barrier_surf_l")):
        pt[:, dst] = p[:, COL[src]]
    # race flags (track spec 4.7): "last" wins over "start"
    s0, ln, total = p[:, COL["s0"]], p[:, COL["length"]], track.length
    last = s0 + ln > total - 50.0
    start = ~last & (s0 < 50.0)
    pt[:, L.P_FLAG] = np.where(last, L.FLAG_LAST, np.where(start, L.FLAG_START, 0.0))
    pt[:, L.P_INVLEN] = 1.0 / pt[:, L.P_LEN]
    kind = pt[:, L.P_KIND]
    with np.errstate(divide="ignore"):
        pt[:, L.P_CURV] = np.where(kind == 1, 1.0 / pt[:, L.P_R], np.where(kind == 2, -1.0 / pt[:, L.P_R], 0.0))
    pt[:, L.P_CURB_R] = p[:, COL["border_style_r"]] == STYLE_CURB
    pt[:, L.P_CURB_L] = p[:, COL["border_style_l"]] == STYLE_CURB
    # a curb rises by atan2(height, width) per metre into it (TORCS 1.3.7's RtTrackHeightL)
    for curb, rise, sfx in ((L.P_CURB_R, L.P_CURBK_R, "r"), (L.P_CURB_L, L.P_CURBK_L, "l")):
        bw = p[:, COL[f"border_w_{sfx}"]]
        pt[:, rise] = np.where((pt[:, curb] > 0.0) & (bw > 0.0), np.arctan2(p[:, COL[f"border_h_{sfx}"]], bw), 0.0)
    road = pt[:, L.P_SURF]
    pt[:, L.P_SAMESURF] = (road == np.roll(road, 1)) & (road == np.roll(road, -1))
    surf = np.array([[sf.friction, sf.rolling_resistance, sf.roughness, 2.0 * np.pi / sf.roughness_wavelength,
                      sf.rebound, sf.dammage] for sf in track.surfaces], dtype=np.float64)
    tsc = np.array([track.length, w, float(track.side_bank_tangent[0]), float(track.side_bank_tangent[1])])
    return np.ascontiguousarray(pt), surf, tsc


def pole_on_left(track: Track) -> bool:
    """Pole side (track spec 7): the track's `pole position side`, else the inside of the first
    curve."""
    side = str(track.grid.get("pole position side", "")).strip().lower()
    if side in ("left", "right"):
        return side == "left"
    kinds = track.pieces[:, COL["kind"]]
    curved = kinds[kinds != 0]
    return bool(curved.size == 0 or curved[0] == LEFT)


QUICKRACE_GRID = {"rows": 2.0, "distance to start": 25.0, "distance between columns": 20.0,
                  "offset within a column": 10.0, "initial height": 0.2}
"""TORCS's quickrace `Starting Grid` (config/raceman/quickrace.xml), overridden by the track's."""


def grid_positions(track: Track, n_cars: int, race_grid: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(s, n) of n_cars on the starting grid (track spec 7), m: the race's grid values (default
    quickrace's; `race_grid` overrides them, e.g. from a raceman file), then the track's own."""
    g = dict(QUICKRACE_GRID)
    if race_grid:
        g.update({k: v for k, v in race_grid.items() if k in QUICKRACE_GRID})
    g.update({k: v for k, v in track.grid.items() if k in QUICKRACE_GRID})
    rows = max(int(g["rows"]), 1)
    i = np.arange(n_cars)
    s = track.length - (g["distance to start"] + (i // rows) * g["distance between columns"]
                        + (i % rows) * g["offset within a column"])
    w = track.width
    a, b = (w, -w) if pole_on_left(track) else (0.0, w)
    to_right = a + b * ((i % rows) + 1) / (rows + 1)
    return np.mod(s, track.length), to_right - w / 2.0


def angle_wrap(a):
    """Wrap angles to [-pi, pi)."""
    return (np.asarray(a) + math.pi) % (2 * math.pi) - math.pi
