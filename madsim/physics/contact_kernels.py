"""Compiled kernels of the contact layer (see `madsim.physics.contact` for the model).

Broad phase (walls by a conservative clearance, cars by box overlap on a neighbour list), the
TORCS response rules (spec torcs-car-format.md 4.12) applied to pymunk's contacts, and the
position-only settling passes. Plain loops over cars on arrays, car axis first, compiled with
numba; no pymunk here.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from madsim.physics.kernel import NO_REFCOUNT, YAW_RATE_MAX, advance_car
from madsim.physics.layout import CONTROL_COLUMNS, N_STATE, S_PIECE, S_R, S_VXG, S_VYG, S_X, S_Y, S_YAW
from madsim.facts import SUBSTEP_S
from madsim.tracks.kernels import GEO_A0, GEO_KIND, GEO_LEN, GEO_R, GEO_S0, locate_from

# --- TORCS response constants (spec torcs-car-format.md 4.12) ---------------------------------
WALL_YAW_SCALE = 10.0       # yaw-rate change divisor of the wall friction term
WALL_YAW_MAX = 6.0          # rad/s, cap after a wall friction term
CAR_YAW_MAX = 3.0           # rad/s, cap after a car-car impulse
CAR_DAMAGE_PER_NS = 0.1     # damage points per N s of impulse
FRONTAL_FACTOR = 1.5        # car-car damage factor for hits within +-60 deg of the nose
FRONTAL_HALF_ANGLE = math.pi / 3.0
SKILL_SEMI_PRO = 0.8        # TORCS damage skill factor (rookie 0, amateur 0.5, semi-pro 0.8, pro 1)
PIT_WALL_E = 1.0            # pit walls: restitution of the impulse (elastic)
PIT_WALL_ROT_K = 0.5        # pit walls: share of the impulse's yaw-rate change that is applied
PIT_WALL_DAMAGE_K = 2e-5    # pit walls: damage = CAR_DAMAGE_PER_NS x this x j^2 (x frontal, skill)
MAT_PIT_WALL = -1           # "surface index" of the pit walls' material body
PIT_CAP_COS = 0.7           # a pit-wall contact normal this close to the track direction is a cap's
PIT_CAP_REACH_M = 0.5       # ... and is kept only this close to an end of the wall
CORNER_ORDER = (3, 0, 2, 1)  # TORCS's corner order (FR, FL, RR, RL) as `_corner`'s k
# Every hit adds its damage as a whole number of points, the fraction dropped (TORCS 1.3.7 adds
# `(int)` of each barrier, pit-wall and car-car hit's damage: `_whole_points`). So a car
# resting against a wall, which hits it at a few cm/s every step, gains no damage.

# --- solver tuning ----------------------------------------------------------------------------
SLOP_M = 1e-3               # extra separation beyond the measured penetration
BACKSTOP_M = 0.5            # settling pushes a box back inside only when a corner is this far out
MIN_RADIUS_M = 0.5          # inner barrier radii are taken as at least this
LEVEL_STRETCH_MAX = 20.0    # cars closer than (rad_i + rad_j) x this along the track are on one level
OTHER_LEVEL_M = 0.1         # a wall contact whose car point is this far inside its own barrier
                            # line belongs to another part of the track (bridges): ignored
WALL_REACH_M = 0.02         # broad phase: consult pymunk when this close to a barrier (+ bulge)
CAR_REACH_M = 0.0          # broad phase: consult pymunk when boxes overlap (contacts act after penetration)
SKIN_M = 6.0                # neighbour-list skin
REBUILD_M = 2.0             # rebuild the neighbour list when a car moved this far (< SKIN_M / 2)
WINDOW_SLACK_M = 5.0        # extra barrier look-ahead that lets a wall clearance be reused
SETTLE_ITERS = 16            # position-only passes over what is left after the pymunk contacts
IDLE_CALLS = 50             # consultations a car stays in the pymunk space after its last contact

B_PIT = 5                   # first pit-wall column of the per-piece barrier table
# columns of the per-car constant table
C_HL, C_HW, C_RAD, C_MASS, C_IZZ, C_GAIN, C_WIN = range(7)
# entries of the scalar parameter array
(P_LENGTH, P_MOVE_CAP, P_RMAX, P_E_CAR, P_SKILL, P_STRETCH, P_CHORD2, P_PIT) = range(8)
N_PRM = P_PIT + 1   # length of a contact solver's parameter row


# --- compiled kernels ------------------------------------------------------------------------------
# All take the car axis first and assume boxes centred on (x, y), yaw = heading of the box's
# long axis, and the track's piece geometry `geo` (madsim.tracks.kernels).


@numba.njit(cache=True, inline="always")
def _wrap(a):
    return a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))


@numba.njit(cache=True)
def _heading(geo, i, q):
    """Centre-line heading of piece i at q metres from its start."""
    kind = geo[i, GEO_KIND]
    if kind == 0.0:
        return geo[i, GEO_A0]
    if kind == 1.0:
        return geo[i, GEO_A0] + q / geo[i, GEO_R]
    return geo[i, GEO_A0] - q / geo[i, GEO_R]


@numba.njit(cache=True)
def _barrier_min(geo, bar, i, q, reach, pit, n, lat):
    """Smallest (left, right) barrier offset, smallest inner barrier radius over s in
    [s(i, q) - reach, s(i, q) + reach] and, if `pit`, the smallest lateral gap (m) between the
    span [n - lat, n + lat] and a pit wall's strip on a piece in that window (inf if none)."""
    npieces = geo.shape[0]
    bl, br, rc, gap = np.inf, np.inf, np.inf, np.inf
    for direction in (-1, 1):
        j = i
        lo = q - reach if direction < 0 else q
        hi = q if direction < 0 else q + reach
        for _ in range(npieces):
            ln = geo[j, GEO_LEN]
            a = min(max(lo, 0.0), ln) / ln
            b = min(max(hi, 0.0), ln) / ln
            for u in (a, b):
                bl = min(bl, bar[j, 0] + u * (bar[j, 1] - bar[j, 0]))
                br = min(br, bar[j, 2] + u * (bar[j, 3] - bar[j, 2]))
            rc = min(rc, bar[j, 4])
            if pit:
                gap = min(gap, max(bar[j, B_PIT] - (n + lat), (n - lat) - bar[j, B_PIT + 1]),
                          max(bar[j, B_PIT + 2] - (lat - n), (-n - lat) - bar[j, B_PIT + 3]))
            if direction < 0:
                if lo >= 0.0:
                    break
                j = j - 1 if j > 0 else npieces - 1
                lo += geo[j, GEO_LEN]
                hi = geo[j, GEO_LEN]
            else:
                if hi <= ln:
                    break
                hi -= ln
                lo = 0.0
                j = j + 1 if j < npieces - 1 else 0
    return bl, br, rc, gap


@numba.njit(cache=True)
def _wall_margin(geo, bar, cars, prm, i, x, y, yaw, hint):
    """Conservative clearance (m) between car i's box and the nearest barrier line or pit wall,
    minus what pymunk may already call a contact: the lateral extent of the box at the car's
    track position against the narrowest barrier offset within reach (and the lateral gap to
    the strip of any pit wall within reach, whichever side of it the car is on), less the bulge
    of a curved barrier over the box (rad^2 / 2 r), the polylines' chord error (chord^2 / 8 r)
    and WALL_REACH_M. <= 0: consult pymunk."""
    p, q, n = locate_from(geo, hint, x, y)
    psi = yaw - _heading(geo, p, q)
    lat = cars[i, C_HL] * abs(math.sin(psi)) + cars[i, C_HW] * abs(math.cos(psi))
    bl, br, rc, gap = _barrier_min(geo, bar, p, q, cars[i, C_WIN], prm[P_PIT] != 0.0, n, lat)
    bulge = (cars[i, C_RAD] ** 2 / 2.0 + prm[P_CHORD2] / 8.0) / rc
    return min(bl - (n + lat), br - (lat - n), gap) - bulge - WALL_REACH_M


