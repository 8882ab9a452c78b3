"""The compiled per-car vehicle model (spec/torcs-car-format.md section 5) and its track lookups.

Everything here is plain loops over cars on the arrays described in `madsim.physics.layout`
(car axis first), compiled with `numba.njit(cache=True)`; with NUMBA_DISABLE_JIT=1 the same code
runs as ordinary Python for debugging. There is no second (numpy) implementation.

One sub-step of dt = 0.002 s, in TORCS's order (spec 4.11): steering -> gearbox -> engine torque
-> aero -> suspensions and wheel loads -> tyre forces -> wheel spin -> engine speed -> body
forces -> velocities -> positions -> heave, roll and pitch -> track position, surfaces and laps.
A car's planar state is read into locals once per call and written back at the end, so the
sub-step loop runs in registers; the vertical state (suspensions, heave, roll, pitch: TORCS's
simuv2, docs/physics.md) is read and written in `st` by its own functions. Each wheel has its own
slip (from its own contact-point velocity and, at the front, its own Ackermann angle) and its
own spin; the two spins of an axle step together through the axle's differential
(`_axle_spin`, spec 4.10). The four tyres (load sensitivity, slip, magic formula) are one loop
over four lanes on the stack, free of branches and libm calls (`physics.elementary`'s atan,
sincos and exp, within 2 ulp), which LLVM turns into SIMD code; IEEE arithmetic without
fastmath, so lanes, batch sizes and NUMBA_DISABLE_JIT all give the same bits.

Low-speed stability (spec 5.2 step 6), documented choice: both slip denominators are regularised,
`sx = (vt - w R) / max(|vt|, V_REG)` and `sy = v_lat / max(|v|, V_REG)` with V_REG = 2 m/s
(TORCS's definitions above that speed), and the wheel spin takes a linearised implicit step,
`w += dt (T - R (Ft - dFt/d(wR) dvt)) / (I + dt R^2 dFt/d(wR))` (slope clamped at >= 0, dvt the
wheel-speed change predicted from the last step's body acceleration), which is stable for any
spin stiffness and leaves steady states unchanged (for the two wheels of an axle, coupled by
their differential, a 2 x 2 linear step), at or below SPIN_AVG_SPEED = 3 m/s of car speed.
Above it the kernel does what TORCS 1.3.7's wheel.cpp does: an explicit spin step, then each
wheel's spin and each tyre force (Ft, Fn, in N) is replaced by the mean of its new raw value
and the last raw one (RELAXATION2(x, prex, 50)). The last raw spins and forces are state
columns, tracked at every speed, so the switch is smooth. A steady torque then spins a wheel
up as if it were 1.5 x heavier (u(n+1) = (u(n) + u(n-1)) / 2 + dw grows by 2 dw / 3 a step).
Below 3 m/s the explicit step with the regularised slip would chatter (docs/physics.md).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from madsim.physics import elementary as el
from madsim.physics.layout import (  # noqa: I001 - column indices, see layout.py
    C_A, C_B, C_BF, C_BR, C_BRAKE_FRONT, C_CD, C_CF, C_CLIFT_F, C_CLIFT_R, C_CR, C_DRIVEN_F,
    C_DRIVEN_R, C_EBRAKE, C_EF, C_ER, C_FSHARE, C_FUELCONS, C_H, C_IDRIVE_F, C_IDRIVE_R, C_IENG,
    C_IFREE_F, C_IFREE_R, C_IZZ, C_KB, C_KMU, C_L, C_LFK, C_LFMAX, C_LFMIN, C_LIMIT, C_LOCK, C_MASS,
    C_MAXI, C_NCURVE, C_OPLOAD, C_PMAX, C_RAD, C_RATIO, C_RC, C_REACH, C_REACT, C_SCX2, C_SHIFT,
    C_SKID, C_STEERSPD, C_TF, C_TR, C_TOE, C_TICK, C_TOP, C_VISC, C_VISC_MAX, C_WGANG, C_WGKX, C_WGKZ,
    C_WGCOS, C_WGSIN, C_TOECOS, C_TOESIN, C_BELL, C_IXX, C_IYY, C_RBELL, C_RIXX, C_RIYY, C_RTR2,
    C_RWB2, C_W0, C_W0B, C_WTRACK,
    C_WGX, C_WGZ, C_WX, C_WY, C_DKIND, C_DSLIP, C_DLOCK, C_DLOCKB, C_DMIN, C_DSPAN, C_DVISC,
    DIFF_FREE, DIFF_LSD, DIFF_SPOOL, DIFF_VISCOUS, FLAG_LAST, FLAG_START, P_A0, P_B0, P_B1,
    P_CURV, P_FLAG, P_INVLEN, P_LEN, P_S0, P_SAMESURF, P_SURF, P_TB0,
    P_ZR0, P_ZR1, S_AX, S_AY, S_BACK, S_CURLAP, S_DAMAGE, S_DIST, S_DRAGK, S_FRIC,
    S_FUEL, S_FZ, S_GEAR, S_GX, S_GY, S_LAPS, S_LAPSTART, S_N, S_PIECE, S_R, S_RIDE,
    S_ROADZ, S_ROLL, S_PITCH, S_S, S_SHIFT, S_STEER, S_THEAD, S_TIME, S_VX, S_VXG, S_VY, S_VYG,
    S_VZ, S_WE, S_SPIN, S_X, S_Y, S_YAW, S_SPINRAW, S_FTRAW, S_FNRAW, T_LENGTH, T_TANGENT_L,
    T_TANGENT_R, T_WIDTH, U_ACCEL, U_BRAKE, U_CLUTCH, U_GEAR, U_STEER,
)
from madsim.physics.finish import cross_forward, finish_rule, finished, takes_damage
from madsim.physics.suspension import G, body_vertical, ground_contact, relief, surface_index, wheel_at, wheel_loads
from madsim.tracks.kernels import locate as _locate  # the one piece walk (track spec 10.1)
from madsim.tracks.kernels import piece_local as _piece_local
from madsim.tracks.kernels import wrap_angle as _wrap

V_REG = 2.0          # m/s, slip denominator floor (see module docstring)
SLIP_MAX = 1.5       # TORCS's slip clamp
YAW_RATE_MAX = 9.0   # rad/s, TORCS's cap
SPIN_AVG_SPEED = 3.0
"""m/s: above this car speed the wheel spins take TORCS's explicit step and the spins and tyre
forces its two-sample averages (module docstring); at or below it, the implicit step."""
PARALLEL_MIN_CARS = 64   # below this many cars the serial loop is faster than threads

_JIT = {"cache": True, "error_model": "numpy"}
FINISH_ACCEL = 0.2          # a finished car's accel command at most (simuv2 ctrlCheck)
FINISH_BRAKE = 0.05         # and its brake command at least, above
FINISH_BRAKE_ABOVE = 30.0   # this forward speed, m/s
NO_REFCOUNT = {"_nrt": False}
"""For kernels that allocate nothing: without numba's runtime (NRT) no array reference counts
are kept. numba keeps them with atomic increments and decrements at every array alias, call
and inlined body; in the sub-step loop they cost ~20 % of `advance_car` (perf: `lock inc` in
NRT_incref / NRT_decref). Arrays passed in stay owned by the caller; the floats are unchanged."""
COUNT_LAPS = np.bool_(True)
"""`track_update`'s count_laps from `advance_car`: a typed bool, not the literal True, so that
`track_update` compiles one signature for both of its callers."""


@numba.njit(inline="always", **_JIT)
def _engine_curve(curve_w, curve_t, i, n, we, j):
    """Full-throttle torque at `we` (linear between points, constant beyond the ends), searching
    from segment j (the previous one: engine speed changes little per step). Returns (T, j)."""
    if we <= curve_w[i, 0]:
        return curve_t[i, 0], j
    if we >= curve_w[i, n - 1]:
        return curve_t[i, n - 1], j
    j = min(max(j, 1), n - 1)
    while curve_w[i, j] < we:
        j += 1
    while curve_w[i, j - 1] > we:
        j -= 1
    u = (we - curve_w[i, j - 1]) / (curve_w[i, j] - curve_w[i, j - 1])
    return curve_t[i, j - 1] + u * (curve_t[i, j] - curve_t[i, j - 1]), j


@numba.njit(**_JIT)
def engine_torque(cp, curve_w, curve_t, i, we, throttle):
    """Engine torque (N m) of car i at engine speed `we` (rad/s) and throttle in [0, 1] (spec 4.4):
    full-throttle curve times the throttle map with engine braking; zero above the rev limiter."""
    if we > cp[i, C_LIMIT]:
        return 0.0
    tmax, _ = _engine_curve(curve_w, curve_t, i, int(cp[i, C_NCURVE]), we, 1)
    tick = cp[i, C_TICK]
    k = cp[i, C_EBRAKE] * (we - tick) / (cp[i, C_MAXI] - tick)
    return tmax * (throttle * (1.0 + k) - k)


@numba.njit(inline="always", **_JIT)
def _wrap_step(a):
    """`_wrap` (wrap_angle) of a yaw that moved by one sub-step from [-pi, pi): the same bits,
    without its division and floor where a stayed inside (there (a + pi) / 2 pi is in [0, 1),
    so wrap_angle returns a - 2 pi * 0 = a)."""
    if -math.pi <= a < 3.14159265:
        return a
    return _wrap(a)


@numba.njit(inline="always", **_JIT)
def _shape_parts(s, b, c, e, skid):
    """`tyre_shape` with its slope as a fraction: (F, num, den) with dF/ds = num / den, den >= 1,
    so that a caller can fold the division into one it makes anyway (`_tyre`). The slope of
    sin(C atan g), g = B s (1-E) + E atan(B s), is cos(C atan g) C g' / (1 + g^2) with
    g' = B (1-E) + E B / (1 + u^2), u = B s: over the common denominator (1 + g^2)(1 + u^2)."""
    st = min(s, SLIP_MAX)
    u = b * st
    g = u * (1.0 - e) + e * el.atan(u)
    phi = c * el.atan(g)
    sh, ch = el.sincos(phi)
    grow = 1.0 + skid * st
    u2 = 1.0 + u * u
    den = (1.0 + g * g) * u2
    num = ch * c * (b * (1.0 - e) * u2 + e * b) * grow + sh * skid * den
    return sh * grow, (num if s <= SLIP_MAX else 0.0), den


