"""Column layouts of the arrays the physics kernels share with `World`.

Every array has the car (or piece) axis first. Names are column indices; the tuples list the
columns in order so that `World` can document and expose them. Units are SI (m, s, rad, kg, N).
"""

from __future__ import annotations

from madsim.tracks.kernels import (GEO_A0, GEO_ARC, GEO_CA0, GEO_COLUMNS, GEO_CX, GEO_CY, GEO_KIND,
                                   GEO_LEN, GEO_R, GEO_S0, GEO_SA0, GEO_X0, GEO_Y0, N_GEO)


def _enum(names: str) -> tuple[str, ...]:
    return tuple(names.split())


# --- per-car state, `World.state` (N, len(STATE_COLUMNS)) float64, Fortran order ---------------
# Fortran order keeps every column contiguous, so a column is a plain (N,) array that the contact
# solver can modify in place.
STATE_COLUMNS = _enum(
    "x y z yaw vx_g vy_g yaw_rate vx vy ax ay "   # pose, global velocity, body velocity, body specific force
    "spin_fr spin_fl spin_rr spin_rl engine_speed gear shift_timer steer_angle fuel damage "
    "s n piece laps back_crossings lap_start_time cur_lap_time last_lap_time best_lap_time "
    "dist_raced time "
    "fz_fr fz_fl fz_rr fz_rl fric_fr fric_fl fric_rr fric_rl roll_fr roll_fl roll_rr roll_rl "
    "grad_x grad_y track_heading road_z drag_factor "
    "spin_raw_fr spin_raw_fl spin_raw_rr spin_raw_rl ft_raw_fr ft_raw_fl ft_raw_rr ft_raw_rl "
    "fn_raw_fr fn_raw_fl fn_raw_rr fn_raw_rl "
    "vz roll pitch roll_rate pitch_rate susp_fr susp_fl susp_rr susp_rl "
    "wheel_vz_fr wheel_vz_fl wheel_vz_rr wheel_vz_rl ride_fr ride_fl ride_rr ride_rl"
)
STATE_DOC = {
    "x": "CG x, global frame, m", "y": "CG y, m",
    "z": "CG height (global), integrated with the body's heave (docs/physics.md, suspension), m",
    "yaw": "heading of the body x axis, rad in [-pi, pi)",
    "vx_g": "global velocity x, m/s", "vy_g": "global velocity y, m/s",
    "yaw_rate": "rad/s, |r| <= 9", "vx": "body-frame longitudinal velocity, m/s",
    "vy": "body-frame lateral velocity (left +), m/s",
    "ax": "body-frame longitudinal specific force of tyres + aero + rolling (no gravity), m/s^2",
    "ay": "body-frame lateral specific force (no gravity), m/s^2",
    "spin_fr": "wheel spin front right, rad/s (each wheel its own, through its axle's differential)",
    "spin_fl": "rad/s", "spin_rr": "rad/s", "spin_rl": "rad/s",
    "engine_speed": "rad/s (SCR rpm sensor = this x 10)",
    "gear": "engaged gear, -1 reverse, 0 neutral, 1..top", "shift_timer": "s left of the shift-time torque cut",
    "steer_angle": "actual front steering angle after the rate limit, rad (left +)",
    "fuel": "kg", "damage": "TORCS damage points",
    "s": "distance from the start line along the centre line (distFromStart), m in [0, L)",
    "n": "signed lateral offset from the centre line (toMiddle), m, left +",
    "piece": "index of the track piece the CG is on", "laps": "completed start-line crossings",
    "back_crossings": "backward crossings not yet consumed by a forward one",
    "lap_start_time": "time of the last counted crossing, s", "cur_lap_time": "s",
    "last_lap_time": "s (0 before the first complete lap)", "best_lap_time": "s (0: none yet)",
    "dist_raced": "(laps - (back_crossings + 1)) * L + s, m", "time": "simulated time since reset, s",
    "fz_fr": "wheel load front right, N", "fz_fl": "N", "fz_rr": "N", "fz_rl": "N",
    "fric_fr": "surface friction under the wheel", "fric_fl": "", "fric_rr": "", "fric_rl": "",
    "roll_fr": "surface rolling resistance under the wheel", "roll_fl": "", "roll_rr": "", "roll_rl": "",
    "grad_x": "road surface gradient dz/dX at the CG (global)", "grad_y": "dz/dY",
    "track_heading": "centre-line tangent heading at the CG's projection, rad",
    "road_z": "road height under the CG, m",
    "drag_factor": "slipstream factor on the body drag's airspeed (1: free air), set once per tick",
    "spin_raw_fr": "last raw (before TORCS's two-sample average) wheel spin front right, rad/s",
    "spin_raw_fl": "rad/s", "spin_raw_rr": "rad/s", "spin_raw_rl": "rad/s",
    "ft_raw_fr": "last raw longitudinal tyre force front right (wheel frame, before the average), N",
    "ft_raw_fl": "N", "ft_raw_rr": "N", "ft_raw_rl": "N",
    "fn_raw_fr": "last raw lateral tyre force front right (wheel frame, before the average), N",
    "fn_raw_fl": "N", "fn_raw_rr": "N", "fn_raw_rl": "N",
    "vz": "CG vertical velocity (global), m/s", "roll": "body roll angle, rad (+: left side up)",
    "pitch": "body pitch angle, rad (+: nose down)", "roll_rate": "rad/s", "pitch_rate": "rad/s",
    "susp_fr": "suspension travel front right: ride height x bellcrank, between the packers and the "
               "suspension course (TORCS's susp.x), m",
    "susp_fl": "m", "susp_rr": "m", "susp_rl": "m",
    "wheel_vz_fr": "wheel's vertical velocity relative to the body (TORCS's rel_vel, + compressing), m/s",
    "wheel_vz_fl": "m/s", "wheel_vz_rr": "m/s", "wheel_vz_rl": "m/s",
    "ride_fr": "ride height front right: body reference above the road under the wheel (unclamped), m",
    "ride_fl": "m", "ride_rr": "m", "ride_rl": "m",
}
S = {name: i for i, name in enumerate(STATE_COLUMNS)}
(S_X, S_Y, S_Z, S_YAW, S_VXG, S_VYG, S_R, S_VX, S_VY, S_AX, S_AY,
 S_SPIN, _S_SPIN1, _S_SPIN2, _S_SPIN3, S_WE, S_GEAR, S_SHIFT, S_STEER, S_FUEL, S_DAMAGE,
 S_S, S_N, S_PIECE, S_LAPS, S_BACK, S_LAPSTART, S_CURLAP, S_LASTLAP, S_BESTLAP,
 S_DIST, S_TIME) = range(32)
