"""World.step's compiled part as one call: the control check, the rules between cars at the
tick's start (finish, slipstream: `kernel.tick_start`), the sub-step loop with the contact broad
phase (`contact_kernels.advance_until_near`, whole ticks where nothing can be near) and race
positions. `World.step` calls it for worlds with contact, and so does the SCR
server's compiled tick (`madsim.net.server_tick`), so both run the same code; only a sub-step
where something is near goes back to Python (the pymunk narrow phase, `World.finish_tick`).
"""

from __future__ import annotations

import numba
import numpy as np

from madsim.array_table import (b1_vector, f8_matrix, f8_vector, i1_vector, i8_matrix, i8_vector,
                                readonly)
from madsim.physics.contact_kernels import SNAP_COLUMNS, _respond_settle, advance_until_near
from madsim.physics.pymunk_direct import (ARB_INTS, D_CALLS, D_NARROWED, D_READY, N_ADD, N_CTABLE,
                                          N_DIRECT, N_DROP, N_IDLE, N_MEMBER, N_POSES, N_PTRS,
                                          N_SLOTS, arbiter_floats, arbiter_ints, narrow_direct)
from madsim.physics.kernel import add_damage, check_controls, refresh, tick_start
from madsim.physics.layout import S_DIST, S_LAPS, S_R, S_VXG, S_VYG, S_X, S_Y, S_YAW

NONFINITE = -1
"""`step_world`'s answer when a control is not finite (nothing was changed)."""
FIRST_CAR = np.int64(0)
"""An int64, not the literal 0: numba compiles a callee once per literal argument value, and
`advance_until_near` (~5 s to compile) is also called with a variable (`finish_contact`)."""


@numba.njit(cache=True)
def race_positions(st, race_pos):
    """race_pos[i] = 1 + the cars ahead of car i: more laps, or as many and a longer distance
    raced, or both equal and a lower row (numpy.lexsort of (row, -dist, -laps) for finite values)."""
    rank_rows(st, 0, st.shape[0], race_pos)


@numba.njit(cache=True, error_model="numpy")
def rank_rows(st, a, b, race_pos):
    """`race_positions` for the cars in rows a..b-1 of st alone (one race of a batch)."""
    for i in range(a, b):
        li, di = st[i, S_LAPS], st[i, S_DIST]
        rank = 1
        for j in range(a, b):
            lj, dj = st[j, S_LAPS], st[j, S_DIST]
            if lj > li or (lj == li and (dj > di or (dj == di and j < i))):
                rank += 1
        race_pos[i] = rank


@numba.njit(cache=True, error_model="numpy")
def step_world(u, nsub, st, cp, curve_w, curve_t, pt, surf, tsc, dt, fuel_on, length, info, x, y,
               yaw, piece, bp, near, snap, path, turn, wall, car, race_pos):
    """Advance the World state `st` (N, N_STATE) `nsub` sub-steps of `dt` s with controls u (N, 5)
    held, up to the first sub-step after which the broad phase (arrays `bp`) finds something
    near: returns the sub-steps done with near[0] > 0 there (the caller resolves the contact and
    goes on, `World.finish_tick`), or nsub with near[0] == 0 and race_pos (N,) updated. Returns
    NONFINITE, changing nothing, when u holds a non-finite value (info: `check_controls`).
    wall, car (N,) bool: this tick's contact flags, cleared. x, y, yaw: st's pose columns;
    piece, snap, path, turn: `advance_until_near`'s scratch. The World's own arguments come
    from `World.tick_args`."""
    check_controls(u, info)
    if info[0]:
        return NONFINITE
    n = st.shape[0]
    if n > 1:        # finish and slipstream: from the state at the tick's start
        tick_start(st, cp, 0, n, length)
    for i in range(n):
        wall[i] = False
        car[i] = False
    k = advance_until_near(st, cp, curve_w, curve_t, pt, surf, tsc, u, FIRST_CAR, nsub, dt, fuel_on,
                           x, y, yaw, piece, bp, near, snap, path, turn)
    if near[0] == 0 and n > 1:
        race_positions(st, race_pos)
    return k