@numba.njit(cache=True)
def _obb_sep(x, y, yaw, cars, i, j):
    """Largest separating-axis gap between the boxes of cars i and j (m; < 0 = overlap, then
    its magnitude is the smallest penetration) and that axis, pointing from i towards j."""
    ci, si = math.cos(yaw[i]), math.sin(yaw[i])
    cj, sj = math.cos(yaw[j]), math.sin(yaw[j])
    dx, dy = x[j] - x[i], y[j] - y[i]
    gap, bx, by = -np.inf, 1.0, 0.0
    for k in range(4):
        if k == 0:
            ax, ay = ci, si
        elif k == 1:
            ax, ay = -si, ci
        elif k == 2:
            ax, ay = cj, sj
        else:
            ax, ay = -sj, cj
        ri = cars[i, C_HL] * abs(ci * ax + si * ay) + cars[i, C_HW] * abs(ci * ay - si * ax)
        rj = cars[j, C_HL] * abs(cj * ax + sj * ay) + cars[j, C_HW] * abs(cj * ay - sj * ax)
        proj = dx * ax + dy * ay
        g = abs(proj) - ri - rj
        if g > gap:
            gap = g
            bx, by = (ax, ay) if proj >= 0.0 else (-ax, -ay)
    return gap, bx, by


@numba.njit(cache=True)
def _build_pairs(x, y, cars, rmax, vref, pairs):
    """Neighbour list: all pairs i < j with centre distance < rad_i + rad_j + SKIN_M, found
    through a hashed uniform grid. Returns the count, or -1 if `pairs` is too small."""
    n = x.shape[0]
    cell = 2.0 * rmax + SKIN_M
    size = 1
    while size < 2 * n:
        size *= 2
    cx = np.empty(n, dtype=np.int64)
    cy = np.empty(n, dtype=np.int64)
    h = np.empty(n, dtype=np.int64)
    start = np.zeros(size + 1, dtype=np.int64)
    for i in range(n):
        fx, fy = x[i] / cell, y[i] / cell
        cx[i] = math.floor(fx) if abs(fx) < 1e15 else 0
        cy[i] = math.floor(fy) if abs(fy) < 1e15 else 0
        h[i] = ((cx[i] * 73856093) ^ (cy[i] * 19349663)) & (size - 1)
        start[h[i] + 1] += 1
        vref[i, 0], vref[i, 1] = x[i], y[i]
    for b in range(size):
        start[b + 1] += start[b]
    fill = start.copy()
    items = np.empty(n, dtype=np.int64)
    for i in range(n):
        items[fill[h[i]]] = i
        fill[h[i]] += 1
    count = 0
    for i in range(n):
        for ox in range(-1, 2):
            for oy in range(-1, 2):
                gx, gy = cx[i] + ox, cy[i] + oy
                b = ((gx * 73856093) ^ (gy * 19349663)) & (size - 1)
                for k in range(start[b], start[b + 1]):
                    j = items[k]
                    if j <= i or cx[j] != gx or cy[j] != gy:
                        continue
                    reach = cars[i, C_RAD] + cars[j, C_RAD] + SKIN_M
                    if (x[j] - x[i]) ** 2 + (y[j] - y[i]) ** 2 < reach * reach:
                        if count >= pairs.shape[0]:
                            return -1
                        pairs[count, 0], pairs[count, 1] = i, j
                        count += 1
    return count


@numba.njit(cache=True)
def _broad_phase(x, y, yaw, piece, geo, bar, cars, prm, wall_cache, vref, pairs, meta, flags, slack):
    """Flag cars near a barrier (bit 1) or overlapping another car (bit 2); `slack`: clearance
    to the barriers beyond the reach allowance that is guaranteed now (m, 0 if near). Returns
    the number of flagged cars, -1 if `pairs` overflowed, -2 - i if car i's piece index is out
    of range. Updates the clearance cache and the neighbour list. Cars with a non-finite pose
    are ignored."""
    n = x.shape[0]
    move_cap = prm[P_MOVE_CAP]
    near = 0
    for i in range(n):
        flags[i] = 0
        if piece[i] < 0 or piece[i] >= geo.shape[0]:
            return -2 - i
        if not (math.isfinite(x[i]) and math.isfinite(y[i]) and math.isfinite(yaw[i])):
            slack[i] = 0.0
            continue          # a car whose state went bad touches nothing (and is not located)
        # (plain 2-D indexing, no row views: views cost reference counting in this loop)
        moved = math.sqrt((x[i] - wall_cache[i, 0]) ** 2 + (y[i] - wall_cache[i, 1]) ** 2)
        used = cars[i, C_GAIN] * moved + cars[i, C_RAD] * abs(_wrap(yaw[i] - wall_cache[i, 2]))
        if moved < move_cap and used < wall_cache[i, 3]:
            slack[i] = wall_cache[i, 3] - used   # its clearance cannot be used up yet
            continue
        margin = _wall_margin(geo, bar, cars, prm, i, x[i], y[i], yaw[i], piece[i])
        slack[i] = max(margin, 0.0)
        if margin > 0.0 and move_cap > 0.0:
            wall_cache[i, 0], wall_cache[i, 1], wall_cache[i, 2] = x[i], y[i], yaw[i]
            wall_cache[i, 3] = margin
        else:
            wall_cache[i, 3] = -1.0
        if margin <= 0.0:
            flags[i] = 1
            near += 1
    if n < 2:
        return near
    rebuild = meta[0] == 0
    if not rebuild:
        for i in range(n):
            if (x[i] - vref[i, 0]) ** 2 + (y[i] - vref[i, 1]) ** 2 > REBUILD_M * REBUILD_M:
                rebuild = True
                break
    if rebuild:
        count = _build_pairs(x, y, cars, prm[P_RMAX], vref, pairs)
        if count < 0:
            return -1
        meta[0], meta[1] = 1, count
        meta[2] += 1
    for k in range(meta[1]):
        i, j = pairs[k, 0], pairs[k, 1]
        reach = cars[i, C_RAD] + cars[j, C_RAD] + CAR_REACH_M
        if (x[j] - x[i]) ** 2 + (y[j] - y[i]) ** 2 > reach * reach:
            continue
        if (_obb_sep(x, y, yaw, cars, i, j)[0] < CAR_REACH_M
                and _same_level(geo, prm, cars, piece, x, y, i, j)):
            for m in (i, j):
                if flags[m] == 0:
                    near += 1
                flags[m] |= 2
    return near


WHOLE_EPS_M = 1e-6          # rounding allowance of `tick_clear`'s bounds, m (and rad)


@numba.njit(cache=True, inline="always")
def _wall_outlasts(i, x, y, yaw, cars, prm, wall_cache, path, turn):
    """True if car i's cached wall clearance outlasts a motion from (x, y, yaw)[i] along a path
    of at most path[i] m turning at most turn[i] rad (`tick_clear`'s test of one car; False for
    a bad pose or bound)."""
    if not (math.isfinite(x[i]) and math.isfinite(y[i]) and math.isfinite(yaw[i])
            and path[i] >= 0.0 and turn[i] >= 0.0):     # NaN bounds fail here too
        return False
    moved = math.sqrt((x[i] - wall_cache[i, 0]) ** 2 + (y[i] - wall_cache[i, 1]) ** 2)
    moved += path[i] + WHOLE_EPS_M
    spun = abs(_wrap(yaw[i] - wall_cache[i, 2])) + turn[i] + WHOLE_EPS_M
    return moved < prm[P_MOVE_CAP] and cars[i, C_GAIN] * moved + cars[i, C_RAD] * spun < wall_cache[i, 3]


