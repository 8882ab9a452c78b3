"""`WorldBatch`: many independent episodes advanced together, each exactly as its own `World`.

A batch has `n_slots` slots; slot e holds one episode: up to `capacity` cars on one track, in
rows `e * capacity ...` of shared arrays (`state` (C, N_STATE) Fortran order, `controls`
(C, 5), `sensors` (C, 79) wire order, C = n_slots * capacity; unused rows are never touched).
Slots may be on different tracks and hold different cars; cars of different slots never see
each other (no contact, no opponents reading, separate race positions).

`step(mask)` advances the masked slots by 0.02 s and computes their sensors, with results
bit-identical to a `World` + `SensorSuite` per slot (as `madsim.envs.backends.LocalBackend`
builds them): the same kernels (`kernel.advance_car`, whole ticks where the contact broad
phase provably finds nothing on the way and else the broad phase after each sub-step, as
`contact_kernels.whole_tick`; `sensors.sensor_kernel`) run in one compiled call over all slots,
and Python is entered only for a slot whose broad phase finds something near (its own
`ContactSolver` then resolves, as in `World`).

Contact solvers are the expensive part of a World (building the pymunk barrier segments takes
~100 ms and a few MB per solver), so a slot gets one only when it first needs one: until then
its broad phase runs on its own copy of the solver's reset-state caches (the broad phase never
touches pymunk), and at the first "near" the caches move into a solver taken from a pool of
solvers built for the same track and cars. The solver goes back to the pool, reset, when the
slot starts its next episode. Episodes that never touch a barrier or another car never build one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba
import numpy as np
from numba import typed

from madsim.cars.spec import CarSpec
from madsim.physics import kernel
from madsim.physics import layout as L
from madsim.physics.contact_kernels import C_GAIN, C_RAD, P_MOVE_CAP, _broad_phase, whole_tick_rows
from madsim.physics.world_tick import rank_rows
from madsim.physics.sensors import (
    N_VALUES,
    O_FOCUS,
    O_TPOS,
    SCR_DEFAULT_ANGLES_DEG,
    SENSOR_RANGE_M,
    FocusState,
    SensorFrame,
    apply_noise,
    sensor_kernel,
)
from madsim.physics.tables import car_table, piece_table
from madsim.physics.world import DAMAGE_SKILL, DT, SUBSTEPS, World, contact_available
from madsim.tracks.track import Track

__all__ = ["WorldBatch"]

_SOLVER_CONSTS = 4       # broad_phase_args: (geo, bar, cars, prm) never written, then 6 caches

# The batch loops are module-level kernels in numba's disk cache (`madsim.kernel_cache` renews
# their entries when any kernel module changes): one per-slot body each, run by a serial and a
# parallel (slots shared among threads) loop. With contact off the broad phase is never called.


@numba.njit(cache=True, error_model="numpy")
def _advance_slot(e, st, cp, cw, ct, u, pts, surfs, tscs, trk, off, ncar, kpos, near, piece, bps,
                  hits, nsub, dt, fuel_on, with_contact, snap, path, turn):
    """World.step for slot e: sub-steps from kpos[e] (the rest at once where provably nothing
    is near) until the broad phase finds something near (near[e] != 0, kpos[e] = sub-steps
    done) or all nsub are done (near[e] = 0)."""
    a, b = off[e], off[e] + ncar[e]
    t = trk[e]
    pt, surf, tsc = pts[t], surfs[t], tscs[t]
    k = kpos[e]
    if k == 0:
        hits[a:b] = False
        if b - a > 1:      # World.step: slipstream from the poses at the tick's start
            kernel.slipstream(st, cp, a, b, tsc[L.T_LENGTH])
    if not with_contact:
        for i in range(a, b):
            kernel.advance_car(st, i, cp, cw, ct, pt, surf, tsc, u, nsub, dt, fuel_on)
        kpos[e] = nsub
        near[e] = 0
        return
    bp = bps[np.int64(e)]
    found = 0
    while k < nsub:
        k += whole_tick_rows(st, a, b, cp, cw, ct, pt, surf, tsc, u, nsub - k, dt, fuel_on, bp,
                             snap, path, turn)
        for i in range(a, b):
            piece[i] = int(st[i, L.S_PIECE])
        if b - a == 1 and _clear_of_walls(st[a, L.S_X], st[a, L.S_Y], st[a, L.S_YAW], piece[a],
                                          bp[0], bp[2], bp[3], bp[4], bp[8], bp[9]):
            continue
        found = _broad_phase(st[a:b, L.S_X], st[a:b, L.S_Y], st[a:b, L.S_YAW], piece[a:b],
                             bp[0], bp[1], bp[2], bp[3], bp[4], bp[5], bp[6], bp[7], bp[8], bp[9])
        if found != 0:
            break
    kpos[e] = k
    near[e] = found


@numba.njit(cache=True, error_model="numpy")
def _advance(st, cp, cw, ct, u, pts, surfs, tscs, trk, off, ncar, run, kpos, near, piece, bps,
             hits, nsub, dt, fuel_on, with_contact, snap, path, turn):
    """`_advance_slot` for every slot where run[e], one after the other."""
    for e in range(off.shape[0]):
        if run[e]:
            _advance_slot(e, st, cp, cw, ct, u, pts, surfs, tscs, trk, off, ncar, kpos, near,
                          piece, bps, hits, nsub, dt, fuel_on, with_contact, snap, path, turn)


@numba.njit(cache=True, error_model="numpy", parallel=True)
def _advance_parallel(st, cp, cw, ct, u, pts, surfs, tscs, trk, off, ncar, run, kpos, near, piece,
                      bps, hits, nsub, dt, fuel_on, with_contact, snap, path, turn):
    """`_advance` with the slots shared among threads (independent: bit-identical)."""
    for e in numba.prange(off.shape[0]):
        if run[e]:
            _advance_slot(e, st, cp, cw, ct, u, pts, surfs, tscs, trk, off, ncar, kpos, near,
                          piece, bps, hits, nsub, dt, fuel_on, with_contact, snap, path, turn)


@numba.njit(cache=True, error_model="numpy")
def _sense_slot(e, st, off, ncar, trk, geos, runs, pruns, half, angles, race_pos, origin, active,
                max_range, local, out):
    """SensorSuite.frame without focus and noise for slot e's cars."""
    a, b = off[e], off[e] + ncar[e]
    t = trk[e]
    sensor_kernel(local[:b - a], st[a:b], geos[t], runs[t], pruns[t], half[t], angles[a:b],
                  race_pos[a:b], origin[a:b], active[a:b], max_range, out[a:b])


