"""TORCS's suspension and the body's heave, roll and pitch (docs/physics.md, "Suspension and
vertical dynamics"; after TORCS 1.3.7's simuv2: susp.cpp, wheel.cpp, axle.cpp, car.cpp,
collide.cpp), compiled per car on the arrays of `madsim.physics.layout` and called by the car
kernel's sub-step (`kernel.advance_car`: `wheel_loads` before the tyres, `body_vertical` after the
planar step) and at placement (`settle`). The vertical state lives in `st`'s columns S_Z, S_VZ,
S_ROLLA, S_PITCH, their rates, S_SUSP, S_WVZ and S_RIDE (4 each, wheel order)."""

from __future__ import annotations

import math

import numba

from madsim.physics import elementary as el
from madsim.physics.finish import takes_damage
from madsim.physics.layout import (  # noqa: I001 - column indices, see layout.py
    C_A, C_ARB, C_B, C_BELL, C_COURSE, C_DBUMP1, C_DBUMP2, C_DMGK, C_DREB1, C_DREB2, C_H,
    C_PACK, C_RBELL, C_RIDE0, C_RIXX, C_RIYY, C_RTR2, C_RWB2, C_SPRING, C_VBUMP, C_VREB, C_W0,
    C_W0B, C_WMASS, C_WX, C_WY,
    P_A0, P_B0, P_B1, P_BSURF_L, P_BSURF_R, P_BW_L, P_BW_R, P_CURB_L, P_CURB_R, P_CURBK_L,
    P_CURBK_R, P_CURV, P_INVLEN, P_LEN, P_S0, P_SSURF_L, P_SSURF_R, P_SURF, P_SW0_L, P_SW0_R,
    P_SW1_L, P_SW1_R, P_TB0, P_WSURF_L, P_WSURF_R, P_ZR0, P_ZR1,
    S_DAMAGE, S_FZ, S_GX, S_GY, S_N, S_PIECE, S_PITCH, S_PITCHR, S_RIDE, S_ROLLA, S_ROLLR, S_S,
    S_SUSP,
    S_THEAD, S_VXG, S_VYG, S_VZ, S_WVZ, S_YAW, S_Z, T_LENGTH, T_TANGENT_L, T_TANGENT_R, T_WIDTH,
)

G = 9.80665          # m/s^2, as TORCS
ANGLE_MAX = 1.04     # rad, TORCS's limit of roll and pitch
SURF_REBOUND, SURF_DAMMAGE = 4, 5
"""Columns of the surface table (`tables.piece_table`) read by `ground_contact`: the surface's
`rebound` and `dammage`."""

_JIT = {"cache": True, "error_model": "numpy"}


@numba.njit(inline="always", **_JIT)
def _damper(v, c1, c2, v1):
    """TORCS's two-slope damper (docs/physics.md): force, N, at travel speed v (m/s, + bump),
    |v| capped at 10 m/s; slope c1 (N s/m) below the threshold v1 (m/s), c2 above, continuous."""
    av = min(abs(v), 10.0)
    f = c1 * av if av < v1 else c2 * av + (c1 - c2) * v1
    return f if v >= 0.0 else -f


@numba.njit(inline="always", **_JIT)
def _wheel_travel(st, i, cp, k, ride, dt, inv_dt):
    """Wheel k's suspension travel for one sub-step (docs/physics.md, after TORCS 1.3.7's
    SimWheelUpdateRide and SimSuspCheckIn): the wheel moves by its relative velocity, stopped
    by the road (`ride`, m: body reference above the road under the wheel) and by the packers,
    then the travel (x bellcrank) is clamped to the packers and the suspension course. Stores
    the travel and the wheel's relative velocity; returns (travel speed, m/s, + in bump; state:
    0 free, 1 on the packers (the road is above them), 2 fully extended)."""
    bell = cp[i, C_BELL + k]
    pack = cp[i, C_PACK + k]
    prex = st[i, S_SUSP + k]
    x = prex * cp[i, C_RBELL + k] - st[i, S_WVZ + k] * dt
    if ride < x:
        x = ride
        st[i, S_WVZ + k] = 0.0
    elif x < pack:
        x = pack
        st[i, S_WVZ + k] = 0.0
    state = 0
    if x < pack:
        x = pack
        state = 1
    x *= bell
    if x > cp[i, C_COURSE + k]:
        x = cp[i, C_COURSE + k]
        state = 2
    st[i, S_SUSP + k] = x
    return (prex - x) * inv_dt, state