@numba.njit(inline="always", **_JIT)
def tyre_shape(s, b, c, e, skid):
    """Magic-formula force factor F(s) of spec 4.9 for slip magnitude s >= 0 (the slip clamp at
    1.5, the TORCS shape sin(C atan(B s (1-E) + E atan(B s))) times the skid term (1 + skid s)),
    and its slope dF/ds (0 beyond the clamp). atan, sin and cos are `elementary`'s (within 2 ulp)
    and there is no branch, so a loop over wheels runs in SIMD lanes."""
    f, num, den = _shape_parts(s, b, c, e, skid)
    return f, num / den


@numba.njit(inline="always", **_JIT)
def wheel_track(cp, i):
    """The wheel track car i's Ackermann angle uses, m: TORCS 1.3.7's `wheeltrack` (SimCarConfig
    sums all four wheels' y: the mean of the front and rear axles' tracks), not the front
    axle's own (docs/physics.md, "Drive line"); `car_derived` puts it in the car table."""
    return cp[i, C_WTRACK]


@numba.njit(inline="always", **_JIT)
def front_wheel_angles(d, wb, track):
    """(right, left) front wheel steer angles, rad, for the steer angle d (rad, left +), wheelbase
    wb and wheel track (m, `wheel_track`): the inner wheel turns by d, the outer by
    atan(wb tan|d| / (wb + track tan|d|)) with d's sign (TORCS 1.3.7's SimSteerUpdate, whose
    negative wheeltrack makes its `wheelbase - tan x wheeltrack` this sum; spec 4.2)."""
    t_d = math.tan(abs(d))
    outer = math.copysign(math.atan(wb * t_d / (wb + track * t_d)), d)
    return (outer, d) if d > 0.0 else (d, outer)


@numba.njit(inline="always", **_JIT)
def _tyre(vwx, vwy, cd, sd, spin_speed, b, c, e, skid):
    """Isotropic combined-slip tyre of one axle per unit of load scale K = Fz mu lf friction:
    (ft, fn, dft) = force along and across the wheel (wheel frame) and d(ft)/d(w R) >= 0 for
    the implicit spin step. Selects, no branches (see `tyre_shape`). Two vector divisions
    besides the shape's two atan: 1 / (dx dv) gives both slip denominators' reciprocals and
    1 / (s den) both 1 / s and the slope's 1 / den (a division costs ~8 times a product in
    the lanes: benchmarks/RESULTS.md, "The car sub-step, cuts that move bits")."""
    vt = vwx * cd + vwy * sd
    vl = vwy * cd - vwx * sd
    dx = max(abs(vt), V_REG)
    dv = max(math.sqrt(vwx * vwx + vwy * vwy), V_REG)
    inv = 1.0 / (dx * dv)
    inv_dx = dv * inv
    sx = (vt - spin_speed) * inv_dx
    sy = vl * (dx * inv)
    s = math.sqrt(sx * sx + sy * sy)
    f, num, den = _shape_parts(s, b, c, e, skid)
    slipping = s > 1e-6
    s1 = s if slipping else 1.0
    inv_sd = 1.0 / (s1 * den)
    inv_s = den * inv_sd
    fs = f * inv_s
    if slipping:
        return -fs * sx, -fs * sy, ((max(num, 0.0) * (s1 * inv_sd) * sx * sx + fs * sy * sy)
                                    * (inv_s * inv_s) * inv_dx)
    return 0.0, 0.0, b * c * inv_dx


@numba.njit(**_JIT)
def _wheel_surfaces(st, i, cp, pt, surf, p, q, n, cpsi, spsi, half):
    """Friction and rolling resistance under each wheel of car i (CG at q, n on piece p)."""
    for k in range(4):
        xw = cp[i, C_A] if k < 2 else -cp[i, C_B]
        yw = cp[i, C_WY + k]
        da, dn = wheel_at(pt, p, n, xw * cpsi - yw * spsi, xw * spsi + yw * cpsi)
        j = surface_index(pt, p, q + da, n + dn, half)
        st[i, S_FRIC + k] = surf[j, 0]
        st[i, S_ROLL + k] = surf[j, 1]


@numba.njit(inline="always", **_JIT)
def rolling_drag(roll, v, r, m, izz, wb, dt):
    """The rolling resistance's drag on the body. roll: the summed rolling resistance, N; v: the
    speed, m/s; r: the yaw rate, rad/s; m: mass, kg; izz: yaw inertia, kg m^2; wb: wheelbase,
    m; dt: step, s. Returns (rv, rm): the force is -rv times the
    velocity (rv in N s/m), the yaw moment -rm, N m (docs/physics.md, "Rolling resistance").
    rv is roll / v unless rv dt / m > v, then v m / dt: TORCS 1.3.7's clamp as SimCarUpdate has
    it (read in Debian's simuv2.so), so a crawling car loses v^2 of its speed a step, not all of
    it. rm is roll wb / 2 against the yaw unless that moment over izz exceeds |r| (rad/s^2
    against rad/s, as TORCS compares them), then r izz: TORCS 1.3.7's clamp (SimCarUpdate)."""
    rv = 0.0
    if v > 1e-5:
        rv = roll / v
        vm = v * m
        if rv * dt > vm:                # rv dt / m > v, without dividing (m > 0)
            rv = vm / dt
    rm = roll * wb * 0.5
    if rm > abs(r) * izz:
        rm = r * izz
    else:
        rm = math.copysign(rm, r)
    return rv, rm