# --- the tick of a compiled door (the SCR server's, MadrasEnv's), from an address table ------

WORLD_TABLE = (
    ("car_table", "f8", 2, "C"), ("curve_w", "f8", 2, "C"), ("curve_t", "f8", 2, "C"),
    ("piece_table", "f8", 2, "C"), ("surfaces", "f8", 2, "C"), ("track_scalars", "f8", 1, "C"),
    ("info", "i8", 1, "C"), ("x", "f8", 1, "C"), ("y", "f8", 1, "C"), ("yaw", "f8", 1, "C"),
    ("piece", "i8", 1, "C"),
    ("bp_geo", "f8", 2, "C"), ("bp_bar", "f8", 2, "C"), ("bp_cars", "f8", 2, "C"), ("bp_prm", "f8", 1, "C"),
    ("bp_wall_cache", "f8", 2, "C"), ("bp_vref", "f8", 2, "C"), ("bp_pairs", "i8", 2, "C"),
    ("bp_meta", "i8", 1, "C"), ("bp_flags", "i1", 1, "C"), ("bp_slack", "f8", 1, "C"),
    ("near", "i8", 1, "C"), ("path", "f8", 1, "C"), ("turn", "f8", 1, "C"),
    ("contact_wall", "b1", 1, "C"), ("contact_car", "b1", 1, "C"), ("race_pos", "i8", 1, "C"),
)
"""The rows a door's address table (`madsim.array_table`) holds for `step_table`, in this order
from its row w0: World.tick_args' arrays (`world_table_arrays`; the contact arrays are the
ContactSolver's broad-phase arguments)."""
(W_CP, W_CURVE_W, W_CURVE_T, W_PT, W_SURF, W_TSC, W_INFO, W_X, W_Y, W_YAW, W_PIECE, W_BP_GEO, W_BP_BAR,
 W_BP_CARS, W_BP_PRM, W_BP_WALL, W_BP_VREF, W_BP_PAIRS, W_BP_META, W_BP_FLAGS, W_BP_SLACK, W_NEAR,
 W_PATH, W_TURN, W_WALL, W_CAR, W_RACE_POS) = (np.int64(k) for k in range(len(WORLD_TABLE)))


def world_table_arrays(tick_args: tuple) -> tuple:
    """The arrays of `WORLD_TABLE`, in its order, from a World's `tick_args`."""
    w = tick_args
    return (*w[1:7], *w[10:15], *w[15], w[16], *w[18:])


@numba.njit(cache=True, error_model="numpy")
def step_table(u, u_tick, nsub, st, snap, t, w0, dt, fuel_on, length):
    """`step_world` on u_tick, a copy of the controls u made here (a shift's throttle cap writes
    into it, never into what the driver sent), with the World's arrays at rows w0.. of address
    table t (`WORLD_TABLE`); returns step_world's answer."""
    for i in range(u.shape[0]):
        for j in range(u.shape[1]):
            u_tick[i, j] = u[i, j]
    bp = (readonly(f8_matrix(t, w0 + W_BP_GEO)), f8_matrix(t, w0 + W_BP_BAR), f8_matrix(t, w0 + W_BP_CARS),
          f8_vector(t, w0 + W_BP_PRM), f8_matrix(t, w0 + W_BP_WALL), f8_matrix(t, w0 + W_BP_VREF),
          i8_matrix(t, w0 + W_BP_PAIRS), i8_vector(t, w0 + W_BP_META), i1_vector(t, w0 + W_BP_FLAGS),
          f8_vector(t, w0 + W_BP_SLACK))
    return step_world(u_tick, nsub, st, f8_matrix(t, w0 + W_CP), f8_matrix(t, w0 + W_CURVE_W),
                      f8_matrix(t, w0 + W_CURVE_T), f8_matrix(t, w0 + W_PT), f8_matrix(t, w0 + W_SURF),
                      f8_vector(t, w0 + W_TSC), dt, fuel_on, length, i8_vector(t, w0 + W_INFO),
                      f8_vector(t, w0 + W_X), f8_vector(t, w0 + W_Y), f8_vector(t, w0 + W_YAW),
                      i8_vector(t, w0 + W_PIECE), bp, i8_vector(t, w0 + W_NEAR), snap,
                      f8_vector(t, w0 + W_PATH), f8_vector(t, w0 + W_TURN), b1_vector(t, w0 + W_WALL),
                      b1_vector(t, w0 + W_CAR), i8_vector(t, w0 + W_RACE_POS))