@numba.njit(cache=True, inline="always")
def _stays_listed(i, x, y, vref, path):
    """True if car i, moving at most path[i] m, cannot leave its neighbour-list reference by
    REBUILD_M (no rebuild on its account)."""
    away = math.sqrt((x[i] - vref[i, 0]) ** 2 + (y[i] - vref[i, 1]) ** 2)
    return away + path[i] + WHOLE_EPS_M < REBUILD_M


@numba.njit(cache=True, inline="always")
def _stays_apart(i, j, x, y, cars, path_i, path_j):
    """True if cars i and j, moving at most path_i and path_j m, stay farther apart than their
    bounding circles plus CAR_REACH_M (the broad phase's first pair test skips them)."""
    gap = math.sqrt((x[j] - x[i]) ** 2 + (y[j] - y[i]) ** 2) - path_i - path_j
    return gap - WHOLE_EPS_M > cars[i, C_RAD] + cars[j, C_RAD] + CAR_REACH_M


@numba.njit(cache=True, **NO_REFCOUNT)
def tick_clear(x, y, yaw, cars, prm, wall_cache, vref, pairs, meta, path, turn):
    """True if `_broad_phase` (same arguments) can flag no car and change no cache while each
    car i, from the pose (x, y, yaw)[i], moves along a path of at most path[i] m and turns by at
    most turn[i] rad: every cached wall clearance outlasts the motion, no car leaves its
    neighbour-list reference by REBUILD_M, and every listed pair stays farther apart than its
    bounding circles. Then its calls at each point of that motion would only have set `flags`
    to 0 and `slack`, which one call at the end sets as they would. False if unsure (a bad
    pose or bound, a neighbour list to build)."""
    n = x.shape[0]
    for i in range(n):
        if not _wall_outlasts(i, x, y, yaw, cars, prm, wall_cache, path, turn):
            return False
    if n < 2:
        return True
    if meta[0] == 0:
        return False
    for i in range(n):
        if not _stays_listed(i, x, y, vref, path):
            return False
    for k in range(meta[1]):
        i, j = pairs[k, 0], pairs[k, 1]
        if not _stays_apart(i, j, x, y, cars, path[i], path[j]):
            return False
    return True


@numba.njit(cache=True)
def _membership(flags, member, idle, add, drop):
    """Which cars enter the pymunk space (flagged, not yet in) and which leave (idle for more
    than IDLE_CALLS consultations). Updates `member` and `idle`; returns the two counts."""
    n_add = n_drop = 0
    for i in range(flags.shape[0]):
        if flags[i]:
            idle[i] = 0
            if not member[i]:
                member[i] = True
                add[n_add] = i
                n_add += 1
        elif member[i]:
            idle[i] += 1
            if idle[i] > IDLE_CALLS:
                member[i] = False
                drop[n_drop] = i
                n_drop += 1
    return n_add, n_drop


@numba.njit(cache=True)
def _fill_poses(slots, x, y, yaw, poses):
    """pymunk.batch pose buffer (x, y, angle per body, in space order; static rows untouched)."""
    for k in range(slots.shape[0]):
        i = slots[k]
        if i >= 0 and math.isfinite(x[i]) and math.isfinite(y[i]) and math.isfinite(yaw[i]):
            poses[3 * k], poses[3 * k + 1], poses[3 * k + 2] = x[i], y[i], yaw[i]
        elif i >= 0:          # never hand pymunk a NaN: park the body far from everything
            poses[3 * k], poses[3 * k + 1], poses[3 * k + 2] = -1e7 - 10.0 * k, -1e7, 0.0


@numba.njit(cache=True)
def _membership_poses(flags, member, idle, add, drop, slots, x, y, yaw, poses):
    """`_membership`, then `_fill_poses` when no car enters or leaves (the usual consultation:
    the space's body order stands); returns the two counts."""
    n_add, n_drop = _membership(flags, member, idle, add, drop)
    if n_add == 0 and n_drop == 0:
        _fill_poses(slots, x, y, yaw, poses)
    return n_add, n_drop


_UNKNOWN = -(1 << 40)


@numba.njit(cache=True)
def _code(keys, codes, body_id):
    """Car index (>= 0) or -1 - material of a pymunk body id; _UNKNOWN if not ours."""
    k = np.searchsorted(keys, body_id)
    if k < keys.shape[0] and keys[k] == body_id:
        return codes[k]
    return _UNKNOWN


@numba.njit(cache=True)
def _corner(x, y, yaw, cars, i, k):
    """Corner k (0..3) of car i's box, global frame."""
    sx = 1.0 if k == 0 or k == 3 else -1.0
    sy = 1.0 if k < 2 else -1.0
    c, s = math.cos(yaw[i]), math.sin(yaw[i])
    lx, ly = sx * cars[i, C_HL], sy * cars[i, C_HW]
    return x[i] + lx * c - ly * s, y[i] + lx * s + ly * c


@numba.njit(cache=True)
def _corner_excess(geo, bar, x, y, yaw, piece, cars, i, k):
    """How far corner k of car i is beyond the exact barrier line (m, <= 0 inside) and the
    unit inward normal there (TORCS's corner test, track spec 10.1)."""
    px, py = _corner(x, y, yaw, cars, i, k)
    return _point_excess(geo, bar, piece[i], px, py)


@numba.njit(cache=True)
def _point_excess(geo, bar, hint, px, py):
    """How far a point is beyond the nearer barrier line (m, <= 0 inside, measured across the
    track as TORCS's toLeft / toRight), located by walking from piece `hint`, and the unit
    inward normal there: the track's lateral direction, tilted by the barrier line's slope
    along the piece where its offset changes (a side that widens or narrows), as TORCS's
    per-segment barrier normal, normal to the side's outer edge (docs/physics.md)."""
    p, q, n = locate_from(geo, hint, px, py)
    length = geo[p, GEO_LEN]
    u = min(max(q / length, 0.0), 1.0)
    a = _heading(geo, p, q)
    sa, ca = math.sin(a), math.cos(a)
    kind = geo[p, GEO_KIND]
    curv = 0.0 if kind == 0.0 else (1.0 / geo[p, GEO_R] if kind == 1.0 else -1.0 / geo[p, GEO_R])
    if n >= 0.0:
        b = bar[p, 0] + u * (bar[p, 1] - bar[p, 0])
        slope = (bar[p, 1] - bar[p, 0]) / (length * max(1.0 - curv * b, 0.1))   # d offset / d arc
        k = 1.0 / math.sqrt(1.0 + slope * slope)
        return n - b, (slope * ca + sa) * k, (slope * sa - ca) * k
    b = bar[p, 2] + u * (bar[p, 3] - bar[p, 2])
    slope = (bar[p, 3] - bar[p, 2]) / (length * max(1.0 + curv * b, 0.1))
    k = 1.0 / math.sqrt(1.0 + slope * slope)
    return -n - b, (slope * ca - sa) * k, (slope * sa + ca) * k


@numba.njit(cache=True, inline="always")
def _whole_points(dmg):
    """One hit's damage as TORCS adds it: the fraction dropped (dmg >= 0; NaN stays NaN)."""
    return np.floor(dmg)