@numba.njit(**_JIT, _nrt=False)
def track_update(st, i, cp, pt, surf, tsc, x, y, cy, sy, count_laps):
    """Locate car i at (x, y) with heading (cy, sy) = (cos, sin) yaw, walking from its stored
    piece, and store what a sub-step reads: s, n, piece, the surface under each wheel and (if
    count_laps) the lap bookkeeping of track spec 10.4. What only observers read (the track
    heading, the road's height and gradient at the CG, the lap time and distance raced) is
    `track_observed`'s, once at the end of a call. Assumes the car moved at most a few pieces
    since the last call. Returns (cos, sin) of the heading relative to the track, yaw - track
    heading (from cy, sy and the tangent of the piece walk: no libm call; the suspension's next
    wheel loads use them), then the walk's piece p, distance along it q (m), offset n (m) and
    tangent (ch, sh) for `track_observed`."""
    old = int(st[i, S_PIECE])
    p, q, n, ch, sh = _locate(pt, old, x, y)
    length, w = tsc[T_LENGTH], tsc[T_WIDTH]
    s = pt[p, P_S0] + q
    if s >= length:
        s -= length
    elif s < 0.0:
        s += length
    st[i, S_S] = s
    st[i, S_N] = n
    st[i, S_PIECE] = p

    # surface under each wheel, from the CG's local frame; fast path when every wheel is on a
    # road whose material is the same on this piece and its neighbours
    cpsi = cy * ch + sy * sh     # cos(yaw - track heading)
    spsi = sy * ch - cy * sh
    half = 0.5 * w
    reach = cp[i, C_REACH]
    if pt[p, P_SAMESURF] > 0.0 and abs(n) + reach <= half and reach <= pt[p, P_LEN]:
        j = int(pt[p, P_SURF])
        for k in range(4):
            st[i, S_FRIC + k] = surf[j, 0]
            st[i, S_ROLL + k] = surf[j, 1]
    else:
        _wheel_surfaces(st, i, cp, pt, surf, p, q, n, cpsi, spsi, half)

    if count_laps and p != old:
        f_old, f_new = pt[old, P_FLAG], pt[p, P_FLAG]
        if f_old == FLAG_LAST and f_new == FLAG_START:
            # the first lap's timer runs from the race start: crossing the line from the
            # grid does not restart it (scr-protocol.md section 5, curLapTime)
            cross_forward(st, cp, i)
        elif f_old == FLAG_START and f_new == FLAG_LAST:
            st[i, S_BACK] += 1.0
    return cpsi, spsi, p, q, n, ch, sh


@numba.njit(**_JIT, _nrt=False)
def track_observed(st, i, pt, surf, tsc, p, q, n, ch, sh):
    """Store what of car i's track position only observers read (the sensors, `settle`, race
    positions), from the last `track_update`'s walk (p, q, n, ch, sh): the track heading, the
    road's height (with its relief: the z sensor's road, TORCS's RtTrackHeightL) and gradient at
    the CG (track spec 5.4: linear right edge + banking), the lap time and the distance raced.
    No sub-step reads them, so `advance_car` stores them once after its sub-steps."""
    length, w = tsc[T_LENGTH], tsc[T_WIDTH]
    inv_len, curv = pt[p, P_INVLEN], pt[p, P_CURV]
    st[i, S_THEAD] = _wrap(pt[p, P_A0] + q * curv)
    u = min(max(q * inv_len, 0.0), 1.0)
    b0, b1 = pt[p, P_B0], pt[p, P_B1]
    tb = pt[p, P_TB0] if b0 == b1 else math.tan(b0 + u * (b1 - b0))
    yr = n + 0.5 * w
    lo = -1e30 if tsc[T_TANGENT_R] > 0.0 else 0.0
    hi = 1e30 if tsc[T_TANGENT_L] > 0.0 else w
    yc = min(max(yr, lo), hi)
    zr0 = pt[p, P_ZR0]
    z = zr0 + u * (pt[p, P_ZR1] - zr0) + yc * tb
    dz_dq = ((pt[p, P_ZR1] - zr0) + yc * (b1 - b0) * (1.0 + tb * tb)) * inv_len
    if curv != 0.0:     # metres along the track at offset n on a curve
        dz_dq /= max(1.0 - curv * n, 0.1)
    dz_dn = tb if lo <= yr <= hi else 0.0
    st[i, S_GX] = dz_dq * ch - dz_dn * sh
    st[i, S_GY] = dz_dq * sh + dz_dn * ch
    st[i, S_ROADZ] = z + relief(pt, surf, tsc, p, q, n, True)
    st[i, S_CURLAP] = st[i, S_TIME] - st[i, S_LAPSTART]
    st[i, S_DIST] = (st[i, S_LAPS] - (st[i, S_BACK] + 1.0)) * length + st[i, S_S]


@numba.njit(**_JIT)
def add_damage(st, cp, damage):
    """Add the contact solver's damage points (N,) to the cars of st (rows as cp and damage)
    that have not finished their race (`finish.takes_damage`, TORCS's finish rule): the
    one place World and WorldBatch add wall, pit-wall and car-car damage."""
    for i in range(st.shape[0]):
        if damage[i] != 0.0 and takes_damage(st, cp, i):
            st[i, S_DAMAGE] += damage[i]


@numba.njit(**_JIT)
def refresh(st, cp, pt, surf, tsc, count_laps):
    """Re-derive yaw wrap, body velocities and the track position of every car after its pose
    or velocity was set from outside (reset, contact corrections)."""
    for i in range(st.shape[0]):
        yaw = _wrap(st[i, S_YAW])
        st[i, S_YAW] = yaw
        cy, sy = math.cos(yaw), math.sin(yaw)
        st[i, S_VX] = st[i, S_VXG] * cy + st[i, S_VYG] * sy
        st[i, S_VY] = st[i, S_VYG] * cy - st[i, S_VXG] * sy
        _, _, p, q, n, ch, sh = track_update(st, i, cp, pt, surf, tsc, st[i, S_X], st[i, S_Y],
                                             cy, sy, count_laps)
        track_observed(st, i, pt, surf, tsc, p, q, n, ch, sh)


SLIP_MIN_SPEED = 10.0
"""m/s: both cars faster than this for a slipstream (TORCS)."""
SLIP_MAX_DYAW = 0.1396
"""rad: largest heading difference of two cars for a slipstream (TORCS: 8 degrees)."""


SLIP_CUT = 8.1
"""A wake acts up to SLIP_CUT x Cd x vx metres: beyond, its factor differs from 1 by < 1e-7."""
SLIP_CHORD = 0.25
"""Assumed lower bound of (distance between two cars) / (their distance along the track)."""
SLIP_ALL_PAIRS = 16
"""Up to this many cars every pair is checked; more are sorted along the track first."""


SLIP_COS_WAKE = math.cos(math.pi - 0.1745)
"""The other car is ahead (in its wake) when it lies within 10 deg of this car's direction of
travel: cos(angle between that direction and the line from the other car to this one) below
this (TORCS: |angle| > 2.9671 rad)."""
SLIP_COS_AHEAD = math.cos(0.1396)
"""The other car is just behind when it lies within 8 deg of the backward direction."""


@numba.njit(inline="always", **_JIT)
def _slip_pair(st, cp, i, j, x, y, yaw, hx, hy, vx, k):
    """Car i's slipstream factor k, lowered by car j if it qualifies; (hx, hy) = car i's unit
    direction of travel."""
    if st[j, S_VX] <= SLIP_MIN_SPEED or abs(_wrap(yaw - st[j, S_YAW])) >= SLIP_MAX_DYAW:
        return k
    dx, dy = x - st[j, S_X], y - st[j, S_Y]
    d = math.sqrt(dx * dx + dy * dy)
    c = (dx * hx + dy * hy) / d if d > 0.0 else 1.0
    if c < SLIP_COS_WAKE:               # the other car is ahead: in its wake
        k = min(k, 1.0 - math.exp(-2.0 * d / (cp[j, C_CD] * st[j, S_VX])))
    elif c > SLIP_COS_AHEAD:            # the other car is just behind: less eddy drag
        k = min(k, 1.0 - 0.15 * math.exp(-8.0 * d / (cp[i, C_CD] * vx)))
    return k


@numba.njit(**_JIT)
def tick_start(st, cp, a, b, length):
    """The rules between the cars a..b-1 of one race at a tick's start, from their state now:
    TORCS's finish (`finish.finish_rule`), then the slipstream (`slipstream`). Every door calls
    this (or `tick_start_few`) once at the start of each tick of a race of several cars."""
    finish_rule(st, cp, a, b)
    slipstream(st, cp, a, b, length)


@numba.njit(**_JIT, **NO_REFCOUNT)
def tick_start_few(st, cp, a, b):
    """`tick_start` for a few cars (up to SLIP_ALL_PAIRS: no sorting, no allocation, no
    reference counts: callable from a NO_REFCOUNT kernel)."""
    finish_rule(st, cp, a, b)
    slipstream_few(st, cp, a, b)