@numba.njit(inline="always", **_JIT)
def _wheel_force(st, i, cp, k, v, state, bar, dt):
    """Vertical force of wheel k on the body, N (TORCS 1.3.7's SimSuspUpdate and
    SimWheelUpdateForce): spring F0 - k (x - x0) (never pulling; F0 = static load / bellcrank,
    the car table's C_W0B) + two-slope damper at travel
    speed v, their sum never pulling, times the bellcrank, + the anti-roll bar's `bar`, N. A fully
    extended wheel moving down passes its own inertia instead. Updates the wheel's relative
    velocity; the tyre's load is this force's positive part."""
    bell = cp[i, C_BELL + k]
    spring = max(cp[i, C_W0B + k] - cp[i, C_SPRING + k] * (st[i, S_SUSP + k] - bell * cp[i, C_RIDE0 + k]), 0.0)
    if v < 0.0:
        damp = _damper(v, cp[i, C_DREB1 + k], cp[i, C_DREB2 + k], cp[i, C_VREB + k])
    else:
        damp = _damper(v, cp[i, C_DBUMP1 + k], cp[i, C_DBUMP2 + k], cp[i, C_VBUMP + k])
    wv = st[i, S_WVZ + k]
    if state == 2 and wv <= 0.0:
        f = wv / dt * cp[i, C_WMASS + k]
        st[i, S_WVZ + k] = 0.0
    else:
        f = bar + max(spring + damp, 0.0) * bell
        st[i, S_WVZ + k] = wv - dt * f / cp[i, C_WMASS + k]
    return f


@numba.njit(inline="always", **_JIT)
def on_piece(pt, p, q):
    """(piece, distance along it, m) of a point q m along piece p that may run one piece over
    either end."""
    if q < 0.0:
        p = p - 1 if p > 0 else pt.shape[0] - 1
        q += pt[p, P_LEN]
    elif q > pt[p, P_LEN]:
        q -= pt[p, P_LEN]
        p = p + 1 if p < pt.shape[0] - 1 else 0
    return p, q


@numba.njit(inline="always", **_JIT)
def wheel_at(pt, p, n, dx, dy):
    """(along, across) offset in track coordinates (m of the centre line's distance, m of lateral
    offset) of a body point dx ahead and dy to the left of a CG at lateral offset n on piece p,
    (dx, dy) already turned into the track's frame at the CG. On a curve of curvature c a
    tangent step dx covers dx / g of the centre line and drops c dx^2 / (2 g) towards the
    outside, g = 1 - c (n + dy): the exact arc's first terms (along within (dx / g) u^2 / 3,
    u = c dx / g: 0.5 mm on g-track-2's curb, 4 mm 1.6 m from the CG 8.4 m inside a 30 m turn;
    across within 0.1 mm). TORCS locates each wheel at its global position. g is kept >= 0.1."""
    c = pt[p, P_CURV]
    g = max(1.0 - c * (n + dy), 0.1)
    return dx / g, dy - 0.5 * c * dx * dx / g


@numba.njit(inline="always", **_JIT)
def _wheel_offset(cp, pt, i, k, p, n, cpsi, spsi):
    """`wheel_at` of wheel k of car i: its static place (C_WX, C_WY) from the CG at lateral
    offset n on piece p, turned into the track frame ((cpsi, spsi): cos, sin of yaw - track
    heading)."""
    xk, yk = cp[i, C_WX + k], cp[i, C_WY + k]
    return wheel_at(pt, p, n, xk * cpsi - yk * spsi, xk * spsi + yk * cpsi)


@numba.njit(inline="always", **_JIT)
def _road_z(pt, tsc, p, q, n):
    """Road height, m, at distance q along piece p (may run one piece over either end) and
    lateral offset n (track spec 5.4: linear right edge + banking, as `kernel.track_observed`)."""
    p, q = on_piece(pt, p, q)
    return _road_z_at(pt, tsc, p, q, n)