@numba.njit(cache=True, inline="always")
def _barrier_rule(i, nx, ny, vn, lx, ly, mat, vx, vy, w, prm, damage):
    """TORCS barrier rule (car spec 4.12 steps 2-6) for car i: wall normal (nx, ny) pointing away
    from the wall, vn the hit point's speed along it (< 0: into the wall), (lx, ly) the friction
    term's lever (the point from the centre), material row `mat` = (friction, rebound,
    dammage). The speed behind the damage is the car's velocity as it is."""
    speed = max(1.0, math.sqrt(vx[i] * vx[i] + vy[i] * vy[i]))
    vcn = vx[i] * nx + vy[i] * ny
    cosa = vcn / speed
    kf = mat[0] * vn
    vx[i] -= nx * kf
    vy[i] -= ny * kf
    w[i] -= (nx * lx + ny * ly) * kf / WALL_YAW_SCALE
    w[i] = min(max(w[i], -WALL_YAW_MAX), WALL_YAW_MAX)
    if vn < 0.0:
        damage[i] += _whole_points(mat[2] * (0.5 * (cosa * vcn) ** 2 + 0.005 * abs(1.0 - cosa) * speed)
                                   * prm[P_SKILL])
        vx[i] -= nx * vn * mat[1]
        vy[i] -= ny * vn * mat[1]


@numba.njit(cache=True)
def _wall_response(i, nx, ny, px, py, mat, x, y, vx, vy, w, prm, damage):
    """TORCS barrier rule once for car i at point (px, py) (`_barrier_rule`: the point's speed
    along the normal from the car's velocities as they are)."""
    rx, ry = px - x[i], py - y[i]
    vn = (vx[i] - w[i] * ry) * nx + (vy[i] + w[i] * rx) * ny
    _barrier_rule(i, nx, ny, vn, rx, ry, mat, vx, vy, w, prm, damage)


@numba.njit(cache=True)
def _barrier_corners(i, a, e, order, rk, ro, rf, x, y, yaw, vx, vy, w, piece, cars, mat, geo, bar,
                     prm, damage):
    """TORCS's barrier rule once per corner of car i's box beyond the exact barrier line, where
    TORCS 1.3's SimCarCollideXYScene looks: at the box as it was at the start of the sub-step
    (SimCarUpdateCornerPos runs after the velocities are updated but before SimCarUpdatePos
    moves the car), i.e. the box moved back by this sub-step's velocities x SUBSTEP_S. The
    corners in TORCS's order (front right, front left, rear right, rear left); each corner's
    into-wall speed from the new velocities at that start-of-step corner (the same for every
    corner of the step), the centre (as moved) pushed out by each corner's own depth in turn,
    the lever arm of the friction term from the start-of-step corner to that pushed centre,
    and the speed behind the damage from the velocity as the corners before it left it; each
    corner's damage cut to whole points. A corner takes the material of the barrier contact
    (records a..e of `order`) whose normal is nearest its own; a corner with no barrier
    contact on its side (normals apart) is skipped. Returns the corners responded."""
    v0x, v0y, w0 = vx[i], vy[i], w[i]
    sx, sy, syaw = x[i] - v0x * SUBSTEP_S, y[i] - v0y * SUBSTEP_S, yaw[i] - w0 * SUBSTEP_S
    c, s = math.cos(syaw), math.sin(syaw)
    gx, gy = x[i], y[i]
    done = 0
    for t in range(4):
        k = CORNER_ORDER[t]
        lx = (1.0 if k == 0 or k == 3 else -1.0) * cars[i, C_HL]
        ly = (1.0 if k < 2 else -1.0) * cars[i, C_HW]
        r0x, r0y = lx * c - ly * s, lx * s + ly * c
        cx, cy = sx + r0x, sy + r0y
        excess, nx, ny = _point_excess(geo, bar, piece[i], cx, cy)
        if excess <= 0.0:
            continue
        g, best = -1, 0.0
        for b in range(a, e):
            r = order[b]
            if rk[r] != 0 or mat[ro[r], 3] != 0.0:
                continue
            dot = rf[r, 0] * nx + rf[r, 1] * ny
            if dot > best:
                g, best = r, dot
        if g < 0:
            continue
        m = mat[ro[g]]
        # into-wall speed of the start-of-step corner from the velocities before the response
        vn = (v0x - w0 * r0y) * nx + (v0y + w0 * r0x) * ny
        gx += nx * excess
        gy += ny * excess
        _barrier_rule(i, nx, ny, vn, cx - gx, cy - gy, m, vx, vy, w, prm, damage)
        done += 1
    x[i], y[i] = gx, gy
    return done


@numba.njit(cache=True)
def _any_corner_beyond(geo, bar, x, y, yaw, piece, cars, i):
    """Whether a corner of car i's box (as it is) is beyond the exact barrier line."""
    for k in range(4):
        if _corner_excess(geo, bar, x, y, yaw, piece, cars, i, k)[0] > 0.0:
            return True
    return False


@numba.njit(cache=True)
def _pit_cap_ok(geo, bar, hint, px, py, nx, ny):
    """False for a pit-wall contact at (px, py) whose normal (nx, ny) runs along the track
    (|n . t| > PIT_CAP_COS) with no end of that wall within PIT_CAP_REACH_M of the point: pymunk
    hitting the seam between two segments of one face, not an end cap."""
    p, q, n = locate_from(geo, hint, px, py)
    a = _heading(geo, p, q)
    if abs(nx * math.cos(a) + ny * math.sin(a)) <= PIT_CAP_COS:
        return True
    col = B_PIT if n >= 0.0 else B_PIT + 2
    last = geo.shape[0] - 1
    if not math.isfinite(bar[p, col]):
        return True
    if q < PIT_CAP_REACH_M and not math.isfinite(bar[p - 1 if p > 0 else last, col]):
        return True
    return q > geo[p, GEO_LEN] - PIT_CAP_REACH_M and not math.isfinite(bar[p + 1 if p < last else 0, col])


@numba.njit(cache=True)
def _pit_wall_response(i, nx, ny, px, py, x, y, yaw, vx, vy, w, cars, prm, damage):
    """TORCS pit-wall rule (car spec 4.12) for car i at point (px, py), wall normal (nx, ny)
    pointing away from the wall, if the point moves into the wall: the impulse of an elastic
    hit on an immovable wall, j = -(1 + e) vn / (1/m + (r x n)^2 / I), on the velocity in full
    and on the yaw rate times PIT_WALL_ROT_K (|r| <= CAR_YAW_MAX after), and damage
    CAR_DAMAGE_PER_NS x PIT_WALL_DAMAGE_K x j^2 (x FRONTAL_FACTOR within +-60 deg of the
    nose) x skill."""
    rx, ry = px - x[i], py - y[i]
    vn = (vx[i] - w[i] * ry) * nx + (vy[i] + w[i] * rx) * ny
    if vn >= 0.0:
        return
    cr = rx * ny - ry * nx
    jn = -(1.0 + PIT_WALL_E) * vn / (1.0 / cars[i, C_MASS] + cr * cr / cars[i, C_IZZ])
    vx[i] += jn * nx / cars[i, C_MASS]
    vy[i] += jn * ny / cars[i, C_MASS]
    w[i] = min(max(w[i] + PIT_WALL_ROT_K * jn * cr / cars[i, C_IZZ], -CAR_YAW_MAX), CAR_YAW_MAX)
    c, s = math.cos(yaw[i]), math.sin(yaw[i])
    ang = math.atan2(-rx * s + ry * c, rx * c + ry * s)
    factor = FRONTAL_FACTOR if abs(ang) < FRONTAL_HALF_ANGLE else 1.0
    damage[i] += _whole_points(CAR_DAMAGE_PER_NS * PIT_WALL_DAMAGE_K * jn * jn * factor * prm[P_SKILL])


