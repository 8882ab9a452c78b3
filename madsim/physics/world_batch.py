"""`WorldBatch`: many independent episodes advanced together, each exactly as its own `World`.

A batch has `n_slots` slots; slot e holds one episode: up to `capacity` cars on one track, in
rows `e * capacity ...` of shared arrays (`state` (C, N_STATE) C order, `controls`
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
~100 ms and a few MB per solver), so a slot gets one only when it first needs one: the broad
phase (which never touches pymunk) runs on the slot's rows of batch-wide copies of a solver's
tables and caches, and at the first "near" the slot takes a solver from a pool of solvers
built for the same track and cars; each resolve copies the caches into it and back. The
solver goes back to the pool, reset, when the slot starts its next episode. Episodes that
never touch a barrier or another car never build one.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from madsim.cars.spec import CarSpec
from madsim.physics import kernel
from madsim.physics import layout as L
from madsim.physics import world_tick
from madsim.physics.sensors import (
    N_VALUES,
    O_TPOS,
    SCR_DEFAULT_ANGLES_DEG,
    SENSOR_RANGE_M,
    FocusState,
    SensorFrame,
    apply_noise,
    fill_rays,
    focus_kernel,
    uncast_angles,
)
from madsim.physics.tables import car_table, piece_table
from madsim.physics.world import DAMAGE_SKILL, DT, SUBSTEPS, World, contact_available, finish_crossings
from madsim.physics.contact_kernels import N_PRM, SNAP_COLUMNS
from madsim.physics.world_batch_kernels import (
    advance_slots,
    advance_slots_parallel,
    race_positions,
    sense_slots,
    sense_slots_parallel,
)
from madsim.tracks.track import Track

__all__ = ["WorldBatch"]

_SOLVER_CONSTS = 4       # broad_phase_args: (geo, bar, cars, prm) never written, then 6 caches

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
    race_laps: as `World` (every slot's race; read at each `start`).

    Per slot e: `offsets[e]` first row, `n_cars[e]` cars; arrays with one row per car:
    `state`, `controls` (the caller writes them before `step`), `sensors`, `hits` (contact
    with a wall or a car during the last tick of the slot), `race_pos`.
    """

    def __init__(self, n_slots: int, capacity: int, *, contact: bool = True, fuel: bool = False,
                 damage: bool = True, threads: bool = False, focus: bool = False,
                 angles_deg=SCR_DEFAULT_ANGLES_DEG, race_laps: int | None = None):
        if n_slots < 1 or capacity < 1:
            raise ValueError(f"n_slots and capacity must be >= 1, got {n_slots}, {capacity}")
        self.n_slots, self.capacity = int(n_slots), int(capacity)
        self.contact = bool(contact) and contact_available()
        self.fuel, self.damage, self.focus = bool(fuel), bool(damage), bool(focus)
        self.race_laps = race_laps
        finish_crossings(race_laps)
        c = self.n_slots * self.capacity
        self.offsets = np.arange(self.n_slots, dtype=np.int64) * self.capacity
        self.n_cars = np.zeros(self.n_slots, dtype=np.int64)
        self.state = np.zeros((c, L.N_STATE))     # C order: a car's state in a few cache lines
        self.controls = np.zeros((c, 5))
        self.sensors = np.zeros((c, N_VALUES))
        self.hits = np.zeros(c, dtype=bool)
        self.race_pos = np.ones(c, dtype=np.int64)
        self._cp = np.zeros((c, L.N_CAR))
        self._curve_w = np.ones((c, 1))
        self._curve_t = np.zeros((c, 1))
        self._piece = np.zeros(c, dtype=np.int64)
        # whole-tick scratch (contact_kernels.whole_tick), C order: a car's row in 10 cache lines
        self._snap = np.zeros((c, SNAP_COLUMNS))
        self._path, self._turn = np.zeros(c), np.zeros(c)
        angles = np.asarray(angles_deg, dtype=np.float64)
        if angles.shape != (19,):
            raise ValueError(f"angles_deg must be 19 rangefinder angles, got shape {angles.shape}")
        self._angles = np.tile(angles, (c, 1))
        self._cast = self._angles.copy()      # the kernels' angles: NaN = a ray not cast
        self._origin = np.zeros(c)
        self._active = np.ones(c, dtype=np.bool_)
        self._local = np.arange(self.capacity, dtype=np.int64)
        self._track = np.zeros(self.n_slots, dtype=np.int64)
        self._kpos = np.zeros(self.n_slots, dtype=np.int64)
        self._near = np.zeros(self.n_slots, dtype=np.int64)
        self._info = np.zeros(2, dtype=np.int64)
        self._tracks: dict[int, int] = {}            # id(Track) -> index
        self._track_objs: list[Track] = []
        # per track: (pt, surf, tsc, geo, runs, prun) in Python; for the physics kernels stacked
        # (track t: rows off[t]:off[t + 1])
        self._tables: list[tuple] = []
        self._pt, self._surf, self._geo_rows, self._bar, self._runs = (_Stacked() for _ in range(5))
        self._prun = _Stacked(ndim=1, dtype=np.int64)
        self._tsc_all = np.zeros((0, 4))
        self._n_geo = np.zeros(0, dtype=np.int64)      # pieces per track
        self._half = np.zeros(0)
        self._kinds: dict = {}
        self._slot_kind: list[_Kind | None] = [None] * self.n_slots
        self._solver: list = [None] * self.n_slots     # attached ContactSolver per slot
        # the contact broad phase's tables and caches (ContactSolver.broad_phase_args) of every
        # slot, rows as `state` (per car) or one per slot; a slot's solver, once attached, holds
        # them during its resolve only (`_resolve` copies them there and back)
        self._box = np.zeros((c, 7))                   # per-car constants
        self._prm = np.zeros((self.n_slots, N_PRM))    # parameters
        self._wall_cache = np.zeros((c, 4))
        self._vref = np.zeros((c, 2))
        self._pairs = np.zeros((self.n_slots, max(64, 8 * self.capacity), 2), dtype=np.int64)
        self._pcap = np.zeros(self.n_slots, dtype=np.int64)   # the slot's pair-list capacity
        self._meta = np.zeros((self.n_slots, 3), dtype=np.int64)
        self._flags = np.zeros(c, dtype=np.int8)
        self._slack = np.zeros(c)
        self._noise_rng: list = [None] * self.n_slots
        self._noisy_slots = 0
        self._focus_state: list = [None] * self.n_slots
        self.contact_pairs: list[list] = [[] for _ in range(self.n_slots)]
        self.solvers_built = 0
        threads = bool(threads)
        self._advance = advance_slots_parallel if threads else advance_slots
        self._sense = sense_slots_parallel if threads else sense_slots

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
        self._cp[rows, L.C_FINISH] = finish_crossings(self.race_laps)
        self._put_curves(rows, kind)
        self.controls[rows] = 0.0
        self.hits[rows] = False
        self._origin[rows] = self.state[rows, L.S_DIST]
        self._cast[a:a + self.capacity] = self._angles[a:a + self.capacity]
        self._piece[rows] = self.state[rows, L.S_PIECE].astype(np.int64)
        self.contact_pairs[slot] = []
        if (self._noise_rng[slot] is not None) != bool(noisy):
            self._noisy_slots += 1 if noisy else -1
        self._noise_rng[slot] = rng if noisy else None
        self._focus_state[slot] = FocusState(n) if self.focus else None
        if self.contact:
            args = kind.solver_args
            self._box[rows], self._prm[slot] = args[2], args[3]
            self._pcap[slot] = args[6].shape[0]
            for src, dst in zip(args[_SOLVER_CONSTS:], self._caches(slot)):
                dst[...] = src

    def _caches(self, slot: int) -> tuple:
        """Views of slot `slot`'s broad-phase caches, as ContactSolver.broad_phase_args[4:]."""
        rows = self.rows(slot)
        return (self._wall_cache[rows], self._vref[rows], self._pairs[slot, :self._pcap[slot]],
                self._meta[slot], self._flags[rows], self._slack[rows])

    def _kind(self, key, track: Track, cars: list[CarSpec]) -> _Kind:
        kind = self._kinds.get(key)
        if kind is not None:
            return kind
        world = World(track, cars, np.random.default_rng(0), fuel=self.fuel, damage=self.damage,
                      contact=False)
        cp, curve_w, curve_t = car_table(world.cars, list(world.skills), self.damage)
        kind = _Kind(world, self._track_of(track), cp, curve_w, curve_t)
        if self.contact:
            solver = self._new_solver(kind)
            t = kind.track_index
            args = solver.broad_phase_args
            kind.solver_args = tuple(c.copy() for c in args)    # (the caches as reset)
            if self._bar.rows(t) is None:
                self._bar.put(t, args[1])
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
            pt, surf, tsc, geo, runs, prun = tables
            for stack, table in zip((self._pt, self._surf, self._geo_rows, self._runs,
                                     self._prun), (pt, surf, geo, runs, prun)):
                stack.put(t, table)
            self._tsc_all = np.vstack([self._tsc_all, tsc[None]])
            self._n_geo = np.append(self._n_geo, geo.shape[0])
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
        """Give the slot a contact solver (its caches come with each `_resolve`)."""
        kind = self._slot_kind[slot]
        solver = kind.pool.pop() if kind.pool else self._new_solver(kind)
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
        u = self.controls.copy()      # the tick's own: a shift's cap writes its accel (World.step)
        kernel.check_controls(u, self._info)
        if self._info[0]:
            row, col = divmod(int(self._info[1]), 5)
            slot = row // self.capacity
            raise ValueError(f"controls: slot {slot} car {row - slot * self.capacity} "
                             f"{L.CONTROL_COLUMNS[col]} is {u[row, col]!r} (must be finite)")
        run = mask.copy()
        self._kpos[:] = 0
        tables = (self._pt.all, self._pt.off, self._surf.all, self._surf.off, self._tsc_all,
                  self._n_geo)
        contact = (self._geo_rows.all, self._geo_rows.off, self._bar.all, self._bar.off,
                   self._box, self._prm, self._wall_cache, self._vref, self._pairs, self._pcap,
                   self._meta, self._flags, self._slack)
        while True:
            self._advance(self.state, self._cp, self._curve_w, self._curve_t, u, tables,
                          self._track, self.offsets, self.n_cars, run, self._kpos, self._near,
                          self._piece, self.hits, nsub, DT, self.fuel, self.contact, self._snap,
                          self._path, self._turn, contact)
            near = np.flatnonzero(run & (self._near != 0))
            if near.size == 0:
                break
            for e in near:
                self._resolve(int(e))
            run[:] = False
            run[near] = self._kpos[near] < nsub
            if not run.any():
                break
        race_positions(self.state, mask, self.offsets, self.n_cars, self.race_pos)
        self.sense(mask)

    def _resolve(self, slot: int) -> None:
        """The contact response for one slot after the broad phase found it near (the pymunk
        narrow phase, then `world_tick.respond_tick` as in World.finish_tick)."""
        solver = self._solver[slot] or self._attach(slot)
        for src, dst in zip(self._caches(slot), solver.broad_phase_args[_SOLVER_CONSTS:]):
            k = min(src.shape[0], dst.shape[0])
            dst[:k] = src[:k]
        rows = self.rows(slot)
        which = [L.S_X, L.S_Y, L.S_YAW, L.S_VXG, L.S_VYG, L.S_R]
        x, y, yaw, vx, vy, w = (np.ascontiguousarray(self.state[rows, c]) for c in which)
        piece = self._piece[rows]
        if solver.broad_phase(x, y, yaw, piece) > 0:
            ints, floats = solver.narrow(x, y, yaw, DT)
            keys, codes, mat, blocked, moved, travel, pair_out = solver.respond_arrays()
            n = x.shape[0]
            scratch = (np.zeros(n, dtype=bool), np.zeros(n, dtype=bool), np.zeros(n))
            tick_pairs, count = np.zeros_like(pair_out), np.zeros(1, dtype=np.int64)
            hits = self.hits[rows]
            t = int(self._track[slot])
            pt, surf, tsc = self._tables[t][:3]
            geo, bar, cars, prm, _, _, bp_pairs, meta, flags, slack = solver.broad_phase_args
            world_tick.respond_tick(ints, floats, keys, codes, x, y, yaw, vx, vy, w, piece, geo, bar,
                                    cars, prm, bp_pairs, meta, flags, slack, mat, blocked, moved,
                                    travel, pair_out, *scratch, self.state[rows], self._cp[rows],
                                    pt, surf, tsc, self.damage, hits, hits, tick_pairs, count)
            self.contact_pairs[slot].extend(map(tuple, tick_pairs[:count[0]].tolist()))
        caches = solver.broad_phase_args[_SOLVER_CONSTS:]
        pairs = caches[2]                       # resolve may have grown its pair list
        if pairs.shape[0] > self._pairs.shape[1]:
            more = pairs.shape[0] - self._pairs.shape[1]
            self._pairs = np.pad(self._pairs, ((0, 0), (0, more), (0, 0)))
        self._pcap[slot] = pairs.shape[0]
        for src, dst in zip(caches, self._caches(slot)):
            dst[...] = src

    def sense(self, mask: np.ndarray) -> None:
        """Compute `sensors` of the masked slots (as `SensorSuite.frame`; `step` does this)."""
        mask = np.asarray(mask, dtype=bool)
        tables = (self._geo_rows.all, self._geo_rows.off, self._runs.all, self._runs.off,
                  self._prun.all, self._prun.off)
        self._sense(self.state, mask, self.offsets, self.n_cars, self._track, tables,
                    self._half, self._cast, self.race_pos, self._origin,
                    self._active, SENSOR_RANGE_M, self._local, self.sensors)
        if self.focus or self._noisy_slots:
            for e in np.flatnonzero(mask).tolist():
                if self.focus or self._noise_rng[e] is not None:
                    self._focus_and_noise(e)

    def cast_only(self, rows, read) -> None:
        """Cast only the rays `read` (indices 0..18) of batch rows `rows` (cars of compiled
        traffic behaviours, `traffic_kernel.RAYS_READ`) until their slot's next `start`; their
        other rays hold `sensors.RAY_UNCAST` until `complete`. Not for a noisy slot."""
        for r in np.atleast_1d(np.asarray(rows, dtype=np.int64)).tolist():
            if self._noise_rng[int(np.searchsorted(self.offsets, r, side="right")) - 1] is not None:
                raise ValueError(f"row {r}: a noisy slot casts every ray")
            self._cast[r] = uncast_angles(self._angles[r], read)

    def complete(self, mask=None) -> int:
        """Cast the rays `cast_only` left out of `sensors` for the slots in `mask` (default:
        all), from the current state: their rows then equal a full cast's bit for bit.
        Returns the rays cast."""
        slots = range(self.n_slots) if mask is None else np.flatnonzero(mask).tolist()
        count = 0
        for e in slots:
            rows = self.rows(e)
            if self.n_cars[e] == 0 or not np.isnan(self._cast[rows]).any():
                continue
            track = self._slot_kind[e].world.track
            count += fill_rays(self._local[:int(self.n_cars[e])], self.state[rows], track.runs,
                               track.piece_run, track.width / 2, self._angles[rows],
                               SENSOR_RANGE_M, self.sensors[rows])
        return count

    def _focus_and_noise(self, slot: int) -> None:
        """The parts of SensorSuite.frame that stay in Python: focus readings, noise."""
        rows = self.rows(slot)
        flat = self.sensors[rows]
        focus = self._focus_state[slot]
        st = self.state[rows]
        if focus is not None and st[0, L.S_TIME] >= focus.earliest_s:
            local = self._local[:flat.shape[0]]
            due = focus.due(local, st[:, L.S_TIME], np.abs(flat[:, O_TPOS]) <= 1.0)
            track = self._slot_kind[slot].world.track
            focus_kernel(local, st, due, focus.requested_deg, track.geo, float(track.length),
                         track.runs, track.piece_run, track.width / 2, SENSOR_RANGE_M, flat)
        rng = self._noise_rng[slot]
        if rng is not None:
            apply_noise(SensorFrame(flat, self._local[:flat.shape[0]]), rng)

    @property
    def solvers_attached(self) -> int:
        """Slots that currently hold a contact solver."""
        return sum(s is not None for s in self._solver)


class _Stacked:
    """Tables of different row counts (one per track) stacked in one array for the kernels:
    table t is all[off[t]:off[t + 1]]; a table not yet put has no rows. Every table of a stack
    has `ndim` dimensions, the same `dtype` and (2-D) the same width."""

    def __init__(self, ndim: int = 2, dtype=np.float64):
        self._tables: list = []
        self.dtype = np.dtype(dtype)
        self.all = np.zeros((0, 1) if ndim == 2 else 0, dtype=self.dtype)
        self.off = np.zeros(1, dtype=np.int64)

    def rows(self, t: int):
        """Table t, or None if it was never put."""
        return self._tables[t] if t < len(self._tables) else None

    def put(self, t: int, table: np.ndarray) -> None:
        """Set table t."""
        self._tables += [None] * (t + 1 - len(self._tables))
        self._tables[t] = np.ascontiguousarray(table, dtype=self.dtype)
        empty = np.zeros((0,) + self._tables[t].shape[1:], dtype=self.dtype)
        parts = [x if x is not None else empty for x in self._tables]
        self.all = np.concatenate(parts)
        self.off = np.concatenate([[0], np.cumsum([p.shape[0] for p in parts])]).astype(np.int64)