@numba.njit(**_JIT)
def slipstream(st, cp, a, b, length):
    """TORCS's slipstream (spec 4.6) for cars a..b-1 on a track of `length` m, from their poses
    now: the body drag of each is multiplied by drag_factor^2, the smallest over the other cars
    of 1 - exp(-2 d / (Cd_other vx_other)) when this car follows another within 10 deg of its
    direction of travel, or 1 - 0.15 exp(-8 d / (Cd vx)) when it leads one within 8 deg; both
    cars above 10 m/s, headings within 8 deg, d = distance between the CGs. Up to
    SLIP_ALL_PAIRS cars every pair is visited (`slipstream_few`); with more the others are
    visited in order of distance along the track, up to where no farther car could lower the
    factor, taking two cars' distance as at least SLIP_CHORD x their distance along the track
    (always so unless a car has spun round in a hairpin)."""
    n = b - a
    if n <= SLIP_ALL_PAIRS:
        slipstream_few(st, cp, a, b)
        return
    cdv_max = _slip_start(st, cp, a, b)
    if cdv_max == 0.0:
        return
    reach = SLIP_CUT * cdv_max / SLIP_CHORD
    order = np.argsort(st[a:b, S_S])
    s_sorted = st[a:b, S_S][order]
    for p in range(n):
        i = a + order[p]
        vx = st[i, S_VX]
        if vx <= SLIP_MIN_SPEED:
            continue
        x, y, yaw, hx, hy = _slip_heading(st, i)
        cdv = cp[i, C_CD] * vx
        k = 1.0
        for step in (1, -1):          # along the track both ways
            for m in range(1, n):
                q = (p + step * m) % n
                ds = (s_sorted[q] - s_sorted[p]) * step
                if ds < 0.0:
                    ds += length
                # no car this far or farther can lower k: stop (d >= SLIP_CHORD ds)
                dmin = SLIP_CHORD * ds
                if ds > reach or (k < 1.0 and k <= min(1.0 - math.exp(-2.0 * dmin / cdv_max),
                                                       1.0 - 0.15 * math.exp(-8.0 * dmin / cdv))):
                    break
                k = _slip_pair(st, cp, i, a + order[q], x, y, yaw, hx, hy, vx, k)
        st[i, S_DRAGK] = k


@numba.njit(inline="always", **_JIT)
def _slip_heading(st, i):
    """Car i's x, y (m), yaw (rad) and unit direction of travel (hx, hy)."""
    vg = math.sqrt(st[i, S_VXG] ** 2 + st[i, S_VYG] ** 2)
    return st[i, S_X], st[i, S_Y], st[i, S_YAW], st[i, S_VXG] / vg, st[i, S_VYG] / vg


@numba.njit(inline="always", **_JIT)
def _slip_start(st, cp, a, b):
    """Every drag factor of cars a..b-1 to 1; returns the largest Cd x vx of a car faster than
    SLIP_MIN_SPEED (0: none is, no slipstream)."""
    cdv_max = 0.0
    for i in range(a, b):
        st[i, S_DRAGK] = 1.0
        if st[i, S_VX] > SLIP_MIN_SPEED:
            cdv_max = max(cdv_max, cp[i, C_CD] * st[i, S_VX])
    return cdv_max


@numba.njit(**_JIT, **NO_REFCOUNT)
def slipstream_few(st, cp, a, b):
    """`slipstream` of cars a..b-1 over every pair (for a few cars: no sorting, no allocation,
    no reference counts: callable from a NO_REFCOUNT kernel)."""
    if _slip_start(st, cp, a, b) == 0.0 or b - a < 2:
        return
    for i in range(a, b):
        vx = st[i, S_VX]
        if vx <= SLIP_MIN_SPEED:
            continue
        x, y, yaw, hx, hy = _slip_heading(st, i)
        k = 1.0
        for j in range(a, b):
            if j != i:
                k = _slip_pair(st, cp, i, j, x, y, yaw, hx, hy, vx, k)
        st[i, S_DRAGK] = k


@numba.njit(inline="always", **_JIT)
def _brake_spin(w, dw):
    """Spin w after a brake's speed change dw >= 0: towards 0, never through it (spec 4.10)."""
    return max(w - dw, 0.0) if w > 0.0 else min(w + dw, 0.0)


@numba.njit(inline="always", **_JIT)
def _axle_spin(cp, i, j, drive, fb, w0, w1, t0, t1, s0, s1, i0, i1, b0, b1, dt):
    """New spins (rad/s) of axle j's right (w0) and left (w1) wheels after one step through the
    axle's differential (TORCS's rules, spec 4.10; its wheel-0 = right, wheel-1 = left).

    drive: torque into the differential, N m (0 on a non-driven axle, whose kind is NONE: two
    free wheels); fb: the part of the two tyre torques taken off the drive before the split
    (4WD: 1 / centre ratio, since the axle's input is the centre differential's net output, in
    which the axle's tyre torques come back divided by its ratio; 0 otherwise); t0, t1: each
    tyre's reaction torque at the old spin, N m; s0, s1 >= 0 its slope d t / d w, N m s (the
    step is implicit in the tyre torques: linearised, solved exactly for the two wheels'
    coupling); i0, i1: wheel inertias, kg m^2; b0, b1 >= 0: brake torques, N m.
    With d = drive - fb (t0 + t1): FREE: d / 2 each plus the spider torque (t1 - t0) / 2 (TORCS
    1.3.7's form); LIMITED SLIP: a spool while d is above the locking input torque or below
    minus the locking brake torque, else free, with the speed ratio |w0 - w1| / (|w0| + |w1|)
    first clamped to max slip bias x (1 - d / locking torque) and d biased by the excess towards
    the slower wheel (the linearised torques t + s dw follow the clamp's change dw; with zero
    slopes, the explicit step, they stay TORCS's torques of the spins before); VISCOUS COUPLER: the right wheel gets min bias of d while not slower, up to
    min + span (1 - exp(-visc |w0 - w1|)); SPOOL: one rigid body (both wheels the right one's
    spin); NONE: no drive torque once the wheels turn. At rest (w0 = w1 = 0) d / 2 each."""
    kind = int(cp[i, C_DKIND + j])
    common = abs(w0) + abs(w1)
    d_in = drive - fb * (t0 + t1)
    if common != 0.0 and kind == DIFF_LSD and (d_in > cp[i, C_DLOCK + j] or d_in < -cp[i, C_DLOCKB + j]):
        kind = DIFF_SPOOL
    if kind == DIFF_SPOOL:
        ii = i0 + i1 + dt * (1.0 + fb) * (s0 + s1)
        w = _brake_spin(w0 + dt * (drive - (1.0 + fb) * (t0 + t1)) / ii, dt * (b0 + b1) / ii)
        return w, w
    # net torque on wheel k: a_k d + spider t_other - (1 + spider) t_k
    a0 = a1 = 0.5
    spider = 0.0
    if common != 0.0:
        if kind == DIFF_FREE or kind == DIFF_LSD:
            spider = 0.5
            if kind == DIFF_LSD:
                lock = cp[i, C_DLOCK + j] if d_in >= 0.0 else -cp[i, C_DLOCKB + j]
                ratio_max = cp[i, C_DSLIP + j] * (1.0 - d_in / lock)
                ratio = abs(w0 - w1) / common
                if ratio > ratio_max:
                    dw = 0.5 * (ratio - ratio_max) * common
                    bias = (ratio - ratio_max) * (1.0 if d_in >= 0.0 else -1.0)
                    if w0 > w1:
                        dw, bias = -dw, -bias
                    # the linearised tyre torques follow the clamped spins (implicit step; the
                    # explicit one passes zero slopes and keeps TORCS's torques of the spins before)
                    w0, w1 = w0 + dw, w1 - dw
                    t0, t1 = t0 + s0 * dw, t1 - s1 * dw
                    a0, a1 = 0.5 * (1.0 + bias), 0.5 * (1.0 - bias)
        elif kind == DIFF_VISCOUS:
            a0 = cp[i, C_DMIN + j]
            if w0 < w1:
                a0 += (1.0 - math.exp(-abs(cp[i, C_DVISC + j] * (w0 - w1)))) * cp[i, C_DSPAN + j]
            a1 = 1.0 - a0
        else:           # NONE
            a0 = a1 = 0.0
    c00, c01 = -(1.0 + spider) - a0 * fb, spider - a0 * fb
    c10, c11 = spider - a1 * fb, -(1.0 + spider) - a1 * fb
    n0 = a0 * drive + c00 * t0 + c01 * t1
    n1 = a1 * drive + c10 * t0 + c11 * t1
    # implicit: (i_k / dt) dw_k = n_k + sum_m c_km s_m dw_m
    m00, m01 = i0 / dt - c00 * s0, -c01 * s1
    m10, m11 = -c10 * s0, i1 / dt - c11 * s1
    det = m00 * m11 - m01 * m10
    w0 += (n0 * m11 - m01 * n1) / det
    w1 += (m00 * n1 - m10 * n0) / det
    return _brake_spin(w0, dt * b0 / (i0 + dt * s0)), _brake_spin(w1, dt * b1 / (i1 + dt * s1))