# S_SPIN: 4 wheel spins follow in wheel order
S_FZ = S["fz_fr"]          # 4 wheel loads follow in wheel order
S_FRIC = S["fric_fr"]      # 4 frictions
S_ROLL = S["roll_fr"]      # 4 rolling resistances
S_GX, S_GY, S_THEAD, S_ROADZ = S["grad_x"], S["grad_y"], S["track_heading"], S["road_z"]
S_DRAGK = S["drag_factor"]
S_SPINRAW = S["spin_raw_fr"]   # 4 last raw spins (TORCS's prespinVel), wheel order
S_FTRAW = S["ft_raw_fr"]       # 4 last raw longitudinal tyre forces (TORCS's preFt)
S_FNRAW = S["fn_raw_fr"]       # 4 last raw lateral tyre forces (TORCS's preFn)
S_VZ, S_ROLLA, S_PITCH, S_ROLLR, S_PITCHR = (S[n] for n in ("vz", "roll", "pitch", "roll_rate", "pitch_rate"))
S_SUSP = S["susp_fr"]          # 4 suspension travels (bellcrank-scaled), wheel order
S_WVZ = S["wheel_vz_fr"]       # 4 wheel vertical velocities relative to the body
S_RIDE = S["ride_fr"]          # 4 ride heights (unclamped), wheel order
N_STATE = len(STATE_COLUMNS)

