"""Compiled loops of `madsim.physics.world_batch.WorldBatch`: every slot's tick, sensors and
race positions in one call (slot e = an episode in rows off[e] .. off[e] + ncar[e] - 1 of the
batch's arrays, car axis first; see WorldBatch for the layout).

The loops are module-level kernels in numba's disk cache (`madsim.kernel_cache` renews their
entries when any kernel module changes): one per-slot body each, run by a serial and a parallel
(slots shared among threads) loop. With contact off the broad phase is never called. The
loops over slots and the bodies keep no array reference counts (`kernel.NO_REFCOUNT`): every
per-track and per-slot table is a row range of one flat array (no typed lists, whose items are
counted), sliced inside them; only the sorted slipstream (more than `kernel.SLIP_ALL_PAIRS`
cars) and the broad phase proper (they allocate) run with counts, the broad phase only when a
slot's cheap check `quiet` cannot prove it would find nothing. (A kernel compiled without
counts cannot call one that allocates: numba compiles the callee without them too.)
"""

from __future__ import annotations

import math

import numba

from madsim.physics import kernel
from madsim.physics import layout as L
from madsim.physics.contact_kernels import (
    C_GAIN,
    C_RAD,
    CAR_REACH_M,
    P_MOVE_CAP,
    REBUILD_M,
    _broad_phase,
    _wrap,
    whole_tick_rows,
)
from madsim.physics.sensors import sensor_kernel
from madsim.physics.world_tick import rank_rows


@numba.njit(cache=True, error_model="numpy", inline="always", **kernel.NO_REFCOUNT)
def advance_slot(e, st, cp, cw, ct, u, tables, trk, off, ncar, kpos, piece, hits, nsub, dt,
                 fuel_on, with_contact, snap, path, turn, contact):
    """World.step for slot e from sub-step kpos[e] (the rest at once where provably nothing is
    near): returns 0 when all nsub are done with nothing near (kpos[e] = nsub), 1 when the
    broad phase must run now (kpos[e] = sub-steps done). tables, contact: `WorldBatch`'s
    stacked per-track tables and broad-phase arrays (see `advance_slots`)."""
    pt_all, pt_off, surf_all, surf_off, tsc_all, n_geo = tables
    _, _, _, _, box, prm, wall_cache, vref, pairs, _, meta, flags, slack = contact
    a, b = off[e], off[e] + ncar[e]
    t = trk[e]
    pt, surf = pt_all[pt_off[t]:pt_off[t + 1]], surf_all[surf_off[t]:surf_off[t + 1]]
    tsc = tsc_all[t]
    k = kpos[e]
    if k == 0:
        for i in range(a, b):
            hits[i] = False
        if 1 < b - a <= kernel.SLIP_ALL_PAIRS:   # World.step: from the poses at the tick's start
            kernel.tick_start_few(st, cp, a, b)  # (more cars: `_advance_one`, it sorts)
    if not with_contact:
        for i in range(a, b):
            kernel.advance_car(st, i, cp, cw, ct, pt, surf, tsc, u, nsub, dt, fuel_on)
        kpos[e] = nsub
        return 0
    cars, wc, vr, pr, mt = box[a:b], wall_cache[a:b], vref[a:b], pairs[e], meta[e]
    while k < nsub:
        k += whole_tick_rows(st, a, b, cp, cw, ct, pt, surf, tsc, u, nsub - k, dt, fuel_on, cars,
                             prm[e], wc, vr, pr, mt, snap, path, turn)
        for i in range(a, b):
            piece[i] = int(st[i, L.S_PIECE])
        if not quiet(st, a, b, piece, n_geo[t], cars, prm[e], wc, vr, pr, mt, flags[a:b],
                      slack[a:b]):
            kpos[e] = k
            return 1
    kpos[e] = nsub
    return 0


@numba.njit(cache=True, error_model="numpy")
def broad_phase_slot(e, st, trk, off, ncar, near, piece, contact):
    """The contact broad phase of slot e's cars (on its rows of the batch's broad-phase arrays,
    as `ContactSolver.broad_phase_args`); near[e] = its answer; True if not 0 (something near)."""
    geo_all, geo_off, bar_all, bar_off, box, prm, wall_cache, vref, pairs, pcap, meta, flags, \
        slack = contact
    a, b = off[e], off[e] + ncar[e]
    t = trk[e]
    near[e] = _broad_phase(st[a:b, L.S_X], st[a:b, L.S_Y], st[a:b, L.S_YAW], piece[a:b],
                           geo_all[geo_off[t]:geo_off[t + 1]], bar_all[bar_off[t]:bar_off[t + 1]],
                           box[a:b], prm[e], wall_cache[a:b], vref[a:b], pairs[e, :pcap[e]],
                           meta[e], flags[a:b], slack[a:b])
    return near[e] != 0