# --- the rest of a tick where something is near (World.finish_tick) ------------------------------

CONTACT_TABLE = (
    ("keys", "i8", 1, "C"), ("codes", "i8", 1, "C"), ("materials", "f8", 2, "C"),
    ("blocked", "b1", 1, "C"), ("moved", "b1", 1, "C"), ("travel", "f8", 1, "C"),
    ("pair_out", "i8", 2, "C"),
    ("hit_wall", "b1", 1, "C"), ("hit_car", "b1", 1, "C"), ("hit_damage", "f8", 1, "C"),
    ("vx", "f8", 1, "C"), ("vy", "f8", 1, "C"), ("yaw_rate", "f8", 1, "C"),
    ("pairs", "i8", 2, "C"), ("pair_count", "i8", 1, "C"),
)
"""The rows of the address table `finish_contact` reads besides `WORLD_TABLE`'s: the contact
solver's response arrays (`ContactSolver.respond_arrays`), one response's flags and damage, the
global velocity and yaw-rate columns of the state, and the tick's car pairs (M, 2) with their
count."""
(C_KEYS, C_CODES, C_MAT, C_BLOCKED, C_MOVED, C_TRAVEL, C_PAIR_OUT, C_HIT_WALL, C_HIT_CAR,
 C_HIT_DAMAGE, C_VX, C_VY, C_YAW_RATE, C_PAIRS, C_PAIR_COUNT) = (
    np.int64(k) for k in range(len(CONTACT_TABLE)))
TICK_DONE = -1
"""`finish_contact`'s answer when the tick is complete."""