@numba.njit(inline="always", **_JIT)
def _road_z_at(pt, tsc, p, q, n):
    """`_road_z` of a point already on piece p (0 <= q <= its length)."""
    u = min(max(q * pt[p, P_INVLEN], 0.0), 1.0)
    b0, b1 = pt[p, P_B0], pt[p, P_B1]
    tb = pt[p, P_TB0] if b0 == b1 else math.tan(b0 + u * (b1 - b0))
    w = tsc[T_WIDTH]
    lo = -1e30 if tsc[T_TANGENT_R] > 0.0 else 0.0
    hi = 1e30 if tsc[T_TANGENT_L] > 0.0 else w
    yc = min(max(n + 0.5 * w, lo), hi)
    zr0 = pt[p, P_ZR0]
    return zr0 + u * (pt[p, P_ZR1] - zr0) + yc * tb


@numba.njit(inline="always", **_JIT)
def _cg_on_piece(st, i, pt, tsc):
    """(piece, distance along it, m (may be past either end), lateral offset, m) of car i's CG."""
    p = int(st[i, S_PIECE])
    q = st[i, S_S] - pt[p, P_S0]
    if q < -0.5 * tsc[T_LENGTH]:
        q += tsc[T_LENGTH]
    elif q > 0.5 * tsc[T_LENGTH]:
        q -= tsc[T_LENGTH]
    return p, q, st[i, S_N]


@numba.njit(inline="always", **_JIT)
def relief(pt, surf, tsc, p, q, n, main):
    """Height, m, of the ground above the smooth road plane (`_road_z`) at distance q along
    piece p (may run one piece over either end) and lateral offset n (m, + left): TORCS 1.3.7's
    RtTrackHeightL (docs/physics.md, "Curbs" and "Road roughness"). On the road and on plain
    borders and sides it is the roughness `a sin(k t) sin(k l)`; on a curb border it is the
    curb's ramp `d atan2(h, w)` plus `a sin(k l) d / w`, with a and k the surface's amplitude
    and wave number (surf columns 2, 3), t the distance from the zone's right edge, d the
    distance into the curb from the road's edge, h and w the curb's height and width
    (P_CURBK_* holds atan2(h, w)) and l the distance from the piece start along the zone's own
    centre line (the road's scaled by its radius in a turn; a side's centre line at half its
    start width). `main`: the point as TORCS locates the car itself (the `z` sensor), not a
    wheel: on a right side with no border TORCS then measures t from the side's narrower end's
    width, and a side that continues the road's cross slope gets the saw-tooth that follows
    (docs/physics.md). 0 on a smooth road."""
    p, q = on_piece(pt, p, q)
    base, a, kt, kl, curb, d, bw = _relief_terms(pt, surf, tsc, p, q, n, main)
    if a == 0.0:
        return base
    return _relief_sum(base, a, math.sin(kt), math.sin(kl), curb, d, bw)


@numba.njit(inline="always", **_JIT)
def _relief_sum(base, a, sin_t, sin_l, curb, d, bw):
    """`relief` from its `_relief_terms` and the sines of their k t and k l."""
    if a == 0.0:
        return base
    return base + (a * sin_l * d / bw if curb else a * sin_t * sin_l)


@numba.njit(**_JIT, _nrt=False)
def _sines4(x0, x1, x2, x3, y0, y1, y2, y3):
    """sin of eight arguments (rad, |x| up to 1e5), four at a time in SIMD lanes: `elementary`'s
    sincos, within 2 ulp of libm's sin (tests/physics/test_elementary.py). The road relief's
    sines under the four wheels (`wheel_loads`), ~4x cheaper than eight libm calls. Not
    inlined: inlined in `kernel.advance_car`, its code (even where the road is smooth and it
    never runs) slows the sub-step by ~15 % (benchmarks/RESULTS.md, "The car sub-step on real
    tracks")."""
    lx, ly, sx, sy = el.lanes4(), el.lanes4(), el.lanes4(), el.lanes4()
    lx[0], lx[1], lx[2], lx[3] = x0, x1, x2, x3
    ly[0], ly[1], ly[2], ly[3] = y0, y1, y2, y3
    for k in range(4):
        sx[k] = el.sincos(lx[k])[0]
        sy[k] = el.sincos(ly[k])[0]
    return sx[0], sx[1], sx[2], sx[3], sy[0], sy[1], sy[2], sy[3]