@numba.njit(cache=True, error_model="numpy", **kernel.NO_REFCOUNT)
def advance_run(e0, e1, st, cp, cw, ct, u, tables, trk, off, ncar, run, kpos, near, piece, hits,
                nsub, dt, fuel_on, with_contact, snap, path, turn, contact):
    """`advance_slot` for the slots e0 .. e1 - 1 where run[e], one after the other, each until
    its tick is done (near[e] = 0); returns the first slot that needs the broad phase now
    (its kpos[e] = sub-steps done), or e1 when none does. No reference counts: the loop over
    slots passes its arrays and tuples on uncounted (`advance_slots` calls the counted parts,
    the sorted slipstream and the broad phase, which allocate)."""
    for e in range(e0, e1):
        if run[e]:
            near[e] = 0
            if advance_slot(e, st, cp, cw, ct, u, tables, trk, off, ncar, kpos, piece, hits, nsub,
                            dt, fuel_on, with_contact, snap, path, turn, contact):
                return e
    return e1


@numba.njit(cache=True, error_model="numpy")
def advance_slots(st, cp, cw, ct, u, tables, trk, off, ncar, run, kpos, near, piece, hits, nsub,
                  dt, fuel_on, with_contact, snap, path, turn, contact):
    """Every slot where run[e], one after the other: the sorted slipstream of slots with more
    than `kernel.SLIP_ALL_PAIRS` cars at a tick's start, then `advance_run` with the broad phase
    where a slot asks, until something is near (near[e] != 0: the broad phase's answer) or the
    slot's tick is done (near[e] = 0). tables: (pt, pt_off, surf, surf_off, tsc, n_geo),
    per-track tables stacked (track t: rows off[t]:off[t + 1]; tsc row t; n_geo[t] pieces);
    contact: (geo, geo_off, bar, bar_off, box, prm, wall_cache, vref, pairs, pcap, meta, flags,
    slack): ContactSolver.broad_phase_args of every slot (per track stacked, per car rows as
    `st`, per slot rows e; pairs[e, :pcap[e]]). Slots are independent: the order of their
    parts does not change a bit."""
    n = off.shape[0]
    for e in range(n):
        if run[e] and kpos[e] == 0 and ncar[e] > kernel.SLIP_ALL_PAIRS:
            kernel.tick_start(st, cp, off[e], off[e] + ncar[e], tables[4][trk[e], L.T_LENGTH])
    e = 0
    while e < n:
        e = advance_run(e, n, st, cp, cw, ct, u, tables, trk, off, ncar, run, kpos, near, piece,
                        hits, nsub, dt, fuel_on, with_contact, snap, path, turn, contact)
        if e < n and broad_phase_slot(e, st, trk, off, ncar, near, piece, contact):
            e += 1                       # something near: Python resolves it, the slot waits


@numba.njit(cache=True, error_model="numpy", parallel=True)
def advance_slots_parallel(st, cp, cw, ct, u, tables, trk, off, ncar, run, kpos, near, piece,
                           hits, nsub, dt, fuel_on, with_contact, snap, path, turn, contact):
    """`advance_slots` with the slots shared among threads (independent: bit-identical)."""
    for e in numba.prange(off.shape[0]):
        if run[e]:
            if kpos[e] == 0 and ncar[e] > kernel.SLIP_ALL_PAIRS:
                kernel.tick_start(st, cp, off[e], off[e] + ncar[e], tables[4][trk[e], L.T_LENGTH])
            while advance_run(e, e + 1, st, cp, cw, ct, u, tables, trk, off, ncar, run, kpos,
                              near, piece, hits, nsub, dt, fuel_on, with_contact, snap, path,
                              turn, contact) == e:
                if broad_phase_slot(e, st, trk, off, ncar, near, piece, contact):
                    break