@numba.njit(**_JIT)
def check_controls(controls, info):
    """Count non-finite controls: info[0] = count, info[1] = first bad flat index (or -1)."""
    info[0] = 0
    info[1] = -1
    for i in range(controls.shape[0]):
        for j in range(controls.shape[1]):
            if not math.isfinite(controls[i, j]):
                if info[1] < 0:
                    info[1] = i * controls.shape[1] + j
                info[0] += 1


@numba.njit(**_JIT)
def advance(st, cp, curve_w, curve_t, pt, surf, tsc, controls, nsub, dt, fuel_on):
    """Advance every car by `nsub` sub-steps of `dt` with its controls held (see `advance_car`)."""
    for i in range(st.shape[0]):
        advance_car(st, i, cp, curve_w, curve_t, pt, surf, tsc, controls, nsub, dt, fuel_on)


@numba.njit(parallel=True, **_JIT)
def advance_parallel(st, cp, curve_w, curve_t, pt, surf, tsc, controls, nsub, dt, fuel_on):
    """`advance` with the cars shared among threads (cars are independent between contact
    calls, so the result is bit-identical to the serial loop)."""
    for i in numba.prange(st.shape[0]):
        advance_car(st, i, cp, curve_w, curve_t, pt, surf, tsc, controls, nsub, dt, fuel_on)


@numba.njit(**_JIT, **NO_REFCOUNT)
def car_derived(cp):
    """cp's derived columns, rows of cars (N, N_CAR): C_WGSIN, C_WGCOS (per wing) and C_TOESIN,
    C_TOECOS (per wheel) from the angles C_WGANG and C_TOE (rad), with this kernel's own
    math.sin / math.cos (`advance_car` reads them instead of 4 libm sincos a call); the
    reciprocals C_RBELL (per wheel), C_RIXX, C_RIYY, C_RWB2, C_RTR2 that the sub-step multiplies
    by instead of dividing (`suspension.wheel_loads`, `body_vertical`); the quotients C_W0B (static
    load / bellcrank, per wheel: the same division the sub-step made, once); the wheel track
    C_WTRACK (`wheel_track`)."""
    for i in range(cp.shape[0]):
        for k in range(4):
            cp[i, C_RBELL + k] = 1.0 / cp[i, C_BELL + k]
            cp[i, C_W0B + k] = cp[i, C_W0 + k] / cp[i, C_BELL + k]
        cp[i, C_RIXX], cp[i, C_RIYY] = 1.0 / cp[i, C_IXX], 1.0 / cp[i, C_IYY]
        cp[i, C_RWB2] = 1.0 / ((cp[i, C_WX] + cp[i, C_WX + 1]) - (cp[i, C_WX + 2] + cp[i, C_WX + 3]))
        cp[i, C_RTR2] = 1.0 / ((cp[i, C_WY + 1] + cp[i, C_WY + 3]) - (cp[i, C_WY] + cp[i, C_WY + 2]))
        cp[i, C_WTRACK] = 0.5 * (cp[i, C_TF] + cp[i, C_TR])
        for k in range(2):
            a = cp[i, C_WGANG + k]
            cp[i, C_WGSIN + k], cp[i, C_WGCOS + k] = math.sin(a), math.cos(a)
        for k in range(4):
            a = cp[i, C_TOE + k]
            cp[i, C_TOESIN + k], cp[i, C_TOECOS + k] = math.sin(a), math.cos(a)