@numba.njit(inline="always", **_JIT)
def _relief_terms(pt, surf, tsc, p, q, n, main):
    """`relief` of a point already on piece p (0 <= q <= its length) without its sines:
    (base, a, k t, k l, curb, d, bw) with relief = base + a sin(k l) d / bw on a curb, else
    base + a sin(k t) sin(k l) (names as in `relief`; a = 0: no roughness, relief = base)."""
    w = tsc[T_WIDTH]
    t = n + 0.5 * w                      # TORCS's toRight on the road
    m = 0.0                              # the zone's centre line, m left of the road's
    curb = False
    d = bw = rise = base = 0.0
    j = int(pt[p, P_SURF])
    if t < 0.0:                          # right border, then right side
        bw = pt[p, P_BW_R]
        t += bw
        j = int(pt[p, P_BSURF_R])
        m = -0.5 * (w + bw)
        curb = pt[p, P_CURB_R] > 0.0
        rise = pt[p, P_CURBK_R]
        d = bw - t
        if t < 0.0:
            u = min(max(q * pt[p, P_INVLEN], 0.0), 1.0)
            sw0, sw1 = pt[p, P_SW0_R], pt[p, P_SW1_R]
            if main and bw == 0.0:
                wmin = min(sw0, sw1)
                t += wmin
                if tsc[T_TANGENT_R] > 0.0:
                    b0, b1 = pt[p, P_B0], pt[p, P_B1]
                    base = (wmin * math.tan(b0 + u * (b1 - b0)) - (1.0 - u) * sw0 * math.tan(b0)
                            - u * sw1 * math.tan(b1))
            else:
                t += sw0 + u * (sw1 - sw0)
            j = int(pt[p, P_SSURF_R])
            m = -0.5 * w - bw - 0.5 * sw0
            curb = False
    elif t > w:                          # left border, then left side
        bw = pt[p, P_BW_L]
        t -= w
        j = int(pt[p, P_BSURF_L])
        m = 0.5 * (w + bw)
        curb = pt[p, P_CURB_L] > 0.0
        rise = pt[p, P_CURBK_L]
        d = t
        if t > bw:
            t -= bw
            j = int(pt[p, P_SSURF_L])
            m = 0.5 * w + bw + 0.5 * pt[p, P_SW0_L]
            curb = False
    if curb:
        base = d * rise
    a = surf[j, 2]
    k = surf[j, 3]
    return base, a, k * t, k * q * (1.0 - pt[p, P_CURV] * m), curb, d, bw


@numba.njit(inline="always", **_JIT)
def _wheel_road(cp, pt, tsc, i, k, p, q, n, cpsi, spsi):
    """Road height under wheel k of car i (its static x, y from the CG (p, q, n: `_cg_on_piece`)
    in the track frame, located by `wheel_at`), without curbs or roughness."""
    da, dn = _wheel_offset(cp, pt, i, k, p, n, cpsi, spsi)
    return _road_z(pt, tsc, p, q + da, n + dn)


@numba.njit(inline="always", **_JIT)
def _wheel_road_terms(cp, pt, surf, tsc, i, k, p, q, n, cpsi, spsi):
    """Under wheel k of car i (CG at p, q, n: `_cg_on_piece`; (cpsi, spsi): cos, sin of yaw -
    track heading): the smooth road's height (m) and the relief's `_relief_terms`."""
    da, dn = _wheel_offset(cp, pt, i, k, p, n, cpsi, spsi)
    pk, qk = on_piece(pt, p, q + da)
    nk = n + dn
    base, a, kt, kl, curb, d, bw = _relief_terms(pt, surf, tsc, pk, qk, nk, False)
    return _road_z_at(pt, tsc, pk, qk, nk), base, a, kt, kl, curb, d, bw