# --- per-car constants (N, N_CAR) float64, built from CarSpec by `carparams.car_table` ---------
MAX_GEAR_SLOTS = 10   # gear + 1 for gear in -1..8
CAR_COLUMNS = _enum(
    "mass_dry izz a b wheelbase cg_h track_f track_r w_front w_front_right w_rear_right "
    "skid mf_bf mf_cf mf_ef mf_br mf_cr mf_er "
    "tickover limiter revs_maxi eng_inertia eng_brake fuel_cons n_curve "
    "top_gear shift_time drive_front_share driven_f driven_r i_free_f i_free_r "
    "viscous_max_share viscosity reaction_factor drag_coef "
    "steer_lock steer_speed brake_front brake_pmax "
    "scx2 clift_f clift_r "
    "half_length half_width reach"
)
C = {name: i for i, name in enumerate(CAR_COLUMNS)}
_n = len(CAR_COLUMNS)
# per-wheel blocks of 4 (wheel order FR, FL, RR, RL)
C_WY = _n             # wheel y relative to the CG, m
C_RAD = _n + 4        # tyre radius, m
C_KMU = _n + 8        # mu x camber factor
C_OPLOAD = _n + 12    # operating load, N
C_LFMIN = _n + 16
C_LFMAX = _n + 20
C_LFK = _n + 24
C_W0 = _n + 28        # static load (dry mass), N
C_RIDE0 = _n + 32     # static ride height, m
C_KB = _n + 36        # brake torque per Pa, N m/Pa
C_RATIO = _n + 40                       # MAX_GEAR_SLOTS overall ratios, slot = gear + 1
C_IDRIVE_F = C_RATIO + MAX_GEAR_SLOTS   # driven front-axle inertia per slot, kg m^2
C_IDRIVE_R = C_IDRIVE_F + MAX_GEAR_SLOTS
# per-axle differential blocks of 2 (front, rear; spec 4.10)
C_DKIND = C_IDRIVE_R + MAX_GEAR_SLOTS   # DIFF_NONE .. DIFF_SPOOL below; non-driven axles: DIFF_NONE
C_DSLIP = C_DKIND + 2     # limited slip: max slip bias (speed ratio |w0 - w1| / (|w0| + |w1|))
C_DLOCK = C_DSLIP + 2     # limited slip: locking input torque, N m (spool above it)
C_DLOCKB = C_DLOCK + 2    # limited slip: locking brake input torque, N m (spool below minus it)
C_DMIN = C_DLOCKB + 2     # viscous coupler: min torque bias of the right wheel
C_DSPAN = C_DMIN + 2      # viscous coupler: max - min torque bias
C_DVISC = C_DSPAN + 2     # viscous coupler: viscosity factor, 1/(rad/s)
C_TOE = C_DVISC + 2       # static toe per wheel (FR, FL, RR, RL), rad, left + (spec 4.5)
# suspension per wheel (blocks of 4; TORCS's susp.cpp / wheel.cpp, docs/physics.md)
C_SPRING = C_TOE + 4      # spring rate k, N/m (at the spring: x bellcrank^2 at the wheel)
C_BELL = C_SPRING + 4     # bellcrank ratio
C_COURSE = C_BELL + 4     # suspension course: largest travel (bellcrank-scaled), m
C_PACK = C_COURSE + 4     # packers: smallest ride height, m
C_DBUMP1 = C_PACK + 4     # slow bump damping, N s/m
C_DBUMP2 = C_DBUMP1 + 4   # fast bump damping, N s/m
C_VBUMP = C_DBUMP2 + 4    # bump slow/fast threshold, m/s
C_DREB1 = C_VBUMP + 4     # slow rebound, N s/m
C_DREB2 = C_DREB1 + 4     # fast rebound, N s/m
C_VREB = C_DREB2 + 4      # rebound threshold, m/s
C_WMASS = C_VREB + 4      # wheel (unsprung) mass, kg
C_WX = C_WMASS + 4        # wheel x relative to the CG, m
# per axle (front, rear)
C_ARB = C_WX + 4          # anti-roll bar rate, N/m
C_RC = C_ARB + 2          # roll-centre height, m
# per wing (front, rear)
C_WGKX = C_RC + 2         # wing drag constant Kx = -1.23 area (x damage factor in the kernel), kg/m
C_WGKZ = C_WGKX + 2       # wing lift constant Kz = 4 Kx, kg/m
C_WGANG = C_WGKZ + 2      # wing angle, rad
C_WGX = C_WGANG + 2       # wing x relative to the CG, m
C_WGZ = C_WGX + 2         # wing z (the car file's), m
C_IXX = C_WGZ + 2         # roll inertia (dry mass), kg m^2
C_IYY = C_IXX + 1         # pitch inertia (dry mass), kg m^2
# sines and cosines of constant angles, formed once here instead of in every `advance_car` call
# (`kernel.car_derived`, called by `tables.car_table`: the kernel's own math.sin / math.cos)
C_WGSIN = C_IYY + 1       # sin, cos of each wing angle (front, rear)
C_WGCOS = C_WGSIN + 2
C_TOESIN = C_WGCOS + 2    # sin, cos of each wheel's static toe (FR, FL, RR, RL)
C_TOECOS = C_TOESIN + 4
# reciprocals of constants the sub-step divides by (`kernel.car_derived`: one division each,
# once, instead of one per sub-step)
C_RBELL = C_TOECOS + 4    # 1 / bellcrank ratio, per wheel
C_RIXX = C_RBELL + 4      # 1 / roll inertia, 1/(kg m^2)
C_RIYY = C_RIXX + 1       # 1 / pitch inertia, 1/(kg m^2)
C_RWB2 = C_RIYY + 1       # 1 / (front pair's x - rear pair's x), 1/m (`suspension.wheel_loads`)
C_RTR2 = C_RWB2 + 1       # 1 / (left pair's y - right pair's y), 1/m
C_DMGK = C_RTR2 + 1       # damage factor of the driver's skill (spec 4.12; 0: damage off)
C_FINISH = C_DMGK + 1     # start-line crossings at which the car has finished (race laps + 1, fewer
                          # once another car has finished; 0: never; -1: the race is over): no
                          # damage after them, TORCS's slow pace (`physics.finish`)