@numba.njit(cache=True)
def _car_response(i, j, nx, ny, px, py, x, y, yaw, vx, vy, w, cars, prm, damage):
    """Car-car impulse at (px, py) along (nx, ny) (pushing i away from j) if the points
    approach. Returns the impulse, N s (0 when separating)."""
    rix, riy = px - x[i], py - y[i]
    rjx, rjy = px - x[j], py - y[j]
    vrx = (vx[i] - w[i] * riy) - (vx[j] - w[j] * rjy)
    vry = (vy[i] + w[i] * rix) - (vy[j] + w[j] * rjx)
    vrn = vrx * nx + vry * ny
    if vrn >= 0.0:
        return 0.0
    ci = rix * ny - riy * nx
    cj = rjx * ny - rjy * nx
    k = (1.0 / cars[i, C_MASS] + 1.0 / cars[j, C_MASS] + ci * ci / cars[i, C_IZZ]
         + cj * cj / cars[j, C_IZZ])
    jn = -(1.0 + prm[P_E_CAR]) * vrn / k
    for m, sign, cr, rx, ry in ((i, 1.0, ci, rix, riy), (j, -1.0, cj, rjx, rjy)):
        vx[m] += sign * jn * nx / cars[m, C_MASS]
        vy[m] += sign * jn * ny / cars[m, C_MASS]
        w[m] = min(max(w[m] + sign * jn * cr / cars[m, C_IZZ], -CAR_YAW_MAX), CAR_YAW_MAX)
        c, s = math.cos(yaw[m]), math.sin(yaw[m])
        ang = math.atan2(-rx * s + ry * c, rx * c + ry * s)
        factor = FRONTAL_FACTOR if abs(ang) < FRONTAL_HALF_ANGLE else 1.0
        damage[m] += _whole_points(CAR_DAMAGE_PER_NS * jn * factor * prm[P_SKILL])
    return jn


@numba.njit(cache=True)
def _respond(ints, floats, keys, codes, x, y, yaw, vx, vy, w, piece, cars, mat, geo, bar, prm,
             wall, car, damage, blocked, moved, travel, pair_out):
    """Apply the contacts pymunk found (batch arbiter arrays: velocities, damage, separation).
    Returns the number of car pairs written to `pair_out`."""
    blocked[:] = False
    moved[:] = False
    travel[:] = 0.0
    count = 0
    narb = ints.shape[0] // 3
    # records: car i, kind (0 wall, 1 car), other (material or car j), normal, point, depth
    ri = np.empty(narb, dtype=np.int64)
    rk = np.empty(narb, dtype=np.int64)
    ro = np.empty(narb, dtype=np.int64)
    rf = np.empty((narb, 5))
    nrec = 0
    for a in range(narb):
        ca = _code(keys, codes, ints[3 * a])
        cb = _code(keys, codes, ints[3 * a + 1])
        cnt = ints[3 * a + 2]
        f = floats[12 * a: 12 * a + 12]
        nx, ny = f[0], f[1]
        dmax, best = 0.0, -1
        for c in range(cnt):
            if -f[6 + 5 * c] > dmax:
                dmax, best = -f[6 + 5 * c], c
        if best < 0 or ca == _UNKNOWN or cb == _UNKNOWN:
            continue
        if ca >= 0 and cb >= 0:               # car-car: i < j, normal pushes i away from j
            i, j = min(ca, cb), max(ca, cb)
            if not _same_level(geo, prm, cars, piece, x, y, i, j):
                continue
            sgn = -1.0 if i == ca else 1.0
            px = py = 0.0
            for c in range(cnt):
                px += 0.5 * (f[2 + 5 * c] + f[4 + 5 * c]) / cnt
                py += 0.5 * (f[3 + 5 * c] + f[5 + 5 * c]) / cnt
            ri[nrec], rk[nrec], ro[nrec] = i, 1, j
            rf[nrec, 0], rf[nrec, 1], rf[nrec, 2], rf[nrec, 3], rf[nrec, 4] = sgn * nx, sgn * ny, px, py, dmax
        elif ca < 0 and cb >= 0 or ca >= 0 and cb < 0:   # wall: normal away from the wall
            i, m = (cb, -1 - ca) if cb >= 0 else (ca, -1 - cb)
            sgn = 1.0 if cb >= 0 else -1.0
            off = 4 if cb >= 0 else 2                     # the car-side point
            px, py = f[off + 5 * best], f[off + 1 + 5 * best]
            if cnt == 2 and abs(f[6] - f[11]) < 1e-9:   # flat contact: middle of the two points
                px, py = 0.5 * (f[off] + f[off + 5]), 0.5 * (f[off + 1] + f[off + 6])
            nx, ny = sgn * nx, sgn * ny
            if mat[m, 3] == 0.0:      # a barrier (pit walls are hit from either side)
                excess, sx, sy = _point_excess(geo, bar, piece[i], px, py)
                dot = nx * sx + ny * sy
                if excess < -OTHER_LEVEL_M or dot <= 0.0:
                    continue     # another level's wall, or seen from behind: the projection handles it
                # TORCS's barrier normal: the track's lateral direction there (tilted where the
                # side's width changes), never the normal pymunk found at a joint of the
                # polyline; the depth along it
                nx, ny, dmax = sx, sy, max(excess, dmax * dot)
            elif not _pit_cap_ok(geo, bar, piece[i], px, py, nx, ny):
                continue         # a seam between two segments of one pit wall's face
            ri[nrec], rk[nrec], ro[nrec] = i, 0, m
            rf[nrec, 0], rf[nrec, 1], rf[nrec, 2], rf[nrec, 3], rf[nrec, 4] = nx, ny, px, py, dmax
        else:
            continue
        nrec += 1
    # canonical order (insertion sort on car, kind, other, point): independent of pymunk's order
    order = np.arange(nrec)
    for a in range(1, nrec):
        b = a
        while b > 0 and _rec_less(ri, rk, ro, rf, order[b], order[b - 1]):
            order[b], order[b - 1] = order[b - 1], order[b]
            b -= 1
    # walls: per car, the barrier rule per corner of the start-of-step box beyond the line,
    # each pushing the centre in by its depth (TORCS); the pit-wall rule (and the barrier rule
    # where no corner is beyond the line) per direction at its deepest point, pushed out by it
    used = np.zeros(nrec, dtype=np.bool_)
    a = 0
    while a < nrec:
        i = ri[order[a]]
        e = a
        while e < nrec and ri[order[e]] == i and rk[order[e]] == 0:
            e += 1
        if e == a:
            a += 1
            continue
        pushx = pushy = 0.0
        corners = _barrier_corners(i, a, e, order, rk, ro, rf, x, y, yaw, vx, vy, w, piece, cars, mat,
                                   geo, bar, prm, damage)
        beyond = corners == 0 and _any_corner_beyond(geo, bar, x, y, yaw, piece, cars, i)
        while True:
            g = -1
            for b in range(a, e):
                r = order[b]
                if not used[r] and (g < 0 or rf[r, 4] > rf[g, 4]):
                    g = r
            if g < 0:
                break
            for b in range(a, e):
                r = order[b]
                if rf[r, 0] * rf[g, 0] + rf[r, 1] * rf[g, 1] > 0.9:
                    used[r] = True
            if mat[ro[g], 3] == 0.0 and (corners > 0 or beyond):
                continue         # pushed out by the corners' own depths (or not yet, as TORCS)
            need = rf[g, 4] - (pushx * rf[g, 0] + pushy * rf[g, 1])
            if need > 0.0:
                pushx += need * rf[g, 0]
                pushy += need * rf[g, 1]
            if mat[ro[g], 3] == 0.0:
                if corners > 0 or beyond:
                    continue     # the barrier rule ran per corner, or runs at the next sub-step
                # no corner beyond the line (the box's side against a barrier that bulges
                # into it): once at the deepest point
                _wall_response(i, rf[g, 0], rf[g, 1], rf[g, 2], rf[g, 3], mat[ro[g]], x, y, vx, vy,
                               w, prm, damage)
            else:
                _pit_wall_response(i, rf[g, 0], rf[g, 1], rf[g, 2], rf[g, 3], x, y, yaw, vx, vy,
                                   w, cars, prm, damage)
        norm = math.sqrt(pushx * pushx + pushy * pushy)
        if norm > 0.0:
            x[i] += pushx * (1.0 + SLOP_M / norm)
            y[i] += pushy * (1.0 + SLOP_M / norm)
            travel[i] += norm + SLOP_M
        wall[i] = True
        blocked[i] = True
        moved[i] = True
        a = e
    # cars, in canonical order
    for b in range(nrec):
        r = order[b]
        if rk[r] != 1:
            continue
        i, j = ri[r], ro[r]
        nx, ny, d = rf[r, 0], rf[r, 1], rf[r, 4] + SLOP_M
        _car_response(i, j, nx, ny, rf[r, 2], rf[r, 3], x, y, yaw, vx, vy, w, cars, prm, damage)
        _separate(i, j, nx, ny, d, x, y, cars, blocked, travel)
        car[i] = car[j] = True
        moved[i] = moved[j] = True
        count = _add_pair(pair_out, count, i, j)
    return count