@numba.njit(cache=True, error_model="numpy")
def _sense(st, run, off, ncar, trk, geos, runs, pruns, half, angles, race_pos, origin, active,
           max_range, local, out):
    """`_sense_slot` for every slot where run[e], one after the other."""
    for e in range(off.shape[0]):
        if run[e]:
            _sense_slot(e, st, off, ncar, trk, geos, runs, pruns, half, angles, race_pos, origin,
                        active, max_range, local, out)


@numba.njit(cache=True, error_model="numpy", parallel=True)
def _sense_parallel(st, run, off, ncar, trk, geos, runs, pruns, half, angles, race_pos, origin,
                    active, max_range, local, out):
    """`_sense` with the slots shared among threads."""
    for e in numba.prange(off.shape[0]):
        if run[e]:
            _sense_slot(e, st, off, ncar, trk, geos, runs, pruns, half, angles, race_pos, origin,
                        active, max_range, local, out)


@numba.njit(cache=True, error_model="numpy")
def _race_positions(st, run, off, ncar, race_pos):
    """World._update_race_pos per slot where run[e]: rank by laps, then distance raced, then
    row."""
    for e in range(off.shape[0]):
        if not run[e] or ncar[e] < 2:
            continue
        rank_rows(st, off[e], off[e] + ncar[e], race_pos)


@numba.njit(cache=True, inline="always")
def _clear_of_walls(x, y, yaw, piece, geo, cars, prm, wall_cache, flags, slack):
    """The contact broad phase's first test for a lone car, with the same arithmetic and
    effects: True if the car's cached wall clearance cannot have been used up since it was
    measured (the broad phase would then return 0 having set only flags and slack). False:
    call the broad phase."""
    if piece < 0 or piece >= geo.shape[0] or not (
            math.isfinite(x) and math.isfinite(y) and math.isfinite(yaw)):
        return False
    moved = math.sqrt((x - wall_cache[0, 0]) ** 2 + (y - wall_cache[0, 1]) ** 2)
    turn = yaw - wall_cache[0, 2]
    turn = turn - 2.0 * math.pi * math.floor((turn + math.pi) / (2.0 * math.pi))
    used = cars[0, C_GAIN] * moved + cars[0, C_RAD] * abs(turn)
    if moved < prm[P_MOVE_CAP] and used < wall_cache[0, 3]:
        flags[0] = 0
        slack[0] = wall_cache[0, 3] - used
        return True
    return False