@numba.njit(**_JIT, _nrt=False)
def wheel_loads(st, i, cp, pt, surf, tsc, sp, cpsi, spsi, dt):
    """Vertical wheel forces of car i on the body (N, wheel order), from its suspensions and
    anti-roll bars at the body's present heave, roll and pitch over the road with its curbs and
    roughness (`relief`; docs/physics.md); sp = sin
    pitch, (cpsi, spsi) = (cos, sin) of yaw - track heading (the caller has them). Stores each
    wheel's ride height and suspension state. Returns (f0, f1, f2, f3, packer mask: bit k set
    when wheel k sits on its packers, the road gradient along and across the body (+: rising
    ahead, rising to the left) from the road heights under the four wheels); a tyre's load is
    max(f, 0)."""
    zb = st[i, S_Z] - cp[i, C_H]
    inv_dt = 1.0 / dt
    sr = math.sin(st[i, S_ROLLA])
    p, q, n = _cg_on_piece(st, i, pt, tsc)
    v0 = v1 = v2 = v3 = 0.0
    e0 = e1 = e2 = e3 = 0
    mask = 0
    # the road under each wheel (m): the smooth plane and the relief's zone per wheel (branches),
    # then, where a surface is rough, the relief's eight sines at once (`_sines4`)
    z0, b0, a0, t0, l0, c0, d0, w0 = _wheel_road_terms(cp, pt, surf, tsc, i, 0, p, q, n, cpsi, spsi)
    z1, b1, a1, t1, l1, c1, d1, w1 = _wheel_road_terms(cp, pt, surf, tsc, i, 1, p, q, n, cpsi, spsi)
    z2, b2, a2, t2, l2, c2, d2, w2 = _wheel_road_terms(cp, pt, surf, tsc, i, 2, p, q, n, cpsi, spsi)
    z3, b3, a3, t3, l3, c3, d3, w3 = _wheel_road_terms(cp, pt, surf, tsc, i, 3, p, q, n, cpsi, spsi)
    if a0 != 0.0 or a1 != 0.0 or a2 != 0.0 or a3 != 0.0:
        l0, l1, l2, l3, t0, t1, t2, t3 = _sines4(l0, l1, l2, l3, t0, t1, t2, t3)
        b0 = _relief_sum(b0, a0, t0, l0, c0, d0, w0)
        b1 = _relief_sum(b1, a1, t1, l1, c1, d1, w1)
        b2 = _relief_sum(b2, a2, t2, l2, c2, d2, w2)
        b3 = _relief_sum(b3, a3, t3, l3, c3, d3, w3)
    l_z = el.lanes4()
    l_z[0], l_z[1], l_z[2], l_z[3] = z0 + b0, z1 + b1, z2 + b2, z3 + b3
    road_fr = road_lr = 0.0       # front minus rear, left minus right sums of the road heights
    for k in range(4):
        road = l_z[k]
        road_fr += road if k < 2 else -road
        road_lr += road if k % 2 == 1 else -road
        ride = zb - cp[i, C_WX + k] * sp + cp[i, C_WY + k] * sr - road
        st[i, S_RIDE + k] = ride
        v, state = _wheel_travel(st, i, cp, k, ride, dt, inv_dt)
        if state == 1:
            mask |= 1 << k
        if k == 0:
            v0, e0 = v, state
        elif k == 1:
            v1, e1 = v, state
        elif k == 2:
            v2, e2 = v, state
        else:
            v3, e3 = v, state
    # anti-roll bars: k_arb (x_left - x_right), + on the right wheel, - on the left
    arb_f = cp[i, C_ARB] * (st[i, S_SUSP + 1] - st[i, S_SUSP])
    arb_r = cp[i, C_ARB + 1] * (st[i, S_SUSP + 3] - st[i, S_SUSP + 2])
    # the road's gradient in the body frame from the heights under the four wheels (TORCS's
    # SimCarUpdateForces): (front pair - rear pair) / (2 wheelbase), (left - right) / (2 track),
    # by the reciprocals of `kernel.car_derived`
    return (_wheel_force(st, i, cp, 0, v0, e0, arb_f, dt), _wheel_force(st, i, cp, 1, v1, e1, -arb_f, dt),
            _wheel_force(st, i, cp, 2, v2, e2, arb_r, dt), _wheel_force(st, i, cp, 3, v3, e3, -arb_r, dt),
            mask, road_fr * cp[i, C_RWB2], road_lr * cp[i, C_RTR2])