@numba.njit(cache=True, error_model="numpy")
def finish_contact(ints, floats, respond, k, nsub, u, st, snap, t, w0, c, dt, fuel_on, damage_on,
                   walk):
    """The rest of a tick after sub-step k where the broad phase found something near: when
    `respond`, the contact response to pymunk's arbiters (ints, floats: `ContactSolver.narrow`)
    with the tick's flags, pairs (table c, `CONTACT_TABLE`) and damage (`respond_tick`); then,
    with `walk`, sub-steps k.. on to
    the next one where something is near (`advance_until_near`). Returns the sub-step to
    resolve next (near[0] != 0 there; without `walk`, the caller steps on from k itself), or
    TICK_DONE with race positions updated. World arrays at rows w0.. of table t (`WORLD_TABLE`);
    u: the tick's controls; st, snap: the state and its whole-tick scratch."""
    n = st.shape[0]
    x, y, yaw = f8_vector(t, w0 + W_X), f8_vector(t, w0 + W_Y), f8_vector(t, w0 + W_YAW)
    piece, near = i8_vector(t, w0 + W_PIECE), i8_vector(t, w0 + W_NEAR)
    cp, pt = f8_matrix(t, w0 + W_CP), f8_matrix(t, w0 + W_PT)
    surf, tsc = f8_matrix(t, w0 + W_SURF), f8_vector(t, w0 + W_TSC)
    bp = (readonly(f8_matrix(t, w0 + W_BP_GEO)), f8_matrix(t, w0 + W_BP_BAR), f8_matrix(t, w0 + W_BP_CARS),
          f8_vector(t, w0 + W_BP_PRM), f8_matrix(t, w0 + W_BP_WALL), f8_matrix(t, w0 + W_BP_VREF),
          i8_matrix(t, w0 + W_BP_PAIRS), i8_vector(t, w0 + W_BP_META), i1_vector(t, w0 + W_BP_FLAGS),
          f8_vector(t, w0 + W_BP_SLACK))
    if respond:
        respond_tick(ints, floats, i8_vector(c, C_KEYS), i8_vector(c, C_CODES), x, y, yaw,
                     f8_vector(c, C_VX), f8_vector(c, C_VY), f8_vector(c, C_YAW_RATE), piece,
                     f8_matrix(t, w0 + W_BP_GEO), bp[1], bp[2], bp[3], bp[6], bp[7], bp[8], bp[9],
                     f8_matrix(c, C_MAT), b1_vector(c, C_BLOCKED), b1_vector(c, C_MOVED),
                     f8_vector(c, C_TRAVEL), i8_matrix(c, C_PAIR_OUT), b1_vector(c, C_HIT_WALL),
                     b1_vector(c, C_HIT_CAR), f8_vector(c, C_HIT_DAMAGE), st, cp, pt, surf, tsc,
                     damage_on, b1_vector(t, w0 + W_WALL), b1_vector(t, w0 + W_CAR),
                     i8_matrix(c, C_PAIRS), i8_vector(c, C_PAIR_COUNT))
    if k < nsub:
        if not walk:
            return k
        k = advance_until_near(st, cp, f8_matrix(t, w0 + W_CURVE_W), f8_matrix(t, w0 + W_CURVE_T), pt,
                               surf, tsc, u, k, nsub, dt, fuel_on, x, y, yaw, piece, bp, near, snap,
                               f8_vector(t, w0 + W_PATH), f8_vector(t, w0 + W_TURN))
        if near[0] != 0:
            return k
    if n > 1:
        race_positions(st, i8_vector(t, w0 + W_RACE_POS))
    return TICK_DONE


@numba.njit(cache=True, error_model="numpy")
def contact_direct(k, nsub, u, st, snap, t, w0, n0, dt, fuel_on, damage_on):
    """`World.finish_tick` in compiled code for a tick that `step_table` left after sub-step k
    with something near: each consultation of pymunk from here (`pymunk_direct.narrow_direct`),
    then `finish_contact` (response, sub-steps on to the next near one), until the tick is
    done (returns TICK_DONE) or a consultation needs Python: a pair list to grow (near[0] < 0),
    no held space or a changed body set (direct[D_READY] == 0), a car entering or leaving the
    space, the tick's pairs or the response's pair buffer to grow. Then it returns the
    sub-step k where World.finish_tick(..., keep_pairs=True) goes on (the tick's pairs so far
    kept; with direct[D_NARROWED] set, pymunk was consulted there and its arbiters wait in the
    get buffers). The calls, arguments and order are World.finish_tick's: bit-identical. World
    arrays at rows w0.. of table t (`WORLD_TABLE`), the solver's at rows n0..
    (`pymunk_direct.NARROW_TABLE`); u: the tick's controls."""
    near = i8_vector(t, w0 + W_NEAR)
    c = i8_matrix(t, n0 + N_CTABLE)
    ptrs, direct = i8_vector(t, n0 + N_PTRS), i8_vector(t, n0 + N_DIRECT)
    pair_out, tick_pairs = i8_matrix(c, C_PAIR_OUT), i8_matrix(c, C_PAIRS)
    pair_count = i8_vector(c, C_PAIR_COUNT)
    meta = i8_vector(t, w0 + W_BP_META)
    x, y, yaw = f8_vector(t, w0 + W_X), f8_vector(t, w0 + W_Y), f8_vector(t, w0 + W_YAW)
    pair_count[0] = 0
    while True:
        if (near[0] < 0 or direct[D_READY] == 0
                or pair_count[0] + pair_out.shape[0] > tick_pairs.shape[0]):
            return k
        n_ints = narrow_direct(ptrs, i1_vector(t, w0 + W_BP_FLAGS), b1_vector(t, n0 + N_MEMBER),
                               i8_vector(t, n0 + N_IDLE), i8_vector(t, n0 + N_ADD),
                               i8_vector(t, n0 + N_DROP), i8_vector(t, n0 + N_SLOTS), x, y, yaw,
                               f8_vector(t, n0 + N_POSES), dt)
        if n_ints < 0:
            return k
        direct[D_CALLS] += 1
        if n_ints // ARB_INTS + 4 * meta[1] + 1 > pair_out.shape[0]:
            direct[D_NARROWED] = 1
            return k
        k = finish_contact(arbiter_ints(ptrs, n_ints), arbiter_floats(ptrs), True, k, nsub, u, st,
                           snap, t, w0, c, dt, fuel_on, damage_on, True)
        if k == TICK_DONE:
            return TICK_DONE