@dataclass
class _Kind:
    """What slots with the same (track, cars) share: a World used to compute start states,
    and the contact solvers: constant broad-phase tables, reset-state caches, idle solvers."""

    world: World
    track_index: int
    cp: np.ndarray
    curve_w: np.ndarray
    curve_t: np.ndarray
    solver_args: tuple | None = None      # (consts..., fresh caches...) of a reset solver
    pool: list = field(default_factory=list)


class WorldBatch:
    """`n_slots` independent episodes of at most `capacity` cars each (see the module
    docstring). contact, fuel, damage: as `World` (and `LocalBackend`); threads: share the
    slots among numba's threads (bit-identical results); focus: compute SCR focus readings
    (once per second per car, in Python, as `SensorSuite`) - off, `sensors` keeps focus at -1.

    Per slot e: `offsets[e]` first row, `n_cars[e]` cars; arrays with one row per car:
    `state`, `controls` (the caller writes them before `step`), `sensors`, `hits` (contact
    with a wall or a car during the last tick of the slot), `race_pos`.
    """

    def __init__(self, n_slots: int, capacity: int, *, contact: bool = True, fuel: bool = False,
                 damage: bool = True, threads: bool = False, focus: bool = False,
                 angles_deg=SCR_DEFAULT_ANGLES_DEG):
        if n_slots < 1 or capacity < 1:
            raise ValueError(f"n_slots and capacity must be >= 1, got {n_slots}, {capacity}")
        self.n_slots, self.capacity = int(n_slots), int(capacity)
        self.contact = bool(contact) and contact_available()
        self.fuel, self.damage, self.focus = bool(fuel), bool(damage), bool(focus)
        c = self.n_slots * self.capacity
        self.offsets = np.arange(self.n_slots, dtype=np.int64) * self.capacity
        self.n_cars = np.zeros(self.n_slots, dtype=np.int64)
        self.state = np.zeros((c, L.N_STATE), order="F")
        self.controls = np.zeros((c, 5))
        self.sensors = np.zeros((c, N_VALUES))
        self.hits = np.zeros(c, dtype=bool)
        self.race_pos = np.ones(c, dtype=np.int64)
        self._cp = np.zeros((c, L.N_CAR))
        self._curve_w = np.ones((c, 1))
        self._curve_t = np.zeros((c, 1))
        self._piece = np.zeros(c, dtype=np.int64)
        self._snap = np.zeros_like(self.state)       # whole-tick scratch (contact_kernels.whole_tick)
        self._path, self._turn = np.zeros(c), np.zeros(c)
        angles = np.asarray(angles_deg, dtype=np.float64)
        if angles.shape != (19,):
            raise ValueError(f"angles_deg must be 19 rangefinder angles, got shape {angles.shape}")
        self._angles = np.tile(angles, (c, 1))
        self._origin = np.zeros(c)
        self._active = np.ones(c, dtype=np.bool_)
        self._local = np.arange(self.capacity, dtype=np.int64)
        self._track = np.zeros(self.n_slots, dtype=np.int64)
        self._kpos = np.zeros(self.n_slots, dtype=np.int64)
        self._near = np.zeros(self.n_slots, dtype=np.int64)
        self._info = np.zeros(2, dtype=np.int64)
        self._tracks: dict[int, int] = {}            # id(Track) -> index
        self._track_objs: list[Track] = []
        # per track: (pt, surf, tsc, geo, runs, prun) in Python, and in typed lists for the kernels
        self._tables: list[tuple] = []
        self._pt, self._surf, self._tsc = typed.List(), typed.List(), typed.List()
        self._geo, self._runs, self._prun = typed.List(), typed.List(), typed.List()
        self._half = np.zeros(0)
        self._kinds: dict = {}
        self._slot_kind: list[_Kind | None] = [None] * self.n_slots
        self._solver: list = [None] * self.n_slots     # attached ContactSolver per slot
        self._bps = _list_of(_dummy_bp(), self.n_slots)   # broad-phase args per slot
        self._noise_rng: list = [None] * self.n_slots
        self._noisy_slots = 0
        self._focus_state: list = [None] * self.n_slots
        self.contact_pairs: list[list] = [[] for _ in range(self.n_slots)]
        self.solvers_built = 0
        threads = bool(threads)
        self._advance = _advance_parallel if threads else _advance
        self._sense = _sense_parallel if threads else _sense

    # --- episodes -----------------------------------------------------------------------------

    def rows(self, slot: int) -> slice:
        """The rows of slot `slot`'s cars."""
        a = int(self.offsets[slot])
        return slice(a, a + int(self.n_cars[slot]))

    def start(self, slot: int, key, track: Track, cars: list[CarSpec], placements, *,
              noisy: bool = False, rng: np.random.Generator | None = None) -> None:
        """Start an episode in `slot` (as `LocalBackend.start`): cars placed at `placements`
        (N, 3) = (s m, n m, speed m/s); its sensors come with the next `sense` (noise from
        `rng` when `noisy`). key: hashable name of (track, cars); equal keys must mean equal
        tracks and cars."""
        cars = list(cars)
        n = len(cars)
        if not 1 <= n <= self.capacity:
            raise ValueError(f"slot {slot}: {n} cars, the batch holds 1..{self.capacity} per slot")
        if noisy and not isinstance(rng, np.random.Generator):
            raise TypeError("start(noisy=True) needs rng, a numpy Generator")
        kind = self._kind(key, track, cars)
        self._release(slot)
        a = int(self.offsets[slot])
        rows = slice(a, a + n)
        kind.world.reset(placements)
        self.n_cars[slot] = n
        self._track[slot] = kind.track_index
        self._slot_kind[slot] = kind
        self.state[rows] = kind.world.state
        self.race_pos[rows] = kind.world.race_pos
        self._cp[rows] = kind.cp
        self._put_curves(rows, kind)
        self.controls[rows] = 0.0
        self.hits[rows] = False
        self._origin[rows] = self.state[rows, L.S_DIST]
        self._piece[rows] = self.state[rows, L.S_PIECE].astype(np.int64)
        self.contact_pairs[slot] = []
        if (self._noise_rng[slot] is not None) != bool(noisy):
            self._noisy_slots += 1 if noisy else -1
        self._noise_rng[slot] = rng if noisy else None
        self._focus_state[slot] = FocusState(n) if self.focus else None
        if self.contact:
            consts, caches = kind.solver_args[:_SOLVER_CONSTS], kind.solver_args[_SOLVER_CONSTS:]
            _list_set(self._bps, slot, consts + tuple(c.copy() for c in caches))

    def _kind(self, key, track: Track, cars: list[CarSpec]) -> _Kind:
        kind = self._kinds.get(key)
        if kind is not None:
            return kind
        world = World(track, cars, np.random.default_rng(0), fuel=self.fuel, damage=self.damage,
                      contact=False)
        cp, curve_w, curve_t = car_table(world.cars, list(world.skills))
        kind = _Kind(world, self._track_of(track), cp, curve_w, curve_t)
        if self.contact:
            solver = self._new_solver(kind)
            geo = self._tables[kind.track_index][3]
            args = solver.broad_phase_args
            # the slot copies hold writable arrays only (one numba type for every slot)
            kind.solver_args = (geo,) + tuple(args[1:_SOLVER_CONSTS]) + tuple(
                c.copy() for c in args[_SOLVER_CONSTS:])
            kind.pool.append(solver)
        self._kinds[key] = kind
        return kind

    def _track_of(self, track: Track) -> int:
        t = self._tracks.get(id(track))       # the Track objects are kept: ids stay unique
        if t is None:
            t = len(self._track_objs)
            self._tracks[id(track)] = t
            self._track_objs.append(track)
            tables = piece_table(track) + (np.array(track.geo, dtype=np.float64),
                                           np.array(track.runs, dtype=np.float64),
                                           np.array(track.piece_run, dtype=np.int64))
            self._tables.append(tables)
            if t == 0:
                (self._pt, self._surf, self._tsc, self._geo, self._runs,
                 self._prun) = (_list_of(x, 1) for x in tables)
            else:
                for lst, x in zip((self._pt, self._surf, self._tsc, self._geo, self._runs,
                                   self._prun), tables):
                    _list_append(lst, x)
            self._half = np.append(self._half, track.width / 2)
        return t

    def _put_curves(self, rows: slice, kind: _Kind) -> None:
        m = kind.curve_w.shape[1]
        if m > self._curve_w.shape[1]:       # wider torque curves: pad every row (never read)
            pad = m - self._curve_w.shape[1]
            self._curve_w = np.pad(self._curve_w, ((0, 0), (0, pad)), mode="edge")
            self._curve_t = np.pad(self._curve_t, ((0, 0), (0, pad)), mode="edge")
        self._curve_w[rows, :m] = kind.curve_w
        self._curve_t[rows, :m] = kind.curve_t
        self._curve_w[rows, m:] = kind.curve_w[:, -1:]
        self._curve_t[rows, m:] = kind.curve_t[:, -1:]

    def _new_solver(self, kind: _Kind):
        """A ContactSolver as `World` builds it."""
        from madsim.physics.contact import ContactSolver

        w, cp = kind.world, kind.cp
        skills = w.skills
        kw = {"damage_factor": DAMAGE_SKILL[skills[0]]} if len(set(skills)) == 1 else {}
        self.solvers_built += 1
        return ContactSolver(w.track, cp[:, L.C_HALF_LEN].copy(), cp[:, L.C_HALF_WID].copy(),
                             np.array([c.mass_total for c in w.cars]), cp[:, L.C_IZZ].copy(),
                             **kw)

    def _release(self, slot: int) -> None:
        solver = self._solver[slot]
        if solver is not None:
            solver.reset()
            self._slot_kind[slot].pool.append(solver)
            self._solver[slot] = None

    def _attach(self, slot: int):
        """Give the slot a contact solver holding its broad-phase caches."""
        kind = self._slot_kind[slot]
        solver = kind.pool.pop() if kind.pool else self._new_solver(kind)
        mine = _list_get(self._bps, slot)
        theirs = solver.broad_phase_args
        for src, dst in zip(mine[_SOLVER_CONSTS:], theirs[_SOLVER_CONSTS:]):
            k = min(src.shape[0], dst.shape[0])
            dst[:k] = src[:k]
        self._solver[slot] = solver
        return solver

    # --- the tick ------------------------------------------------------------------------------

    def step(self, mask: np.ndarray, substeps: int = SUBSTEPS) -> None:
        """Advance the slots where `mask` (n_slots,) is True by `substeps` sub-steps of 0.002 s
        (default 10: 0.02 s; TORCS's schedule gives 10 or 11) with their `controls` rows held
        (as `World.step`; non-finite controls raise ValueError naming slot, car and column),
        then compute their sensors and `hits`."""
        if substeps != SUBSTEPS and not (isinstance(substeps, (int, np.integer)) and 1 <= substeps <= 100):
            raise ValueError(f"substeps must be an integer in 1..100, got {substeps!r}")
        nsub = int(substeps)
        mask = np.asarray(mask, dtype=bool)
        u = self.controls
        kernel.check_controls(u, self._info)
        if self._info[0]:
            row, col = divmod(int(self._info[1]), 5)
            slot = row // self.capacity
            raise ValueError(f"controls: slot {slot} car {row - slot * self.capacity} "
                             f"{L.CONTROL_COLUMNS[col]} is {u[row, col]!r} (must be finite)")
        run = mask.copy()
        self._kpos[:] = 0
        while True:
            self._advance(self.state, self._cp, self._curve_w, self._curve_t, u, self._pt,
                          self._surf, self._tsc, self._track, self.offsets, self.n_cars, run,
                          self._kpos, self._near, self._piece, self._bps, self.hits, nsub,
                          DT, self.fuel, self.contact, self._snap, self._path, self._turn)
            near = np.flatnonzero(run & (self._near != 0))
            if near.size == 0:
                break
            for e in near:
                self._resolve(int(e))
            run[:] = False
            run[near] = self._kpos[near] < nsub
            if not run.any():
                break
        _race_positions(self.state, mask, self.offsets, self.n_cars, self.race_pos)
        self.sense(mask)

    def _resolve(self, slot: int) -> None:
        """World.finish_tick's contact resolve for one slot."""
        solver = self._solver[slot] or self._attach(slot)
        rows = self.rows(slot)
        st = self.state
        cols = [st[rows, c] for c in (L.S_X, L.S_Y, L.S_YAW, L.S_VXG, L.S_VYG, L.S_R)]
        rep = solver.resolve(*cols, self._piece[rows], DT)
        hit_w, hit_c = np.asarray(rep.wall, dtype=bool), np.asarray(rep.car, dtype=bool)
        if hit_w.any() or hit_c.any():
            self.hits[rows] |= hit_w | hit_c
            self.contact_pairs[slot].extend(tuple(p) for p in rep.pairs)
            if self.damage:
                st[rows, L.S_DAMAGE] += np.asarray(rep.damage, dtype=np.float64)
            t = int(self._track[slot])
            pt, surf, tsc = self._tables[t][:3]
            kernel.refresh(st[rows], self._cp[rows], pt, surf, tsc, True)
        args = solver.broad_phase_args          # resolve may have grown its pair list
        _list_set(self._bps, slot, (self._tables[int(self._track[slot])][3],) + tuple(args[1:]))

    def sense(self, mask: np.ndarray) -> None:
        """Compute `sensors` of the masked slots (as `SensorSuite.frame`; `step` does this)."""
        mask = np.asarray(mask, dtype=bool)
        self._sense(self.state, mask, self.offsets, self.n_cars, self._track, self._geo,
                    self._runs, self._prun, self._half, self._angles, self.race_pos, self._origin,
                    self._active, SENSOR_RANGE_M, self._local, self.sensors)
        if self.focus or self._noisy_slots:
            for e in np.flatnonzero(mask).tolist():
                if self.focus or self._noise_rng[e] is not None:
                    self._focus_and_noise(e)

    def _focus_and_noise(self, slot: int) -> None:
        """The parts of SensorSuite.frame that stay in Python: focus readings, noise."""
        rows = self.rows(slot)
        flat = self.sensors[rows]
        focus = self._focus_state[slot]
        st = self.state[rows]
        if focus is not None and st[0, L.S_TIME] >= focus.earliest_s:
            local = self._local[:flat.shape[0]]
            due = np.nonzero(focus.due(local, st[:, L.S_TIME], np.abs(flat[:, O_TPOS]) <= 1.0))[0]
            track = self._slot_kind[slot].world.track
            for j in due:
                centre = focus.requested_deg[j]
                flat[j, O_FOCUS:O_FOCUS + 5] = track.rangefinders(
                    st[j:j + 1, L.S_X], st[j:j + 1, L.S_Y], st[j:j + 1, L.S_YAW],
                    centre + np.arange(-2.0, 3.0), s_hint=st[j:j + 1, L.S_S],
                    max_range_m=SENSOR_RANGE_M)[0]
        rng = self._noise_rng[slot]
        if rng is not None:
            apply_noise(SensorFrame(flat, self._local[:flat.shape[0]]), rng)

    @property
    def solvers_attached(self) -> int:
        """Slots that currently hold a contact solver."""
        return sum(s is not None for s in self._solver)


# typed-list operations inside cached kernels: numba compiles typed.List's Python-side methods
# in every process (about 0.15 s per item type and operation), these come from the disk cache


@numba.njit(cache=True)
def _list_of(item, n):
    """A typed list of n times `item`."""
    out = typed.List()
    for _ in range(n):
        out.append(item)
    return out


@numba.njit(cache=True)
def _list_append(items, item):
    items.append(item)


@numba.njit(cache=True)
def _list_set(items, i, item):
    items[i] = item


@numba.njit(cache=True)
def _list_get(items, i):
    return items[i]


def _dummy_bp() -> tuple:
    """Broad-phase arguments of the numba types a solver's have, for slots without one."""
    f2, f1 = np.zeros((1, 1)), np.zeros(1)
    return (f2, f2, f2, f1, f2, f2, np.zeros((1, 2), dtype=np.int64), np.zeros(3, dtype=np.int64),
            np.zeros(1, dtype=np.int8), f1)