@numba.njit(**_JIT, _nrt=False)
def body_vertical(st, i, cp, inv_m, fz_sum, mx, my, dt):
    """Heave, roll and pitch of car i by one sub-step (TORCS's semi-implicit Euler, roll and
    pitch limited to +-1.04 rad); the packers' ground contact follows (`ground_contact`).
    inv_m: 1 / the car's mass, 1/kg; fz_sum: vertical force on the body without gravity, N;
    mx, my: roll and pitch moments, N m."""
    vz = st[i, S_VZ] + (fz_sum * inv_m - G) * dt
    wr = st[i, S_ROLLR] + mx * cp[i, C_RIXX] * dt
    wp = st[i, S_PITCHR] + my * cp[i, C_RIYY] * dt
    st[i, S_VZ], st[i, S_ROLLR], st[i, S_PITCHR] = vz, wr, wp
    st[i, S_Z] = st[i, S_Z] + vz * dt
    st[i, S_ROLLA] = min(max(st[i, S_ROLLA] + wr * dt, -ANGLE_MAX), ANGLE_MAX)
    st[i, S_PITCH] = min(max(st[i, S_PITCH] + wp * dt, -ANGLE_MAX), ANGLE_MAX)


@numba.njit(inline="always", **_JIT)
def surface_index(pt, p, q, nw, half):
    """Material index (row of the surface table) under a point at distance q (m, may run one
    piece over) along piece p and offset nw (m, + left); half: half the road's width, m."""
    p, q = on_piece(pt, p, q)
    over_r = -nw - half
    over_l = nw - half
    if over_r > 0.0:
        bw = pt[p, P_BW_R]
        if over_r <= bw:
            return int(pt[p, P_BSURF_R])
        u = min(max(q / pt[p, P_LEN], 0.0), 1.0)
        if over_r <= bw + pt[p, P_SW0_R] + u * (pt[p, P_SW1_R] - pt[p, P_SW0_R]):
            return int(pt[p, P_SSURF_R])
        return int(pt[p, P_WSURF_R])
    if over_l > 0.0:
        bw = pt[p, P_BW_L]
        if over_l <= bw:
            return int(pt[p, P_BSURF_L])
        u = min(max(q / pt[p, P_LEN], 0.0), 1.0)
        if over_l <= bw + pt[p, P_SW0_L] + u * (pt[p, P_SW1_L] - pt[p, P_SW0_L]):
            return int(pt[p, P_SSURF_L])
        return int(pt[p, P_WSURF_L])
    return int(pt[p, P_SURF])


@numba.njit(**_JIT)
def ground_contact(st, i, cp, pt, surf, tsc, mask, vxg, vyg, cpsi, spsi):
    """The packers' ground contact of car i (TORCS 1.3.7's SimCarCollideZ, docs/physics.md,
    "Bottoming"), wheel by wheel in wheel order for each wheel k on its packers (bit k of
    `mask`, from `wheel_loads`): the body rises to the packers (`z += packers - ride`); with n
    the road's unit normal under the wheel (the piece's slope along the track, its banking
    across) and e, d the wheel's surface's `rebound` and `dammage`, the body's velocity
    (vxg, vyg, vz; m/s) into the road `u = (v . n) e`, when negative, is taken off (`v -= u n`)
    and the car takes `int(d |u| x skill damage factor)` damage points unless it has finished
    (`takes_damage`). Not inlined: it runs
    only while a wheel is on its packers. (cpsi, spsi): cos, sin of yaw - track heading as
    `wheel_loads` had them. Returns the new (vxg, vyg), m/s; updates z, vz and the damage."""
    p, q, n = _cg_on_piece(st, i, pt, tsc)
    half = 0.5 * tsc[T_WIDTH]
    z, vz = st[i, S_Z], st[i, S_VZ]
    for k in range(4):
        if not mask & (1 << k):
            continue
        z += cp[i, C_PACK + k] - st[i, S_RIDE + k]
        da, dn = _wheel_offset(cp, pt, i, k, p, n, cpsi, spsi)
        pk, qk = on_piece(pt, p, q + da)
        nk = n + dn
        # the road's normal: the piece's chord along the track at the wheel's offset (per metre
        # of that offset's own length on a curve), its cross slope (banking) across, a curb's
        # rise on a curb
        curv = pt[pk, P_CURV]
        span = pt[pk, P_LEN] * max(1.0 - curv * nk, 0.1)
        g_along = (_road_z_at(pt, tsc, pk, pt[pk, P_LEN], nk) - _road_z_at(pt, tsc, pk, 0.0, nk)) / span
        g_across = (_road_z_at(pt, tsc, pk, qk, half) - _road_z_at(pt, tsc, pk, qk, -half)) / (2.0 * half)
        if 0.0 < nk - half <= pt[pk, P_BW_L]:          # a curb border rises outwards (`relief`)
            g_across += pt[pk, P_CURBK_L]
        elif 0.0 < -nk - half <= pt[pk, P_BW_R]:
            g_across -= pt[pk, P_CURBK_R]
        inv = 1.0 / math.sqrt(1.0 + g_along * g_along + g_across * g_across)
        heading = pt[pk, P_A0] + qk * curv
        ch, sh = math.cos(heading), math.sin(heading)
        nx = -(g_along * ch - g_across * sh) * inv          # global x, y, z of the unit normal
        ny = -(g_along * sh + g_across * ch) * inv
        j = surface_index(pt, pk, qk, nk, half)
        u = (vxg * nx + vyg * ny + vz * inv) * surf[j, SURF_REBOUND]
        if u < 0.0:
            vxg -= nx * u
            vyg -= ny * u
            vz -= inv * u
            if takes_damage(st, cp, i):
                st[i, S_DAMAGE] += math.floor(surf[j, SURF_DAMMAGE] * -u * cp[i, C_DMGK])
    st[i, S_Z], st[i, S_VZ] = z, vz
    return vxg, vyg