C_WTRACK = C_FINISH + 1   # the wheel track of the Ackermann angle, m (`kernel.wheel_track`)
C_W0B = C_WTRACK + 1      # static load / bellcrank ratio, N, per wheel (`kernel.car_derived`:
                          # the spring's preload in `suspension.wheel_loads`, divided once)
N_CAR = C_W0B + 4
DIFF_KINDS = ("NONE", "FREE", "LIMITED SLIP", "VISCOUS COUPLER", "SPOOL")
DIFF_NONE, DIFF_FREE, DIFF_LSD, DIFF_VISCOUS, DIFF_SPOOL = range(5)
(C_MASS, C_IZZ, C_A, C_B, C_L, C_H, C_TF, C_TR, C_WF, C_WFR, C_WRR,
 C_SKID, C_BF, C_CF, C_EF, C_BR, C_CR, C_ER,
 C_TICK, C_LIMIT, C_MAXI, C_IENG, C_EBRAKE, C_FUELCONS, C_NCURVE,
 C_TOP, C_SHIFT, C_FSHARE, C_DRIVEN_F, C_DRIVEN_R, C_IFREE_F, C_IFREE_R,
 C_VISC_MAX, C_VISC, C_REACT, C_CD,
 C_LOCK, C_STEERSPD, C_BRAKE_FRONT, C_PMAX,
 C_SCX2, C_CLIFT_F, C_CLIFT_R,
 C_HALF_LEN, C_HALF_WID, C_REACH) = range(_n)

# --- per-piece track table (P, N_PIECE) float64, built by `tables.piece_table` ----------------
# It starts with the track's own piece geometry (`tracks.kernels.GEO_COLUMNS`, Track.geo), so
# the one piece walk (`tracks.kernels.locate`) reads either table.
PIECE_COLUMNS = GEO_COLUMNS + _enum(
    "zr0 zr1 bank0 bank1 tanbank0 surface "
    "border_w_r border_w_l border_surf_r border_surf_l side_w0_r side_w1_r side_w0_l side_w1_l "
    "side_surf_r side_surf_l barrier_surf_r barrier_surf_l flag same_surface inv_length curvature "
    "curb_r curb_l curb_rise_r curb_rise_l"
)
P = {name: i for i, name in enumerate(PIECE_COLUMNS)}
(P_KIND, P_S0, P_LEN, P_R, P_ARC, P_X0, P_Y0, P_A0, P_CX, P_CY, P_CA0, P_SA0) = (
    GEO_KIND, GEO_S0, GEO_LEN, GEO_R, GEO_ARC, GEO_X0, GEO_Y0, GEO_A0, GEO_CX, GEO_CY, GEO_CA0, GEO_SA0)
(P_ZR0, P_ZR1, P_B0, P_B1, P_TB0, P_SURF,
 P_BW_R, P_BW_L, P_BSURF_R, P_BSURF_L, P_SW0_R, P_SW1_R, P_SW0_L, P_SW1_L,
 P_SSURF_R, P_SSURF_L, P_WSURF_R, P_WSURF_L, P_FLAG, P_SAMESURF, P_INVLEN, P_CURV,
 P_CURB_R, P_CURB_L, P_CURBK_R, P_CURBK_L) = range(N_GEO, len(PIECE_COLUMNS))
"""P_CURB_*: 1 where that side's border is a curb; P_CURBK_*: the curb's rise, m per m of depth
into it from the road's edge (TORCS's atan2(height, width), `suspension.relief`)."""
N_PIECE = len(PIECE_COLUMNS)
FLAG_LAST, FLAG_START = 1.0, 2.0

# track scalars (4,): length, width, right side continues the cross slope, left side does
T_LENGTH, T_WIDTH, T_TANGENT_R, T_TANGENT_L = range(4)

# controls (N, 5)
CONTROL_COLUMNS = ("steer", "accel", "brake", "gear", "clutch")
U_STEER, U_ACCEL, U_BRAKE, U_GEAR, U_CLUTCH = range(5)