@numba.njit(cache=True, inline="always")
def quiet(st, a, b, piece, n_geo, cars, prm, wall_cache, vref, pairs, meta, flags, slack):
    """True if the contact broad phase on cars a..b-1 (rows of `st`; cars 0.. of the other
    arrays, as `ContactSolver.broad_phase_args`) would return 0 having set only flags (to 0)
    and slack: every car's cached wall clearance holds, no neighbour-list rebuild is due and
    no listed pair's bounding circles meet. Then sets those as it would, with the same
    arithmetic. False (nothing written): call the broad phase."""
    n = b - a
    move_cap = prm[P_MOVE_CAP]
    for i in range(n):
        x, y, yaw = st[a + i, L.S_X], st[a + i, L.S_Y], st[a + i, L.S_YAW]
        if piece[a + i] < 0 or piece[a + i] >= n_geo or not (
                math.isfinite(x) and math.isfinite(y) and math.isfinite(yaw)):
            return False
        moved = math.sqrt((x - wall_cache[i, 0]) ** 2 + (y - wall_cache[i, 1]) ** 2)
        used = cars[i, C_GAIN] * moved + cars[i, C_RAD] * abs(_wrap(yaw - wall_cache[i, 2]))
        if not (moved < move_cap and used < wall_cache[i, 3]):
            return False
    if n > 1:
        if meta[0] == 0:
            return False
        for i in range(n):
            if (st[a + i, L.S_X] - vref[i, 0]) ** 2 + (st[a + i, L.S_Y] - vref[i, 1]) ** 2 \
                    > REBUILD_M * REBUILD_M:
                return False
        for k in range(meta[1]):
            i, j = pairs[k, 0], pairs[k, 1]
            reach = cars[i, C_RAD] + cars[j, C_RAD] + CAR_REACH_M
            if not (st[a + j, L.S_X] - st[a + i, L.S_X]) ** 2 + (st[a + j, L.S_Y]
                                                                 - st[a + i, L.S_Y]) ** 2 \
                    > reach * reach:
                return False
    for i in range(n):
        x, y, yaw = st[a + i, L.S_X], st[a + i, L.S_Y], st[a + i, L.S_YAW]
        moved = math.sqrt((x - wall_cache[i, 0]) ** 2 + (y - wall_cache[i, 1]) ** 2)
        used = cars[i, C_GAIN] * moved + cars[i, C_RAD] * abs(_wrap(yaw - wall_cache[i, 2]))
        flags[i] = 0
        slack[i] = wall_cache[i, 3] - used
    return True


@numba.njit(cache=True, error_model="numpy", **kernel.NO_REFCOUNT)
def sense_slot(e, st, off, ncar, trk, tables, half, angles, race_pos, origin, active, max_range,
                local, out):
    """SensorSuite.frame without focus and noise for slot e's cars. tables: (geo, geo_off,
    runs, runs_off, piece_run, piece_run_off), per track stacked as `advance_slots`'s."""
    geo, geo_off, runs, runs_off, prun, prun_off = tables
    a, b = off[e], off[e] + ncar[e]
    t = trk[e]
    sensor_kernel(local[:b - a], st[a:b], geo[geo_off[t]:geo_off[t + 1]],
                  runs[runs_off[t]:runs_off[t + 1]], prun[prun_off[t]:prun_off[t + 1]], half[t],
                  angles[a:b], race_pos[a:b], origin[a:b], active[a:b], max_range, out[a:b])


@numba.njit(cache=True, error_model="numpy", **kernel.NO_REFCOUNT)
def sense_slots(st, run, off, ncar, trk, tables, half, angles, race_pos, origin, active,
                max_range, local, out):
    """`sense_slot` for every slot where run[e], one after the other."""
    for e in range(off.shape[0]):
        if run[e]:
            sense_slot(e, st, off, ncar, trk, tables, half, angles, race_pos, origin, active,
                        max_range, local, out)


@numba.njit(cache=True, error_model="numpy", parallel=True)
def sense_slots_parallel(st, run, off, ncar, trk, tables, half, angles, race_pos, origin,
                         active, max_range, local, out):
    """`sense_slots` with the slots shared among threads."""
    for e in numba.prange(off.shape[0]):
        if run[e]:
            sense_slot(e, st, off, ncar, trk, tables, half, angles, race_pos, origin, active,
                        max_range, local, out)


@numba.njit(cache=True, error_model="numpy", **kernel.NO_REFCOUNT)
def race_positions(st, run, off, ncar, race_pos):
    """World._update_race_pos per slot where run[e]: rank by laps, then distance raced, then
    row."""
    for e in range(off.shape[0]):
        if not run[e] or ncar[e] < 2:
            continue
        rank_rows(st, off[e], off[e] + ncar[e], race_pos)