@numba.njit(**_JIT, **NO_REFCOUNT)
def advance_car(st, i, cp, curve_w, curve_t, pt, surf, tsc, controls, nsub, dt, fuel_on):
    """`nsub` explicit sub-steps of car i: the dynamic bicycle model of car spec 5.2 with TORCS's
    engine, gearbox, tyre and aero rules. Controls must be finite (any range: clipped here).
    Assumes small road grade/banking (gravity and load from the local road gradient) and no
    contact (the contact solver runs between calls). A shift in progress lowers the car's accel
    command in `controls` itself to 0.1 (TORCS's ctrl->accelCmd, held to the end of the driver
    call): callers pass the tick's own copy. One call of n sub-steps is bit-identical to n calls
    of one on the same controls (nothing is evaluated once per call that a sub-step changes). Returns
    (largest squared speed, m^2/s^2; largest |yaw rate|, rad/s) at the start and the sub-steps'
    ends: bounds of how far the car went (contact whole ticks check them with its end pose).
    `wheel_loads`, `body_vertical`, `track_update` and `track_observed` are compiled on their
    own and called, not inlined into this body at numba's IR level: numba's passes grow faster
    than linearly with a function's size, and inlined they made this kernel's first compile
    1.8x longer (55.6 s against 31 s of CPU on the 2-core AMD EPYC) for no speed measurable in
    `bench_substep`. The small helpers on the sub-step's chain (`_axle_spin`, the tyre's) stay
    inlined: called, `_axle_spin` cost ~5 % on madsim-speedway."""
    steer_cmd = min(max(controls[i, U_STEER], -1.0), 1.0)
    accel = min(max(controls[i, U_ACCEL], 0.0), 1.0)
    brake = min(max(controls[i, U_BRAKE], 0.0), 1.0)
    clutch = min(max(controls[i, U_CLUTCH], 0.0), 1.0)
    gear_req = min(max(math.floor(controls[i, U_GEAR] + 0.5), -1.0), cp[i, C_TOP])

    # car constants
    a, b, wb, h = cp[i, C_A], cp[i, C_B], cp[i, C_L], cp[i, C_H]
    izz, mass_dry = cp[i, C_IZZ], cp[i, C_MASS]
    inv_izz = 1.0 / izz
    lock, steer_rate, track_w = cp[i, C_LOCK], cp[i, C_STEERSPD] * dt, wheel_track(cp, i)
    rad0, rad1, rad2, rad3 = cp[i, C_RAD], cp[i, C_RAD + 1], cp[i, C_RAD + 2], cp[i, C_RAD + 3]
    skid = cp[i, C_SKID]
    bf, cf, ef, br, cr, er = cp[i, C_BF], cp[i, C_CF], cp[i, C_EF], cp[i, C_BR], cp[i, C_CR], cp[i, C_ER]
    share_min = share = cp[i, C_FSHARE]
    visc, share_span = cp[i, C_VISC], cp[i, C_VISC_MAX] - share_min
    viscous = visc > 0.0
    feedback = cp[i, C_REACT] - 1.0    # 4WD: 1 / centre ratio (see _axle_spin); else 0
    driven_f, driven_r = cp[i, C_DRIVEN_F] > 0.0, cp[i, C_DRIVEN_R] > 0.0
    limiter, maxi, tick, ieng = cp[i, C_LIMIT], cp[i, C_MAXI], cp[i, C_TICK], cp[i, C_IENG]
    ebrake, inv_span = cp[i, C_EBRAKE], 1.0 / (cp[i, C_MAXI] - cp[i, C_TICK])
    n_curve = int(cp[i, C_NCURVE])
    seg = 1
    p_brake = brake * cp[i, C_PMAX]
    tb_f = p_brake * cp[i, C_BRAKE_FRONT]
    tb_r = p_brake * (1.0 - cp[i, C_BRAKE_FRONT])
    tb0, tb1 = cp[i, C_KB] * tb_f, cp[i, C_KB + 1] * tb_f
    tb2, tb3 = cp[i, C_KB + 2] * tb_r, cp[i, C_KB + 3] * tb_r
    wear = 1.0 + st[i, S_DAMAGE] / 10000.0
    dragk = st[i, S_DRAGK]
    scx2 = cp[i, C_SCX2] * wear * dragk * dragk
    clift_f, clift_r = cp[i, C_CLIFT_F], cp[i, C_CLIFT_R]
    sw0, cw0 = cp[i, C_WGSIN], cp[i, C_WGCOS]             # wings (spec 4.7), see `car_derived`
    sw1, cw1 = cp[i, C_WGSIN + 1], cp[i, C_WGCOS + 1]
    kx0, kx1 = cp[i, C_WGKX] * wear, cp[i, C_WGKX + 1] * wear
    kz0, kz1 = cp[i, C_WGKZ], cp[i, C_WGKZ + 1]
    xw0, xw1, zw0, zw1 = cp[i, C_WGX], cp[i, C_WGX + 1], cp[i, C_WGZ], cp[i, C_WGZ + 1]
    y0, y1, y2, y3 = cp[i, C_WY], cp[i, C_WY + 1], cp[i, C_WY + 2], cp[i, C_WY + 3]
    rc_f, rc_r = cp[i, C_RC], cp[i, C_RC + 1]                 # roll-centre heights
    x0w, x1w, x2w, x3w = cp[i, C_WX], cp[i, C_WX + 1], cp[i, C_WX + 2], cp[i, C_WX + 3]
    toe0, toe1 = cp[i, C_TOE], cp[i, C_TOE + 1]               # static toe (spec 4.5), rad
    cd2, sd2 = cp[i, C_TOECOS + 2], cp[i, C_TOESIN + 2]       # the rear wheels' (constant) heading
    cd3, sd3 = cp[i, C_TOECOS + 3], cp[i, C_TOESIN + 3]
    # the four tyres as one loop over lanes (wheel k in lane k, on this call's stack): LLVM
    # vectorises it (SIMD) because its trip count is not a constant it could unroll first;
    # `& ~3` tells it the count is 0 or 4, so the vector body stores whole registers (with a
    # count of 1..4 it masked them, vmaskmovpd, and the scalar reads that follow waited for
    # the masked stores, no store-to-load forwarding: make_vec's physics took ~12 % longer,
    # benchmarks/RESULTS.md, "The car sub-step's masked stores")
    n_lanes = min(4, cp.shape[1]) & ~3
    l_vx, l_vy, l_cd, l_sd, l_spin = el.lanes4(), el.lanes4(), el.lanes4(), el.lanes4(), el.lanes4()
    l_b, l_c, l_e = el.lanes4(), el.lanes4(), el.lanes4()
    l_ft, l_fn, l_dft = el.lanes4(), el.lanes4(), el.lanes4()
    l_fz, l_k, l_fric = el.lanes4(), el.lanes4(), el.lanes4()
    l_mu, l_lf0, l_lfd, l_lfk = el.lanes4(), el.lanes4(), el.lanes4(), el.lanes4()
    for k in range(4):
        l_mu[k], l_lfk[k] = cp[i, C_KMU + k], cp[i, C_LFK + k] / cp[i, C_OPLOAD + k]
        l_lf0[k], l_lfd[k] = cp[i, C_LFMIN + k], cp[i, C_LFMAX + k] - cp[i, C_LFMIN + k]
    l_b[0], l_b[1], l_b[2], l_b[3] = bf, bf, br, br
    l_c[0], l_c[1], l_c[2], l_c[3] = cf, cf, cr, cr
    l_e[0], l_e[1], l_e[2], l_e[3] = ef, ef, er, er
    l_cd[2], l_sd[2], l_cd[3], l_sd[3] = cd2, sd2, cd3, sd3

    # state into locals
    x, y, yaw, r = st[i, S_X], st[i, S_Y], st[i, S_YAW], st[i, S_R]
    vxg, vyg = st[i, S_VXG], st[i, S_VYG]
    ax_s, ay_s = st[i, S_AX], st[i, S_AY]
    w0, w1, w2, w3, we = st[i, S_SPIN], st[i, S_SPIN + 1], st[i, S_SPIN + 2], st[i, S_SPIN + 3], st[i, S_WE]
    gear, shift_t, d = st[i, S_GEAR], st[i, S_SHIFT], st[i, S_STEER]
    fuel = st[i, S_FUEL]
    fz0, fz1, fz2, fz3 = st[i, S_FZ], st[i, S_FZ + 1], st[i, S_FZ + 2], st[i, S_FZ + 3]
    pw0, pw1 = st[i, S_SPINRAW], st[i, S_SPINRAW + 1]          # last raw spins and tyre forces
    pw2, pw3 = st[i, S_SPINRAW + 2], st[i, S_SPINRAW + 3]
    pt0, pt1, pt2, pt3 = st[i, S_FTRAW], st[i, S_FTRAW + 1], st[i, S_FTRAW + 2], st[i, S_FTRAW + 3]
    pn0, pn1, pn2, pn3 = st[i, S_FNRAW], st[i, S_FNRAW + 1], st[i, S_FNRAW + 2], st[i, S_FNRAW + 3]
    cy, sy = math.cos(yaw), math.sin(yaw)
    # cos, sin of yaw - track heading as the last `track_update` formed them (same piece, same
    # x, y: the same bits), then each sub-step's `track_update` returns the next
    _, _, ch, sh = _piece_local(pt, int(st[i, S_PIECE]), x, y)
    cpsi, spsi = cy * ch + sy * sh, sy * ch - cy * sh
    p_end, q_end, n_end = int(st[i, S_PIECE]), 0.0, 0.0      # the last walk (track_observed)
    ch_end, sh_end = ch, sh
    d_done = math.nan
    cd0 = cd1 = 1.0
    sd0 = sd1 = 0.0
    v2_max, r_max = vxg * vxg + vyg * vyg, abs(r)     # (start included: any integrator)

    for _ in range(nsub):
        # --- a finished car goes on at TORCS's "slow pace" (simuv2's ctrlCheck, each step): the
        # accel command capped at 0.2, the brake at least 0.05 above 30 m/s forward; both
        # lower the tick's commands themselves (TORCS's ctrl), as a shift's cap does
        if finished(st, cp, i):
            if accel > FINISH_ACCEL:
                accel = FINISH_ACCEL
                controls[i, U_ACCEL] = FINISH_ACCEL
            if brake < FINISH_BRAKE and vxg * cy + vyg * sy > FINISH_BRAKE_ABOVE:
                brake = FINISH_BRAKE
                controls[i, U_BRAKE] = FINISH_BRAKE
                p_brake = brake * cp[i, C_PMAX]
                tb_f = p_brake * cp[i, C_BRAKE_FRONT]
                tb_r = p_brake * (1.0 - cp[i, C_BRAKE_FRONT])
                tb0, tb1 = cp[i, C_KB] * tb_f, cp[i, C_KB + 1] * tb_f
                tb2, tb3 = cp[i, C_KB + 2] * tb_r, cp[i, C_KB + 3] * tb_r

        # --- steering: rate-limited towards steer * lock; Ackermann (spec 4.2): the inner
        # front wheel turns by d, the outer by atan(L tan|d| / (L + t tan|d|)), t TORCS's wheel
        # track (`front_wheel_angles`); each wheel's heading adds its static toe
        d += min(max(steer_cmd * lock - d, -steer_rate), steer_rate)
        if d != d_done:
            d_done = d
            d0, d1 = front_wheel_angles(d, wb, track_w)        # wheel 0 right, 1 left
            cd0, sd0 = math.cos(d0 + toe0), math.sin(d0 + toe0)     # heading = steer + toe
            cd1, sd1 = math.cos(d1 + toe1), math.sin(d1 + toe1)
            l_cd[0], l_sd[0], l_cd[1], l_sd[1] = cd0, sd0, cd1, sd1

        # --- gearbox (spec 4.3), in TORCS's order: a shift in progress runs its timer down and,
        # while it runs and the pedal is up, opens the clutch and caps the throttle; then a
        # requested gear is engaged (unless a shift is in progress). The step of the change
        # itself is coupled, so the engine snaps to the wheels' speed (idle from rest). The cap
        # lowers the tick's accel command itself (TORCS's ctrl->accelCmd): it holds to the end
        # of the driver call, past the shift's end (docs/physics.md, "Gear changes").
        c = 1.0 - clutch
        throttle = accel
        if shift_t > 0.0:
            shift_t -= dt
            if shift_t > 0.0 and clutch < 0.01:
                c = 0.0
                if accel > 0.1:
                    accel = 0.1
                    controls[i, U_ACCEL] = 0.1
                throttle = accel
        if gear_req != gear and shift_t <= 0.0:
            gear = gear_req
            shift_t = cp[i, C_SHIFT] if gear != 0.0 else 0.0
            c = 1.0 - clutch
            throttle = accel
        slot = int(gear) + 1
        ratio = cp[i, C_RATIO + slot]
        coupled = gear != 0.0 and c > 0.01

        # --- engine torque (spec 4.4): limiter cut holds the engine at the red line
        if we > limiter:
            we = limiter
            teng = 0.0
        else:
            tmax, seg = _engine_curve(curve_w, curve_t, i, n_curve, we, seg)
            k_eb = ebrake * (we - tick) * inv_span
            teng = tmax * (throttle * (1.0 + k_eb) - k_eb)
        if fuel_on and fuel <= 0.0:
            teng = 0.0
        t_drive = teng * ratio * min(3.0 * c, 1.0)

        # --- body velocity in the body frame
        vx = vxg * cy + vyg * sy
        vy = vyg * cy - vxg * sy
        m = mass_dry + fuel
        # --- aero (spec 4.7): body downforce with the ground-effect factor of the last ride
        # heights; wings at their angle + pitch + the body's climb angle (TORCS's wing.cpp)
        v = math.sqrt(vx * vx + vy * vy)
        vx2 = vx * vx
        down_f = down_r = wfx = wfz = wmy = 0.0
        pitch = st[i, S_PITCH]
        s_p, c_p = math.sin(pitch), math.cos(pitch)        # aero and wheel loads
        if vx > 0.0:
            hm = 1.5 * (st[i, S_RIDE] + st[i, S_RIDE + 1] + st[i, S_RIDE + 2] + st[i, S_RIDE + 3])
            hm = hm * hm
            hm = 2.0 * math.exp(-3.0 * hm * hm)
            # climb = atan2(vz, vx) + pitch, its cos and sin without atan2: (vx, vz) / |(vx, vz)|
            # rotated by the pitch (within a few ulp of the libm form, relative to vx^2); one
            # division for 1 / |v| and 1 / |(vx, vz)|
            vz = st[i, S_VZ]
            vxz = math.sqrt(vx2 + vz * vz)
            inv_vv = 1.0 / (v * vxz)
            body_down = vx2 * hm * vx * (vxz * inv_vv)       # cos_a = max(0, vx/|v|)
            down_f = clift_f * body_down
            down_r = clift_r * body_down
            vh = vx2 * (v * inv_vv)
            c_cl, s_cl = (vx * c_p - vz * s_p) * vh, (vz * c_p + vx * s_p) * vh
            sa0 = sw0 * c_cl + cw0 * s_cl                    # sin(wing angle + climb) vx^2
            sa1 = sw1 * c_cl + cw1 * s_cl
            fxw0, fxw1 = kx0 * sa0, kx1 * sa1                # < 0: drag
            fzw0, fzw1 = kz0 * sa0, kz1 * sa1                # < 0: downforce
            wfx = fxw0 + fxw1
            wfz = fzw0 + fzw1
            wmy = -(fzw0 * xw0 + fxw0 * zw0 + fzw1 * xw1 + fxw1 * zw1)
        # --- wheel loads (docs/physics.md): the suspension forces at the body's heave, roll, pitch
        # and the road gradient in the body frame from the road under the four wheels (TORCS's
        # SimCarUpdateForces: front minus rear over the wheelbase, left minus right over the track)
        fb0, fb1, fb2, fb3, packed, gbx, gby = wheel_loads(st, i, cp, pt, surf, tsc, s_p, cpsi, spsi, dt)
        fz0, fz1, fz2, fz3 = max(fb0, 0.0), max(fb1, 0.0), max(fb2, 0.0), max(fb3, 0.0)
        ax_kin = ax_s - G * gbx
        ay_kin = ay_s - G * gby

        # rolling resistance force, N
        roll = (fz0 * st[i, S_ROLL] + fz1 * st[i, S_ROLL + 1] + fz2 * st[i, S_ROLL + 2]
                + fz3 * st[i, S_ROLL + 3])

        # --- tyres (spec 4.9): each wheel its own slip from its own contact-point velocity
        # (body velocity + yaw rate x wheel position), forces by its load scale
        # K = Fz mu camber lf(Fz) friction (spec 4.9), all four in one loop over lanes
        l_fz[0], l_fz[1], l_fz[2], l_fz[3] = fz0, fz1, fz2, fz3
        l_fric[0], l_fric[1] = st[i, S_FRIC], st[i, S_FRIC + 1]
        l_fric[2], l_fric[3] = st[i, S_FRIC + 2], st[i, S_FRIC + 3]
        l_vx[0], l_vx[1], l_vx[2], l_vx[3] = vx - y0 * r, vx - y1 * r, vx - y2 * r, vx - y3 * r
        l_vy[0], l_vy[1], l_vy[2], l_vy[3] = vy + a * r, vy + a * r, vy - b * r, vy - b * r
        l_spin[0], l_spin[1], l_spin[2], l_spin[3] = w0 * rad0, w1 * rad1, w2 * rad2, w3 * rad3
        for k in range(n_lanes):
            fz = l_fz[k]
            l_k[k] = fz * l_mu[k] * l_fric[k] * (l_lf0[k] + l_lfd[k] * el.exp(l_lfk[k] * fz))
            l_ft[k], l_fn[k], l_dft[k] = _tyre(l_vx[k], l_vy[k], l_cd[k], l_sd[k], l_spin[k],
                                               l_b[k], l_c[k], l_e[k], skid)
        k0, k1, k2, k3 = l_k[0], l_k[1], l_k[2], l_k[3]
        ft0, ft1, ft2, ft3 = l_ft[0], l_ft[1], l_ft[2], l_ft[3]
        fn0, fn1, fn2, fn3 = l_fn[0], l_fn[1], l_fn[2], l_fn[3]
        dft0, dft1, dft2, dft3 = l_dft[0], l_dft[1], l_dft[2], l_dft[3]
        # forces in N; above SPIN_AVG_SPEED each is the mean of its raw value now and the last
        # one (TORCS's SimWheelUpdateForce: RELAXATION2(Ft, preFt, 50), same for Fn)
        fast = v > SPIN_AVG_SPEED
        gt0, gt1, gt2, gt3 = ft0 * k0, ft1 * k1, ft2 * k2, ft3 * k3
        gn0, gn1, gn2, gn3 = fn0 * k0, fn1 * k1, fn2 * k2, fn3 * k3
        if fast:
            at0, at1, at2, at3 = 0.5 * (gt0 + pt0), 0.5 * (gt1 + pt1), 0.5 * (gt2 + pt2), 0.5 * (gt3 + pt3)
            an0, an1, an2, an3 = 0.5 * (gn0 + pn0), 0.5 * (gn1 + pn1), 0.5 * (gn2 + pn2), 0.5 * (gn3 + pn3)
        else:
            at0, at1, at2, at3 = gt0, gt1, gt2, gt3
            an0, an1, an2, an3 = gn0, gn1, gn2, gn3
        pt0, pt1, pt2, pt3 = gt0, gt1, gt2, gt3
        pn0, pn1, pn2, pn3 = gn0, gn1, gn2, gn3

        # --- 4WD centre viscous coupler (spec 4.10, TORCS's rule) on the axles' mean spins: the
        # front axle gets the min torque bias while it turns at least as fast as the rear, more
        # as it falls behind
        if viscous:
            wf = 0.5 * (w0 + w1)
            wr = 0.5 * (w2 + w3)
            if wf == 0.0 and wr == 0.0:
                share = 0.5
            elif wf >= wr:
                share = share_min
            else:
                share = share_min + (1.0 - math.exp(-visc * (wr - wf))) * share_span

        # --- wheel spin (spec 4.10 inertias; brakes stop but never reverse), each axle through
        # its differential: above SPIN_AVG_SPEED TORCS's explicit step on the averaged tyre
        # torques, else the implicit step
        # a driven wheel's inertia is the engaged gear's whatever the clutch (TORCS sets it at
        # the gear change and keeps it while the clutch is open; neutral's slot is the free one)
        i_f = 0.5 * (cp[i, C_IDRIVE_F + slot] if driven_f else cp[i, C_IFREE_F])
        i_r = 0.5 * (cp[i, C_IDRIVE_R + slot] if driven_r else cp[i, C_IFREE_R])
        # linearised in the slip velocity vt - wR: the wheel's own change and the body's
        # (predicted from the last step's acceleration) both enter, so a steadily accelerating
        # car sees exactly the wheel inertia I (not I + dt R^2 dF/ds)
        drive_f = t_drive * share if driven_f else 0.0
        drive_r = t_drive * (1.0 - share) if driven_r else 0.0
        if fast:
            w0, w1 = _axle_spin(cp, i, 0, drive_f, feedback, w0, w1, rad0 * at0, rad1 * at1,
                                0.0, 0.0, i_f, i_f, tb0, tb1, dt)
            w2, w3 = _axle_spin(cp, i, 1, drive_r, feedback, w2, w3, rad2 * at2, rad3 * at3,
                                0.0, 0.0, i_r, i_r, tb2, tb3, dt)
        else:
            dvx = (ax_kin + r * vy) * dt
            dvy = (ay_kin - r * vx) * dt
            dvt0, dvt1 = dvx * cd0 + dvy * sd0, dvx * cd1 + dvy * sd1
            rk0, rk1, rk2, rk3 = k0 * rad0, k1 * rad1, k2 * rad2, k3 * rad3
            w0, w1 = _axle_spin(cp, i, 0, drive_f, feedback, w0, w1,
                                rk0 * (ft0 - dft0 * dvt0), rk1 * (ft1 - dft1 * dvt1),
                                rk0 * dft0 * rad0, rk1 * dft1 * rad1, i_f, i_f, tb0, tb1, dt)
            w2, w3 = _axle_spin(cp, i, 1, drive_r, feedback, w2, w3,
                                rk2 * (ft2 - dft2 * (dvx * cd2 + dvy * sd2)),
                                rk3 * (ft3 - dft3 * (dvx * cd3 + dvy * sd3)),
                                rk2 * dft2 * rad2, rk3 * dft3 * rad3, i_r, i_r, tb2, tb3, dt)

        # --- engine speed (spec 4.10): follows the driven wheels through the clutch, else free
        we_free = we + teng / ieng * dt
        if coupled:
            if driven_f and driven_r:
                w_axle = 0.25 * (w0 + w1 + w2 + w3)
            elif driven_f:
                w_axle = 0.5 * (w0 + w1)
            else:
                w_axle = 0.5 * (w2 + w3)
            c4 = c * c * c * c
            we = w_axle * ratio * c4 + we_free * (1.0 - c4)
            if we > maxi:
                we = maxi
                if w_axle * ratio > maxi:        # over-revving: the engine holds the wheels back
                    scale = maxi / (w_axle * ratio)
                    if driven_f:
                        w0 *= scale
                        w1 *= scale
                    if driven_r:
                        w2 *= scale
                        w3 *= scale
        else:
            we = we_free
        we = min(max(we, tick), maxi)
        # the spins: above SPIN_AVG_SPEED the mean of the raw new one and the last raw one
        # (TORCS's SimWheelUpdateRotation: RELAXATION2(spinVel, prespinVel, 50))
        if fast:
            w0, pw0 = 0.5 * (w0 + pw0), w0
            w1, pw1 = 0.5 * (w1 + pw1), w1
            w2, pw2 = 0.5 * (w2 + pw2), w2
            w3, pw3 = 0.5 * (w3 + pw3), w3
        else:
            pw0, pw1, pw2, pw3 = w0, w1, w2, w3
        if fuel_on:
            fuel = max(fuel - abs(teng) * we * cp[i, C_FUELCONS] * 1e-7 * dt, 0.0)

        # --- body forces (body frame): tyres, aero drag, wings, gravity along the road gradient
        fx0, fx1 = at0 * cd0 - an0 * sd0, at1 * cd1 - an1 * sd1
        fx2, fx3 = at2 * cd2 - an2 * sd2, at3 * cd3 - an3 * sd3
        fy_f = (at0 * sd0 + an0 * cd0) + (at1 * sd1 + an1 * cd1)
        fy_r = (at2 * sd2 + an2 * cd2) + (at3 * sd3 + an3 * cd3)
        drag = -math.copysign(scx2 * vx2, vx) + wfx
        fx_ng = fx0 + fx1 + fx2 + fx3 + drag
        fy_ng = fy_f + fy_r
        fx = fx_ng - m * G * gbx      # gravity along the road: m g x height difference / distance
        fy = fy_ng - m * G * gby      # between the wheels (spec 4.11), i.e. the gradient, not sin
        mz = a * fy_f - b * fy_r - (fx0 * y0 + fx1 * y1 + fx2 * y2 + fx3 * y3)

        # --- integration (spec 4.11): velocities first; rolling resistance cannot reverse them
        rv, rm = rolling_drag(roll, math.sqrt(vxg * vxg + vyg * vyg), r, m, izz, wb, dt)
        inv_m = 1.0 / m
        vxg += ((fx * cy - fy * sy) - rv * vxg) * inv_m * dt
        vyg += ((fx * sy + fy * cy) - rv * vyg) * inv_m * dt
        r += (mz - rm) * inv_izz * dt
        r = min(max(r, -YAW_RATE_MAX), YAW_RATE_MAX)
        ax_s = (fx_ng - rv * vx) * inv_m
        ay_s = (fy_ng - rv * vy) * inv_m
        # heave, roll, pitch (TORCS's car.cpp moments): loads at the wheels, lateral forces
        # through the roll centres, longitudinal ones at the CG height + ride height, aero
        mx = (y0 * fb0 + y1 * fb1 + y2 * fb2 + y3 * fb3) + rc_f * fy_f + rc_r * fy_r
        my = (wmy + down_f * a - down_r * b
              - (x0w * fb0 + x1w * fb1 + x2w * fb2 + x3w * fb3)
              - (fx0 * (h + st[i, S_RIDE]) + fx1 * (h + st[i, S_RIDE + 1])
                 + fx2 * (h + st[i, S_RIDE + 2]) + fx3 * (h + st[i, S_RIDE + 3])))
        body_vertical(st, i, cp, inv_m, fb0 + fb1 + fb2 + fb3 - down_f - down_r + wfz, mx, my, dt)
        if packed:      # a wheel on its packers: bottoming (TORCS's SimCarCollideZ)
            vxg, vyg = ground_contact(st, i, cp, pt, surf, tsc, packed, vxg, vyg, cpsi, spsi)
        v2_max = max(v2_max, vxg * vxg + vyg * vyg)
        r_max = max(r_max, abs(r))
        x += vxg * dt
        y += vyg * dt
        yaw = _wrap_step(yaw + r * dt)
        cy, sy = math.cos(yaw), math.sin(yaw)
        st[i, S_TIME] += dt
        cpsi, spsi, p_end, q_end, n_end, ch_end, sh_end = track_update(
            st, i, cp, pt, surf, tsc, x, y, cy, sy, COUNT_LAPS)

    if nsub > 0:
        track_observed(st, i, pt, surf, tsc, p_end, q_end, n_end, ch_end, sh_end)
    st[i, S_X], st[i, S_Y], st[i, S_YAW], st[i, S_R] = x, y, yaw, r
    st[i, S_VXG], st[i, S_VYG] = vxg, vyg
    st[i, S_VX] = vxg * cy + vyg * sy
    st[i, S_VY] = vyg * cy - vxg * sy
    st[i, S_AX], st[i, S_AY] = ax_s, ay_s
    st[i, S_SPIN], st[i, S_SPIN + 1], st[i, S_SPIN + 2], st[i, S_SPIN + 3] = w0, w1, w2, w3
    st[i, S_WE] = we
    st[i, S_GEAR], st[i, S_SHIFT], st[i, S_STEER] = gear, shift_t, d
    st[i, S_FUEL] = fuel
    st[i, S_FZ], st[i, S_FZ + 1], st[i, S_FZ + 2], st[i, S_FZ + 3] = fz0, fz1, fz2, fz3
    st[i, S_SPINRAW], st[i, S_SPINRAW + 1], st[i, S_SPINRAW + 2], st[i, S_SPINRAW + 3] = pw0, pw1, pw2, pw3
    st[i, S_FTRAW], st[i, S_FTRAW + 1], st[i, S_FTRAW + 2], st[i, S_FTRAW + 3] = pt0, pt1, pt2, pt3
    st[i, S_FNRAW], st[i, S_FNRAW + 1], st[i, S_FNRAW + 2], st[i, S_FNRAW + 3] = pn0, pn1, pn2, pn3
    return v2_max, r_max