@numba.njit(cache=True)
def _respond_settle(ints, floats, keys, codes, x, y, yaw, vx, vy, w, piece, cars, mat, geo, bar,
                    prm, pairs, meta, flags, slack, wall, car, damage, blocked, moved, travel,
                    pair_out):
    """`_respond` then `_settle` in one call (what `ContactSolver` runs after each pymunk
    step); returns the car pairs written to `pair_out`."""
    count = _respond(ints, floats, keys, codes, x, y, yaw, vx, vy, w, piece, cars, mat, geo, bar,
                     prm, wall, car, damage, blocked, moved, travel, pair_out)
    return _settle(x, y, yaw, piece, cars, geo, bar, prm, pairs, meta, flags, slack, wall, car,
                   blocked, moved, travel, pair_out, count)


@numba.njit(cache=True)
def _same_level(geo, prm, cars, piece, x, y, i, j):
    """False if cars i and j are far apart along the track although close in plan (one passes
    over the other on a bridge): their distances from start differ by more than touching boxes
    can."""
    pi, qi, _ = locate_from(geo, piece[i], x[i], y[i])
    pj, qj, _ = locate_from(geo, piece[j], x[j], y[j])
    d = abs(geo[pi, GEO_S0] + qi - geo[pj, GEO_S0] - qj) % prm[P_LENGTH]
    d = min(d, prm[P_LENGTH] - d)
    return d <= (cars[i, C_RAD] + cars[j, C_RAD]) * prm[P_STRETCH] + 1.0


@numba.njit(cache=True)
def _rec_less(ri, rk, ro, rf, a, b):
    if ri[a] != ri[b]:
        return ri[a] < ri[b]
    if rk[a] != rk[b]:
        return rk[a] < rk[b]
    if ro[a] != ro[b]:
        return ro[a] < ro[b]
    if rf[a, 2] != rf[b, 2]:
        return rf[a, 2] < rf[b, 2]
    return rf[a, 3] < rf[b, 3]


@numba.njit(cache=True)
def _separate(i, j, nx, ny, d, x, y, cars, blocked, travel):
    """Move cars i (along +n) and j (along -n) apart by d in total: split by mass, or all by the
    one that a wall has not already pushed. `travel` accumulates how far each car moved."""
    if blocked[i] and not blocked[j]:
        si, sj = 0.0, 1.0
    elif blocked[j] and not blocked[i]:
        si, sj = 1.0, 0.0
    else:
        mi, mj = cars[i, C_MASS], cars[j, C_MASS]
        si, sj = mj / (mi + mj), mi / (mi + mj)
    x[i] += nx * d * si
    y[i] += ny * d * si
    x[j] -= nx * d * sj
    y[j] -= ny * d * sj
    travel[i] += d * si
    travel[j] += d * sj


@numba.njit(inline="always", cache=True)
def _add_pair(pair_out, count, i, j):
    """Record the pair (i, j) in pair_out[:count] unless it is there; returns the new count.
    Inlined: a call with the literal 0 would otherwise compile a second specialisation."""
    for k in range(count):
        if pair_out[k, 0] == i and pair_out[k, 1] == j:
            return count
    if count < pair_out.shape[0]:
        pair_out[count, 0], pair_out[count, 1] = i, j
        count += 1
    return count


@numba.njit(cache=True)
def _push_inside(i, x, y, yaw, piece, cars, geo, bar):
    """If a corner of car i is more than BACKSTOP_M beyond an exact barrier line, move the car
    so that its four corners are inside them, along the inward normal at the worst corner
    (a backstop: TORCS's barrier rule leaves a box in the wall by about one step's motion and
    answers it at the next step, `_barrier_corners`). Returns True if it moved."""
    pushed = False
    for _ in range(3):
        worst, wx, wy = 0.0, 0.0, 0.0
        for k in range(4):
            e, nx, ny = _corner_excess(geo, bar, x, y, yaw, piece, cars, i, k)
            if e > worst:
                worst, wx, wy = e, nx, ny
        if worst <= (0.0 if pushed else BACKSTOP_M):
            break
        x[i] += wx * (worst + SLOP_M)
        y[i] += wy * (worst + SLOP_M)
        pushed = True
    return pushed


@numba.njit(cache=True)
def _settle(x, y, yaw, piece, cars, geo, bar, prm, pairs, meta, flags, slack, wall, car, blocked,
            moved, travel, pair_out, count):
    """Position-only relaxation after the pymunk contacts, with exact tests: corners of cars
    near a barrier, or moved further than their clearance allows, back inside the barrier
    lines when more than BACKSTOP_M beyond (`_push_inside`);
    boxes of moved cars not overlapping (pushed apart along the smallest-overlap axis).
    Returns the updated pair count."""
    n = x.shape[0]
    stamp = np.full(n, -9, dtype=np.int64)      # pass in which each car last moved
    for i in range(n):
        if moved[i]:
            stamp[i] = -1
    for it in range(SETTLE_ITERS + 1):
        for i in range(n):
            if stamp[i] < it - 1 and not (it == 0 and flags[i] & 1):
                continue
            if (flags[i] & 1 or cars[i, C_GAIN] * travel[i] >= slack[i]) and \
                    _push_inside(i, x, y, yaw, piece, cars, geo, bar):
                wall[i] = blocked[i] = moved[i] = True
                stamp[i] = it
        if it == SETTLE_ITERS:
            break
        changed = False
        for k in range(meta[1]):
            i, j = pairs[k, 0], pairs[k, 1]
            if stamp[i] < it - 1 and stamp[j] < it - 1:
                continue
            gap, ax, ay = _obb_sep(x, y, yaw, cars, i, j)
            if gap < 0.0 and _same_level(geo, prm, cars, piece, x, y, i, j):
                _separate(i, j, -ax, -ay, SLOP_M - gap, x, y, cars, blocked, travel)
                car[i] = car[j] = moved[i] = moved[j] = True
                stamp[i] = stamp[j] = it
                count = _add_pair(pair_out, count, i, j)
                changed = True
        if not changed:
            break
    return count


# --- the sub-step loop with the broad phase --------------------------------------------------------
# World.step's compiled loop: advance every car one sub-step, run the broad phase, and stop at the
# first sub-step that finds something near (there, and only there, the solver's `resolve` has
# work). Plain module-level functions calling `_broad_phase` directly, so numba caches them on
# disk like every other kernel (a stepper built around a first-class function argument was
# compiled anew in every process: a ~1 s stall on a server's first tick).


PREDICT_ACCEL = 30.0
"""m/s^2: the speed gain per tick a whole-tick attempt assumes (checked after the tick)."""
PREDICT_YAW_ACCEL = 100.0
"""rad/s^2: the yaw-rate gain per tick a whole-tick attempt assumes (checked after the tick)."""