@numba.njit(**_JIT)
def settle(st, cp, pt, tsc, rows):
    """Put the cars `rows` at rest on their suspensions: each wheel at its static ride height
    under its present load (st's fz), the body's height, pitch and roll fitted to the four, the
    vertical velocity that follows the road (docs/physics.md). Call after `refresh`."""
    for j in range(rows.shape[0]):
        i = rows[j]
        dpsi = st[i, S_YAW] - st[i, S_THEAD]
        cpsi, spsi = math.cos(dpsi), math.sin(dpsi)
        p, q, n = _cg_on_piece(st, i, pt, tsc)
        h0 = h1 = h2 = h3 = 0.0
        for k in range(4):
            bell = cp[i, C_BELL + k]
            r = cp[i, C_RIDE0 + k] - (st[i, S_FZ + k] - cp[i, C_W0 + k]) / (cp[i, C_SPRING + k] * bell * bell)
            r = min(max(r, cp[i, C_PACK + k]), cp[i, C_COURSE + k] / bell)
            hk = r + _wheel_road(cp, pt, tsc, i, k, p, q, n, cpsi, spsi)      # body reference, global z
            if k == 0:
                h0 = hk
            elif k == 1:
                h1 = hk
            elif k == 2:
                h2 = hk
            else:
                h3 = hk
        a, b = cp[i, C_A], cp[i, C_B]
        hf, hr = 0.5 * (h0 + h1), 0.5 * (h2 + h3)
        sp = min(max((hr - hf) / (a + b), -0.8), 0.8)
        sr = min(max(0.5 * ((h1 - h0) / (cp[i, C_WY + 1] - cp[i, C_WY])
                            + (h3 - h2) / (cp[i, C_WY + 3] - cp[i, C_WY + 2])), -0.8), 0.8)
        zb = (b * hf + a * hr) / (a + b)
        st[i, S_PITCH] = math.asin(sp)
        st[i, S_ROLLA] = math.asin(sr)
        st[i, S_Z] = zb + cp[i, C_H]
        st[i, S_VZ] = st[i, S_GX] * st[i, S_VXG] + st[i, S_GY] * st[i, S_VYG]
        st[i, S_ROLLR] = st[i, S_PITCHR] = 0.0
        for k in range(4):
            ride = (zb - cp[i, C_WX + k] * sp + cp[i, C_WY + k] * sr
                    - _wheel_road(cp, pt, tsc, i, k, p, q, n, cpsi, spsi))
            st[i, S_RIDE + k] = ride
            st[i, S_SUSP + k] = min(max(ride, cp[i, C_PACK + k]) * cp[i, C_BELL + k], cp[i, C_COURSE + k])
            st[i, S_WVZ + k] = 0.0