@numba.njit(cache=True, error_model="numpy")
def respond_tick(ints, floats, keys, codes, x, y, yaw, vx, vy, w, piece, geo, bar, cars, prm, pairs,
                 meta, flags, slack, mat, blocked, moved, travel, pair_out, hit_wall, hit_car, damage,
                 st, cp, pt, surf, tsc, damage_on, wall, car, tick_pairs, pair_count):
    """One contact response within a tick (World's and WorldBatch's): `_respond_settle` on
    pymunk's arbiters (ints, floats: `ContactSolver.narrow`) with the solver's arrays, the poses
    and velocities x, y, yaw, vx, vy, w (N,) written back to st's columns (a no-op where they
    are its columns); if a car was hit, the response's flags (hit_wall, hit_car, damage:
    scratch) or-ed into the tick's wall and car (N,), its car pairs appended to tick_pairs at
    pair_count[0] in ascending order (the caller made room), its damage added (`damage_on`)
    and the track positions refreshed. Returns whether a car was hit."""
    n = st.shape[0]
    for i in range(n):
        hit_wall[i] = False
        hit_car[i] = False
        damage[i] = 0.0
    count = _respond_settle(ints, floats, keys, codes, x, y, yaw, vx, vy, w, piece, cars, mat, geo,
                            bar, prm, pairs, meta, flags, slack, hit_wall, hit_car, damage, blocked,
                            moved, travel, pair_out)
    for i in range(n):
        st[i, S_X], st[i, S_Y], st[i, S_YAW] = x[i], y[i], yaw[i]
        st[i, S_VXG], st[i, S_VYG], st[i, S_R] = vx[i], vy[i], w[i]
    hit = False
    for i in range(n):
        hit = hit or hit_wall[i] or hit_car[i]
    if hit:
        for i in range(n):
            wall[i] = wall[i] or hit_wall[i]
            car[i] = car[i] or hit_car[i]
        _append_sorted(pair_out, count, tick_pairs, pair_count)
        if damage_on:
            add_damage(st, cp, damage)
        refresh(st, cp, pt, surf, tsc, True)
    return hit


@numba.njit(cache=True)
def _append_sorted(pair_out, count, pairs, pair_count):
    """Append pair_out[:count] to pairs at pair_count[0], in ascending (i, j) order (the caller
    made room)."""
    m = pair_count[0]
    for r in range(count):
        i, j = pair_out[r, 0], pair_out[r, 1]
        s = m + r
        while s > m and (pairs[s - 1, 0] > i or (pairs[s - 1, 0] == i and pairs[s - 1, 1] > j)):
            pairs[s, 0], pairs[s, 1] = pairs[s - 1, 0], pairs[s - 1, 1]
            s -= 1
        pairs[s, 0], pairs[s, 1] = i, j
    pair_count[0] = m + count