@numba.njit(cache=True, inline="always")
def _predict_motion(st, a, b, span, path, turn):
    """path[i], turn[i] for rows a..b-1: the farthest (m) and the most turn (rad) a whole-tick
    attempt of `span` s assumes (`PREDICT_ACCEL`, `PREDICT_YAW_ACCEL`; checked after it)."""
    for i in range(a, b):
        v = math.sqrt(st[i, S_VXG] ** 2 + st[i, S_VYG] ** 2)
        path[i] = span * (v + PREDICT_ACCEL * span)
        turn[i] = span * min(abs(st[i, S_R]) + PREDICT_YAW_ACCEL * span, YAW_RATE_MAX)


SNAP_COLUMNS = N_STATE + len(CONTROL_COLUMNS)
"""Width of the whole-tick scratch `snap` (one row per state row): a car's state, then its
controls (a shift that starts in a tick writes its throttle cap into them, `kernel.advance_car`:
a tick given back restores both)."""


@numba.njit(cache=True, inline="always")
def _save_rows(st, u, a, b, snap):
    """snap[i] = st[i] followed by u[i], rows a..b-1 (plain loops: slice assignment compiles
    slowly; row by row where st is row-major (WorldBatch: a car's row is contiguous, and a
    column-first copy of a few rows costs ~5 % of make_vec's time with traffic), column by
    column otherwise (World's Fortran-ordered state))."""
    ns = st.shape[1]
    if st.strides[0] > st.strides[1]:
        for i in range(a, b):
            for c in range(ns):
                snap[i, c] = st[i, c]
            for c in range(u.shape[1]):
                snap[i, ns + c] = u[i, c]
        return
    for c in range(ns):
        for i in range(a, b):
            snap[i, c] = st[i, c]
    for c in range(u.shape[1]):
        for i in range(a, b):
            snap[i, ns + c] = u[i, c]


@numba.njit(cache=True, inline="always")
def _restore_rows(st, u, a, b, snap):
    """The inverse of `_save_rows`: st[i] and u[i] back from snap[i], rows a..b-1."""
    ns = st.shape[1]
    if st.strides[0] > st.strides[1]:
        for i in range(a, b):
            for c in range(ns):
                st[i, c] = snap[i, c]
            for c in range(u.shape[1]):
                u[i, c] = snap[i, ns + c]
        return
    for c in range(ns):
        for i in range(a, b):
            st[i, c] = snap[i, c]
    for c in range(u.shape[1]):
        for i in range(a, b):
            u[i, c] = snap[i, ns + c]


@numba.njit(cache=True, error_model="numpy", inline="always")
def whole_tick(st, a, b, cp, curve_w, curve_t, pt, surf, tsc, u, nsub, dt, fuel_on, cars, prm,
               wall_cache, vref, pairs, meta, snap, path, turn):
    """Advance cars a..b-1 (rows of `st`) by m sub-steps in one `advance_car` call each and
    return m: the most of nsub, nsub // 2, nsub // 4, ... sub-steps at which the broad phase
    (its arguments cars .. meta, as `ContactSolver.broad_phase_args`, rows a..b-1 of `st` being
    its cars 0..) could flag none of them and change no cache (so it need run after the last
    only), else 1 (the broad phase runs after each).

    The test is `tick_clear` twice: before, with each car's path and turn predicted from its
    speed and yaw rate (`PREDICT_ACCEL`, `PREDICT_YAW_ACCEL`), so that sub-steps that will not
    pass are not computed; after, with the bounds the kernel returns (the largest speed and
    yaw rate it reached), from the start poses. A failed check restores the rows and their
    controls `u` from `snap` ((len(st), SNAP_COLUMNS): a shift started in the tick has written
    its cap into u) and does one sub-step, as the sub-step path would. `advance_car` runs n
    sub-steps per call exactly as n calls of one, so a whole tick is bit-identical to sub-steps
    with the broad phase between. path, turn: (len(st),) scratch. The car loop is a prange: parallel in a parallel
    caller (it is inlined), serial elsewhere."""
    m = nsub
    while m > 0:                 # the most sub-steps (nsub, halved) the prediction allows
        _predict_motion(st, a, b, m * dt, path, turn)
        if tick_clear(st[a:b, S_X], st[a:b, S_Y], st[a:b, S_YAW], cars, prm, wall_cache, vref,
                      pairs, meta, path[a:b], turn[a:b]):
            break
        if m == nsub and m > 1:  # not clear even standing still: no m is (the test is monotone)
            for i in range(a, b):
                path[i] = 0.0
                turn[i] = 0.0
            if not tick_clear(st[a:b, S_X], st[a:b, S_Y], st[a:b, S_YAW], cars, prm, wall_cache,
                              vref, pairs, meta, path[a:b], turn[a:b]):
                m = 0
                break
        m //= 2
    if m > 0:
        _save_rows(st, u, a, b, snap)
    while True:                          # (one advance_car call site: each costs compile time)
        steps = max(m, 1)
        span = steps * dt
        for i in numba.prange(a, b):
            v2_max, r_max = advance_car(st, i, cp, curve_w, curve_t, pt, surf, tsc, u, steps,
                                        dt, fuel_on)
            path[i] = span * math.sqrt(v2_max)
            turn[i] = span * r_max
        if m == 0:
            return 1
        ok = tick_clear(snap[a:b, S_X], snap[a:b, S_Y], snap[a:b, S_YAW], cars, prm, wall_cache,
                        vref, pairs, meta, path[a:b], turn[a:b])
        for i in range(a, b):      # NaN speeds escape max(); they leave a NaN pose
            ok = ok and math.isfinite(st[i, S_X]) and math.isfinite(st[i, S_Y])
        if ok:
            return m
        _restore_rows(st, u, a, b, snap)     # the bound failed: back, and one sub-step
        m = 0


@numba.njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def whole_tick_rows(st, a, b, cp, curve_w, curve_t, pt, surf, tsc, u, nsub, dt, fuel_on, cars, prm,
                    wall_cache, vref, pairs, meta, snap, path, turn):
    """`whole_tick` in a function of its own (serial), compiled without array reference counts
    (`kernel.NO_REFCOUNT`: it allocates nothing; inlined into a caller that keeps them, its
    array aliases and calls cost atomic increments): for serial callers."""
    return whole_tick(st, a, b, cp, curve_w, curve_t, pt, surf, tsc, u, nsub, dt, fuel_on, cars,
                      prm, wall_cache, vref, pairs, meta, snap, path, turn)


@numba.njit(cache=True, error_model="numpy")
def advance_until_near(st, cp, curve_w, curve_t, pt, surf, tsc, u, k0, nsub, dt, fuel_on,
                       x, y, yaw, piece, bp, near, snap, path, turn):
    """Sub-steps k0.. of `kernel.advance_car` for all cars (state `st` (N, N_STATE)), whole
    ticks (or the most sub-steps) at once where `whole_tick` proves nothing can be near; after
    each call `piece` (N,) is refreshed and `near[0]` = the broad phase's answer on the arrays
    `bp` (ContactSolver.broad_phase_args). Returns the sub-steps done (nsub if nothing near).
    snap, path, turn: `whole_tick`'s scratch."""
    k = k0
    n = np.int64(st.shape[0])
    while k < nsub:
        if n >= SPLIT_MIN_CARS:
            done = split_tick(st, cp, curve_w, curve_t, pt, surf, tsc, u, k, nsub, dt, fuel_on, x,
                              y, yaw, piece, bp, near, snap, path, turn)
            if done > 0:
                k += done
                if near[0] != 0:
                    return k
                continue
        k += whole_tick_rows(st, np.int64(0), n, cp, curve_w, curve_t, pt, surf, tsc, u, nsub - k,
                             dt, fuel_on, bp[2], bp[3], bp[4], bp[5], bp[6], bp[7], snap, path, turn)
        if _near_after_sub_step(st, x, y, yaw, piece, bp, near):
            return k
    return nsub


SPLIT_MIN_CARS = 3
"""`advance_until_near` tries `split_tick` with at least this many cars."""


@numba.njit(cache=True, error_model="numpy")
def split_tick(st, cp, curve_w, curve_t, pt, surf, tsc, u, k0, nsub, dt, fuel_on, x, y, yaw,
               piece, bp, near, snap, path, turn):
    """Sub-steps k0.. of a tick where some cars are near something and the others ("lazy")
    provably are not: the near cars go one sub-step at a time with the broad phase after each,
    the lazy ones wait at their start pose and catch up in one `advance_car` call at the first
    sub-step where the broad phase needs them where they really are (something near, a
    neighbour-list rebuild, a near car within reach of a lazy car's start circle plus its
    path) or at the tick's end. Returns the sub-steps done, with near[0] the broad phase's
    answer there on the true poses; or 0, having changed nothing, if no split applies or a lazy
    car went farther than predicted (the caller then steps every car).

    Bit-identical to stepping every car with the broad phase after each sub-step: a lazy car
    i (predicted path and turn of the rest of the tick as `whole_tick`'s, then checked) keeps
    its wall clearance, its neighbour-list reference, and every listed pair with another lazy
    car beyond reach (`tick_clear`'s tests), and each of its pairs with a near car is checked
    at every sub-step from its start pose less its path. So the broad phase could flag no
    lazy car and no pair of one and changes no cache for one whatever its pose on the way; it
    sees the near cars where they are. Arguments as `advance_until_near`'s."""
    if nsub - k0 < 2:
        return 0
    _predict_motion(st, 0, st.shape[0], (nsub - k0) * dt, path, turn)
    return split_predicted(st, cp, curve_w, curve_t, pt, surf, tsc, u, k0, nsub, dt, fuel_on, x, y,
                           yaw, piece, bp, near, snap, path, turn)


@numba.njit(cache=True, error_model="numpy")
def split_predicted(st, cp, curve_w, curve_t, pt, surf, tsc, u, k0, nsub, dt, fuel_on, x, y, yaw,
                    piece, bp, near, snap, path, turn):
    """`split_tick` with each car's path (m) and turn (rad) over the rest of the tick predicted
    in path, turn (N,)."""
    n = st.shape[0]
    cars, prm, wall_cache, vref, pairs, meta = bp[2], bp[3], bp[4], bp[5], bp[6], bp[7]
    if meta[0] == 0:
        return 0
    lazy = np.empty(n, dtype=np.bool_)
    for i in range(n):
        lazy[i] = (_wall_outlasts(i, x, y, yaw, cars, prm, wall_cache, path, turn)
                   and _stays_listed(i, x, y, vref, path))
    for k in range(meta[1]):
        i, j = pairs[k, 0], pairs[k, 1]
        if (lazy[i] or lazy[j]) and not _stays_apart(i, j, x, y, cars, path[i], path[j]):
            lazy[i] = False
            lazy[j] = False
    n_lazy = 0
    for i in range(n):
        n_lazy += lazy[i]
    if n_lazy == 0 or n_lazy == n:
        return 0             # nothing to split: whole_tick decides
    _save_rows(st, u, 0, n, snap)
    cache_snap = wall_cache.copy()
    k = k0
    while True:
        _advance_rows(st, lazy, np.int64(0), cp, curve_w, curve_t, pt, surf, tsc, u, np.int64(1), dt,
                      fuel_on, path, turn)
        k += 1
        if k == nsub or not _lazy_apart(x, y, cars, vref, pairs, meta, lazy, path):
            break
        for i in range(n):
            piece[i] = int(st[i, S_PIECE])
        near[0] = _broad_phase(x, y, yaw, piece, bp[0], bp[1], cars, prm, wall_cache, vref, pairs,
                               meta, bp[8], bp[9])
        if near[0] != 0:
            break
    if not _advance_rows(st, lazy, np.int64(1), cp, curve_w, curve_t, pt, surf, tsc, u,
                         np.int64(k - k0), dt, fuel_on, path, turn):
        _restore_rows(st, u, 0, n, snap)
        for i in range(n):
            for c in range(wall_cache.shape[1]):
                wall_cache[i, c] = cache_snap[i, c]
        return 0
    _near_after_sub_step(st, x, y, yaw, piece, bp, near)
    return k - k0


@numba.njit(cache=True, error_model="numpy", **NO_REFCOUNT)
def _advance_rows(st, lazy, group, cp, curve_w, curve_t, pt, surf, tsc, u, steps, dt, fuel_on, path,
                  turn):
    """`steps` sub-steps in one `advance_car` call for each car with lazy[i] == (group == 1);
    True if each of them went at most path[i] m and turned at most turn[i] rad (the kernel's
    bounds: its largest speed and yaw rate) and has a finite position. (group and steps are
    int64 values, never literals: numba would compile a copy per literal.)"""
    ok = True
    span = steps * dt
    want = group == 1
    for i in range(st.shape[0]):
        if lazy[i] == want:
            v2_max, r_max = advance_car(st, i, cp, curve_w, curve_t, pt, surf, tsc, u, steps, dt,
                                        fuel_on)
            ok = (ok and span * math.sqrt(v2_max) <= path[i] and span * r_max <= turn[i]
                  and math.isfinite(st[i, S_X]) and math.isfinite(st[i, S_Y]))
    return ok


@numba.njit(cache=True, **NO_REFCOUNT)
def _lazy_apart(x, y, cars, vref, pairs, meta, lazy, path):
    """True if the broad phase on these poses would rebuild no neighbour list and skip every
    listed pair of a lazy and a near car by its first test, wherever the lazy car is within
    path[i] m of (x, y)[i] (`split_tick`)."""
    for i in range(x.shape[0]):       # (the broad phase's own rebuild test)
        if (x[i] - vref[i, 0]) ** 2 + (y[i] - vref[i, 1]) ** 2 > REBUILD_M * REBUILD_M:
            return False
    for k in range(meta[1]):
        i, j = pairs[k, 0], pairs[k, 1]
        if lazy[i] != lazy[j]:
            if not _stays_apart(i, j, x, y, cars, path[i] if lazy[i] else path[j], 0.0):
                return False
    return True


@numba.njit(cache=True, error_model="numpy", parallel=True)
def advance_until_near_parallel(st, cp, curve_w, curve_t, pt, surf, tsc, u, k0, nsub, dt, fuel_on,
                                x, y, yaw, piece, bp, near, snap, path, turn):
    """`advance_until_near` with the cars shared among threads (they are independent between
    broad-phase calls: bit-identical); the broad phase stays serial."""
    k = k0
    n = np.int64(st.shape[0])
    while k < nsub:
        k += whole_tick(st, np.int64(0), n, cp, curve_w, curve_t, pt, surf, tsc, u, nsub - k, dt,
                        fuel_on, bp[2], bp[3], bp[4], bp[5], bp[6], bp[7], snap, path, turn)
        if _near_after_sub_step(st, x, y, yaw, piece, bp, near):
            return k
    return nsub


@numba.njit(cache=True, inline="always")
def _near_after_sub_step(st, x, y, yaw, piece, bp, near):
    for i in range(st.shape[0]):
        piece[i] = int(st[i, S_PIECE])
    near[0] = _broad_phase(x, y, yaw, piece, bp[0], bp[1], bp[2], bp[3], bp[4], bp[5], bp[6],
                           bp[7], bp[8], bp[9])
    return near[0] != 0
