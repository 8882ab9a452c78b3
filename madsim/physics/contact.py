"""Car-car and car-wall contact: a compiled broad phase, pymunk narrow phase, TORCS response.

`ContactSolver.resolve` runs after every 0.002 s sub-step with the cars' poses and global
velocities, which it changes in place (positions separated, velocities changed by the contact),
and returns a `ContactReport` (per car: wall contact, car contact, damage added; car pairs).
The World's tick takes the same steps without the report: its compiled stepper runs the broad
phase, `ContactSolver.narrow` the pymunk step, and `world_tick.finish_contact` the response
and the tick's bookkeeping (one Python call per sub-step where something is near). A
consultation where no car enters or leaves the space calls chipmunk from compiled code
(`pymunk_direct.narrow_direct`), and MadrasEnv's compiled step makes it without returning to
Python at all (`world_tick.contact_direct`).

1. Broad phase (compiled, no pymunk). Walls: per car a conservative clearance to the barrier
   lines and the pit walls (lateral extent of the box at the car's track position against the
   narrowest barrier offset within reach and the lateral gap to any pit wall's strip within
   reach, less the bulge of a curved barrier over the box and the polylines' chord error),
   reused while the car cannot have moved enough to use it up. Cars: exact box
   overlap (separating axes) on a neighbour list rebuilt from a hashed grid when some car has
   moved `REBUILD_M`. Contacts act after penetration, so "near" means overlapping (cars) or
   within the bulge allowance + `WALL_REACH_M` (walls). Nothing near: pymunk is not touched.
   `contact_kernels.tick_clear` bounds the broad phase over a stretch of motion (each car's
   path length and turn): when it proves every call on the way would find nothing and change
   no cache, World and WorldBatch advance the cars that stretch in one kernel call.
2. Narrow phase (pymunk). Cars are box bodies of their size, barriers static segments built once
   per track from the track's barrier polylines (one static body per barrier material), pit
   walls (borders of style `wall` with a side beyond, track spec 6) the closed outlines of
   `Track.pit_wall_quads` on one more static body (faces and end caps as TORCS builds them,
   segment neighbours set so that the joints are not hit): a solver
   holds a barrier space only between its first consultation and `reset()`, which empties it and
   returns it to the track's pool, so a later solver on the same Track object (a reset onto a
   track used before) takes it instead of building one (40-300 ms). A space coming back holds
   no car and no contact, as a fresh one, and results are bit-identical (tested). Only cars near
   something are in the pymunk space (they leave after `IDLE_CALLS` consultations without);
   their poses go in through `pymunk.batch`, one `space.step` finds the contacts, and the
   manifolds come back through `pymunk.batch` as arrays. pymunk's bodies never move (no
   velocities, no bias), so no contact state carries over between calls.
3. Response (compiled; TORCS rules, spec torcs-car-format.md 4.12), in a canonical order that
   does not depend on pymunk's internal order:
   - wall, as TORCS's SimCarCollideXYScene: once per corner of the car's box beyond the
     barrier line, in TORCS's corner order (`contact_kernels._barrier_corners`; docs/physics.md,
     "Once per corner", "Where TORCS looks"), tested where TORCS tests it: the box at the start
     of the sub-step (moved back by the velocities x 0.002 s; a box that only the sub-step's
     move put beyond the line is answered at the next sub-step), the centre pushed in by each
     such corner's own depth (no slop). With n = TORCS's barrier normal, the track's lateral
     direction at the corner (pointing away from the wall; pymunk's own normal is not used: at a joint of
     the barrier polyline it can run along the track and brake a scraping car by 10-35 m/s),
     vn = the corner's velocity along n before the response (< 0 = into it), p = the corner
     relative to the pushed CG: `v -= n vn k_friction`, `r -= (n . p) vn k_friction / 10` (|r| <= 6
     rad/s), and when vn < 0 damage `k_damage (0.5 (c v.n)^2 + 0.005 |1 - c| V) x skill` (V =
     max(1, |v|), c = v.n / V, whole points per corner) and `v -= n vn rebound`. So each corner
     in the wall takes (k_friction + rebound) of the into-wall speed (0.5 for TORCS's barrier:
     friction 0, rebound 0.5; TORCS's "friction" damps the normal speed: a nose-first hit with
     two corners in stops there) and the tangential speed is kept. A barrier contact with no
     corner beyond the line before or after the move (a side against a bulging barrier) gets
     one response at its deepest point, pushed out by that depth (+ `SLOP_M`).
   - pit walls, the same way per direction and deepest point (a contact whose normal runs
     along the track away from the wall's ends is a seam between two of its segments: dropped),
     but TORCS's pit-wall rule: when
     vn < 0, the elastic impulse on an immovable wall j = -(1 + e) vn / (1/m + (p x n)^2 / I),
     e = 1, on v in full and on r by half (|r| <= 3 rad/s), damage 0.1 x 2e-5 j^2 (x1.5 within
     +-60 deg of the nose) x skill.
   - car-car, at the manifold's mid point along pymunk's normal, when the points approach:
     `j = -(1 + e) v_rel.n / (1/m1 + 1/m2 + (r1 x n)^2/I1 + (r2 x n)^2/I2)` on both velocities
     and yaw rates (capped at 3 rad/s), e = 1 as in TORCS (`car_restitution` lowers it), damage
     `0.1 |j| x skill` per car, x1.5 if the point is within +-60 deg of that car's nose; the
     cars separated by the full penetration (+ `SLOP_M`), split by mass (a car a wall already
     pushed stays).
   Then position-only passes (compiled, exact tests, up to `SETTLE_ITERS`): moved boxes that
   still overlap are separated along their smallest-overlap axis, and every car near a barrier
   or moved with a corner more than `BACKSTOP_M` beyond an exact barrier line is projected
   until its four corners are inside (TORCS lets a box ride in the wall by a step's motion).

Why pymunk detects but does not respond: TORCS's wall rule is not a restitution law (the car
keeps moving into the wall at half speed and the position push stops it; pymunk's elasticity e
gives -e times the speed), pymunk removes penetration gradually through bias velocities (we
need it gone now, at 300 km/h), and its solver would integrate positions that the World
integrates. The car-car impulse is the physical one (r x n lever arms): momentum is conserved
and, with e <= 1, kinetic energy is not created. TORCS's code uses r . n there, which does not
conserve energy; we do not copy that.

Damage comes in whole points per hit: TORCS adds the int of each barrier, pit-wall and car-car
hit (`contact_kernels._whole_points`), so a car resting against a wall gains none.

Differences from TORCS, on purpose: a wall direction responds once per step (TORCS once per
corner, with stale corner velocities); cars are separated fully, not by at most 5 cm; walls are
pymunk segments, so the side of a box hits a convex wall corner (TORCS tests corners only),
with TORCS's exact corner test as the safety net; the barrier normal is the lateral direction
at the contact point (TORCS: per track segment, normal to the chord of its outermost side, so
on a curve it is off by up to half a segment's angle and turns in steps). Boxes are centred on
(x, y) (TORCS's CG offset in the body is ignored). pymunk is 2-D: contacts between cars far
apart along the track, and barrier contacts whose car point is well inside the car's own
barrier lines, are ignored (bridges); pit walls are not told apart by level, and their height
is not used. Cars with a non-finite pose are ignored.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np
import pymunk
import pymunk.batch as pmb
from pymunk._chipmunk_cffi import ffi as _ffi, lib as _lib

from madsim.physics import pymunk_direct as _pd
from madsim.physics.contact_kernels import (
    CAR_DAMAGE_PER_NS,
    CAR_YAW_MAX,
    FRONTAL_FACTOR,
    SLOP_M,
    WALL_YAW_MAX,
    WALL_YAW_SCALE,
    C_GAIN,
    C_HL,
    C_HW,
    C_IZZ,
    C_MASS,
    C_RAD,
    C_WIN,
    B_PIT,
    LEVEL_STRETCH_MAX,
    MIN_RADIUS_M,
    MAT_PIT_WALL,
    SKILL_SEMI_PRO,
    WINDOW_SLACK_M,
    _broad_phase,
    _fill_poses,
    _membership_poses,
    _respond_settle,
    advance_until_near,
    advance_until_near_parallel,
)
from madsim.tracks.build import COL
from madsim.tracks.kernels import GEO_KIND, GEO_R

__all__ = ["ContactSolver", "ContactReport", "advance_until_near", "advance_until_near_parallel", "SLOP_M", "SKILL_SEMI_PRO", "WALL_YAW_SCALE",
           "WALL_YAW_MAX", "CAR_YAW_MAX", "CAR_DAMAGE_PER_NS", "FRONTAL_FACTOR"]

_BODY_FIELDS = pmb.BodyFields.POSITION | pmb.BodyFields.ANGLE
_ARB_FIELDS = (pmb.ArbiterFields.BODY_A_ID | pmb.ArbiterFields.BODY_B_ID | pmb.ArbiterFields.NORMAL
               | pmb.ArbiterFields.CONTACT_COUNT | pmb.ArbiterFields.POINT_A_1
               | pmb.ArbiterFields.POINT_B_1 | pmb.ArbiterFields.DISTANCE_1
               | pmb.ArbiterFields.POINT_A_2 | pmb.ArbiterFields.POINT_B_2
               | pmb.ArbiterFields.DISTANCE_2)
_ARB_INTS, _ARB_FLOATS = _pd.ARB_INTS, _pd.ARB_FLOATS   # per arbiter, see pymunk_direct
# The narrow phase calls pymunk.batch's own C iterators with request structs made once per
# solver (`_BatchIO`): what set_space_bodies / get_space_arbiters do, without a new struct, a
# function look-up and two buffer objects per call.
_SET_BODIES = _ffi.addressof(_lib, "pmSpaceBodySetIteratorFuncBatched")
_GET_ARBITERS = _ffi.addressof(_lib, "pmSpaceArbiterIteratorFuncBatched")
_F64, _I64 = np.dtype(np.float64), np.dtype(np.int64)
_pd.check_layout(_ffi)
_FN_ADDRESSES = {_pd.P_EACH_BODY: _pd.address(_ffi, _ffi.addressof(_lib, "cpSpaceEachBody")),
                 _pd.P_STEP: _pd.address(_ffi, _ffi.addressof(_lib, "cpSpaceStep")),
                 _pd.P_EACH_ARB: _pd.address(_ffi, _ffi.addressof(_lib, "cpSpaceEachCachedArbiter")),
                 _pd.P_SET_FN: _pd.address(_ffi, _SET_BODIES),
                 _pd.P_GET_FN: _pd.address(_ffi, _GET_ARBITERS)}

JOIN_M = 0.01    # pit-wall quads whose edges meet this closely are one wall (float32 piece starts)

# Track -> its free barrier spaces (a cache: which space a solver takes never changes a result)
_POOLS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


@dataclass(frozen=True)
class ContactReport:
    """What one `resolve` call did: per car (N,) flags and the damage it added; car pairs
    (i < j, sorted) that touched."""

    wall: np.ndarray
    car: np.ndarray
    damage: np.ndarray
    pairs: list


class ContactSolver:
    """Contact between N box-shaped cars and the track's barriers (see the module docstring).

    half_length, half_width: (N,) box half sizes, m; mass: (N,) kg; izz: (N,) yaw inertia,
    kg m^2. wall_friction, rebound: override the barrier surfaces' `friction` (TORCS normal
    damping factor) and `rebound` for every wall; None takes each barrier's own material.
    car_restitution: car-car restitution (1 = TORCS, elastic). damage_factor: TORCS skill
    factor applied to all contact damage (0.8 = semi-pro).
    """

    def __init__(self, track, half_length, half_width, mass, izz, *, wall_friction=None,
                 rebound=None, car_restitution: float = 1.0, damage_factor: float = SKILL_SEMI_PRO):
        arrays = {}
        for name, value in (("half_length", half_length), ("half_width", half_width),
                            ("mass", mass), ("izz", izz)):
            a = np.array(value, dtype=np.float64).reshape(-1) if np.ndim(value) else None
            if a is None or a.size == 0:
                raise ValueError(f"ContactSolver: {name} must be a non-empty (N,) array")
            if not np.all(np.isfinite(a)) or np.any(a <= 0):
                raise ValueError(f"ContactSolver: {name} must be finite and > 0, got {a}")
            arrays[name] = a
        n = arrays["half_length"].size
        for name, a in arrays.items():
            if a.size != n:
                raise ValueError(f"ContactSolver: {name} has {a.size} entries, half_length has {n}")
        for name, value, hi in (("wall_friction", wall_friction, 10.0), ("rebound", rebound, 10.0),
                                ("car_restitution", car_restitution, 1.0),
                                ("damage_factor", damage_factor, 10.0)):
            if value is not None and not (math.isfinite(value) and 0.0 <= value <= hi):
                raise ValueError(f"ContactSolver: {name} must be in [0, {hi}], got {value!r}")
        self.track = track
        self.n_cars = n
        self._shape = (n,)
        hl, hw = arrays["half_length"], arrays["half_width"]
        rad = np.hypot(hl, hw)

        # --- track constants for the compiled kernels --------------------------------------
        self._geo = np.ascontiguousarray(track.geo, dtype=np.float64)
        self._bar = _barrier_table(track)
        kappa, stretch = _track_bounds(track, self._bar)
        chord = max(np.hypot(*np.diff(track.barrier_polyline(side), axis=0).T).max()
                    for side in ("left", "right"))
        cache_ok = math.isfinite(stretch)
        cars = np.zeros((n, 7))
        cars[:, C_HL], cars[:, C_HW], cars[:, C_RAD] = hl, hw, rad
        cars[:, C_MASS], cars[:, C_IZZ] = arrays["mass"], arrays["izz"]
        cars[:, C_GAIN] = 1.0 + rad * kappa * (stretch if cache_ok else 1.0)
        cars[:, C_WIN] = rad * (stretch if cache_ok else LEVEL_STRETCH_MAX) + WINDOW_SLACK_M
        self._cars = cars
        self._prm = np.array([track.length, WINDOW_SLACK_M / stretch if cache_ok else 0.0,
                              rad.max(), car_restitution, damage_factor,
                              min(stretch, LEVEL_STRETCH_MAX), chord ** 2,
                              float(np.isfinite(self._bar[:, B_PIT]).any()
                                    or np.isfinite(self._bar[:, B_PIT + 2]).any())])

        # --- broad-phase caches and outputs -------------------------------------------------
        self._wall_cache = np.zeros((n, 4))          # x, y, yaw at the last full check, budget
        self._vref = np.zeros((n, 2))                # positions when the neighbour list was built
        self._pairs = np.zeros((max(64, 8 * n), 2), dtype=np.int64)
        self._meta = np.zeros(3, dtype=np.int64)     # list valid, n pairs, rebuild count
        self._flags = np.zeros(n, dtype=np.int8)
        self._slack = np.zeros(n)
        self._bp_args = None
        self._travel = np.zeros(n)

        # --- pymunk ----------------------------------------------------------------------------
        self._pool = _POOLS.get(track)
        if self._pool is None:
            self._pool = _POOLS[track] = _SpacePool(track)
        self._pool.keep_one_free()         # built now, not at the first contact of an episode
        self._mat = _material_table(track, self._pool.mat_ids, wall_friction, rebound)
        self._space = None                 # held between the first consultation and reset()
        self._mat_bodies: list = []
        self._bodies, self._shapes = [], []
        for i in range(n):
            body = pymunk.Body(float(arrays["mass"][i]), float(arrays["izz"][i]))
            shape = pymunk.Poly(body, [(-hl[i], -hw[i]), (hl[i], -hw[i]), (hl[i], hw[i]), (-hl[i], hw[i])],
                                radius=0.0)
            shape.elasticity = 0.0
            shape.friction = 0.0
            self._bodies.append(body)
            self._shapes.append(shape)
        self._id_keys = self._id_codes = np.zeros(0, dtype=np.int64)
        self.arrays_version = 0            # bumped when an array of respond_arrays() is replaced
        self.narrow_version = 0            # bumped when slots or poses (narrow_table_arrays) change
        self._code_of: dict = {}
        self._member = np.zeros(n, dtype=bool)
        self._idle = np.zeros(n, dtype=np.int64)
        self._add = np.zeros(n, dtype=np.int64)
        self._drop = np.zeros(n, dtype=np.int64)
        self._set_buf = pmb.Buffer()
        self._arb_buf = pmb.Buffer()
        self._set_req = _batch_request(_BODY_FIELDS, self._set_buf)
        self._arb_req = _batch_request(_ARB_FIELDS, self._arb_buf)
        self._arb_views = _arbiter_views(self._arb_req)
        self._ptrs = _pd.empty_ptrs()      # addresses for `pymunk_direct.narrow_direct`
        self.direct = np.zeros(3, dtype=np.int64)    # pymunk_direct.D_*
        for k, a in _FN_ADDRESSES.items():
            self._ptrs[k] = a
        self._ptrs[_pd.P_SET_REQ] = _pd.address(_ffi, self._set_req)
        self._ptrs[_pd.P_ARB_REQ] = _pd.address(_ffi, self._arb_req)
        self._ptrs[_pd.P_SET_FLOATS] = _pd.address(_ffi, self._set_req.floatArray)
        self._ptrs[_pd.P_ARB_INTS] = _pd.address(_ffi, self._arb_req.intArray)
        self._ptrs[_pd.P_ARB_FLOATS] = _pd.address(_ffi, self._arb_req.floatArray)
        self._cp_space = None              # the held space's chipmunk pointer
        self._space_touched = False        # bodies added / removed since its last step
        self._slots = np.zeros(0, dtype=np.int64)    # car index per dynamic body, in space order
        self._poses = np.zeros(0)
        self._pair_out = np.zeros((max(16, 4 * n), 2), dtype=np.int64)
        self._blocked = np.zeros(n, dtype=bool)
        self._moved = np.zeros(n, dtype=bool)
        empty_b, empty_f = np.zeros(n, dtype=bool), np.zeros(n)
        for a in (empty_b, empty_f):
            a.setflags(write=False)
        self._empty = ContactReport(wall=empty_b, car=empty_b, damage=empty_f, pairs=[])
        self._counts = {"calls": 0, "consults": 0, "pymunk_steps": 0}
        self._lease = [None]               # the held (space, material bodies), for the finaliser
        self.reset()
        # a solver dropped while holding a space gives it back (emptied) as reset() does
        weakref.finalize(self, _give_back, self._pool, self._lease, self._bodies, self._shapes,
                         self._member).atexit = False

    # --- public -----------------------------------------------------------------------------

    def reset(self) -> None:
        """Forget every cached contact, clearance and neighbour list (new episode); the barrier
        space goes back to the track's pool, empty."""
        if self._space is not None:
            _give_back(self._pool, self._lease, self._bodies, self._shapes, self._member)
            self._space, self._mat_bodies = None, []
        self._member[:] = False
        self._idle[:] = 0
        self.direct[_pd.D_READY] = self.direct[_pd.D_NARROWED] = 0
        self._wall_cache[:, 3] = -1.0
        self._meta[:2] = 0
        self._slots = np.zeros(0, dtype=np.int64)

    def wall_segments(self) -> np.ndarray:
        """(S, 4) the static wall segments pymunk collides with: x0, y0, x1, y1 (m)."""
        held = (self._space, self._mat_bodies) if self._space is not None else self._pool.take()
        segs = [sh for sh in held[0].shapes if isinstance(sh, pymunk.Segment)]
        if held[0] is not self._space:
            self._pool.put(*held)
        return np.array([(sh.a.x, sh.a.y, sh.b.x, sh.b.y) for sh in segs]).reshape(-1, 4)

    @property
    def stats(self) -> dict:
        """Counters since construction: resolve() calls, calls that consulted pymunk, pymunk
        steps, neighbour-list rebuilds."""
        compiled = int(self.direct[_pd.D_CALLS])    # consultations from compiled code
        return dict({k: v + compiled for k, v in self._counts.items()},
                    list_rebuilds=int(self._meta[2]))

    @property
    def broad_phase_kernel(self):
        """The compiled broad phase, callable from another numba function as
        `kernel(x, y, yaw, piece, *solver.broad_phase_args)`; returns the number of cars near
        something (0: resolve() would not change anything with this state), or a negative code
        that resolve() handles (-1: its pair list overflowed, resolve() grows it; -2 - i: car
        i's piece index is out of range, resolve() raises ValueError). Running it before
        resolve() on the same state is harmless (resolve() runs it again, same result)."""
        return _broad_phase

    @property
    def broad_phase_args(self) -> tuple:
        """The arrays `broad_phase_kernel` takes after (x, y, yaw, piece); fetch them again
        after a resolve() call (it may replace the pair-list array)."""
        args = self._bp_args          # (built once per pair-list array: read every tick)
        if args is None or args[6] is not self._pairs:
            args = self._bp_args = (self._geo, self._bar, self._cars, self._prm, self._wall_cache,
                                    self._vref, self._pairs, self._meta, self._flags, self._slack)
        return args

    def resolve(self, x, y, yaw, vx, vy, yaw_rate, piece, dt) -> ContactReport:
        """Find and resolve contacts after one sub-step. x, y, yaw, vx, vy (global frame),
        yaw_rate: (N,) float64 arrays, changed in place; piece: (N,) int64 track piece of each
        car (a hint, not changed); dt: the sub-step, s (the barrier rule takes the box at the
        start of the sub-step as the pose moved back by the velocities x `SUBSTEP_S`, 0.002 s,
        the sub-step World and WorldBatch use, whatever dt is)."""
        shape = self._shape
        try:   # one chained test: this runs 500 times per simulated second
            ok = (x.shape == y.shape == yaw.shape == vx.shape == vy.shape == yaw_rate.shape
                  == piece.shape == shape and x.dtype == y.dtype == yaw.dtype == vx.dtype == vy.dtype
                  == yaw_rate.dtype == _F64 and piece.dtype == _I64 and dt > 0.0)
        except (AttributeError, TypeError):
            ok = False
        if not ok:
            self._explain_bad_arrays(x, y, yaw, vx, vy, yaw_rate, piece, dt)
        self._counts["calls"] += 1
        if self.broad_phase(x, y, yaw, piece) == 0:
            return self._empty
        return self._consult(x, y, yaw, vx, vy, yaw_rate, piece, float(dt))

    def broad_phase(self, x, y, yaw, piece) -> int:
        """The broad phase on this state (arrays as `resolve` checks them), its pair list grown
        until it fits: the number of cars near something (0: nothing to resolve). Raises
        ValueError for a piece index out of range."""
        while True:
            near = _broad_phase(x, y, yaw, piece, *self.broad_phase_args)
            if near >= 0:
                return near
            if near < -1:
                i = -2 - near
                raise ValueError(f"ContactSolver.resolve: piece[{i}] = {piece[i]} is not a piece "
                                 f"index of track {self.track.name!r} (0..{self._geo.shape[0] - 1})")
            self._pairs = np.zeros((2 * self._pairs.shape[0], 2), dtype=np.int64)
            self._meta[0] = 0

    def _explain_bad_arrays(self, *args) -> None:
        n = self.n_cars
        names = ("x", "y", "yaw", "vx", "vy", "yaw_rate", "piece")
        for name, a in zip(names, args):
            want = _I64 if name == "piece" else _F64
            if not (isinstance(a, np.ndarray) and a.dtype == want and a.shape == (n,)):
                raise ValueError(f"ContactSolver.resolve: {name} must be a numpy {want} array of shape "
                                 f"({n},), got {type(a).__name__} {getattr(a, 'dtype', '')} "
                                 f"{getattr(a, 'shape', '')}")
        raise ValueError(f"ContactSolver.resolve: dt must be a number > 0 (s), got {args[-1]!r}")

    # --- narrow phase -------------------------------------------------------------------------

    def _consult(self, x, y, yaw, vx, vy, w, piece, dt) -> ContactReport:
        ints, floats = self._narrow(x, y, yaw, dt)
        n = self.n_cars
        wall = np.zeros(n, dtype=bool)
        car = np.zeros(n, dtype=bool)
        damage = np.zeros(n)
        count = _respond_settle(ints, floats, self._id_keys, self._id_codes, x, y, yaw, vx, vy, w,
                                piece, self._cars, self._mat, self._geo, self._bar, self._prm,
                                self._pairs, self._meta, self._flags, self._slack, wall, car,
                                damage, self._blocked, self._moved, self._travel, self._pair_out)
        pairs = sorted(map(tuple, self._pair_out[:count].tolist()))
        return ContactReport(wall=wall, car=car, damage=damage, pairs=pairs)

    def narrow(self, x, y, yaw, dt) -> tuple[np.ndarray, np.ndarray]:
        """The pymunk narrow phase for a caller that responds itself (World.finish_tick through
        `world_tick.finish_contact`), on a state where `broad_phase` (or the compiled broad phase
        on the same arrays) has just found cars near: the arbiters' integers (K, 3) and floats
        (K, 12) flattened, what `_respond_settle` reads. Counted as a resolve() call. Arrays
        the response writes may be new ones afterwards: see `respond_arrays`."""
        self._counts["calls"] += 1
        return self._narrow(x, y, yaw, float(dt))

    def narrow_table_arrays(self, contact_table: np.ndarray) -> tuple:
        """The arrays of `pymunk_direct.NARROW_TABLE` after the caller's contact table (a
        compiled tick's own consultations, `world_tick.contact_direct`). `slots` and `poses`
        are replaced when a car enters or leaves the space: see `narrow_version`."""
        return (contact_table, self._ptrs, self._member, self._idle, self._add, self._drop,
                self._slots, self._poses, self.direct)

    def arbiters_after_direct(self) -> tuple[np.ndarray, np.ndarray]:
        """`narrow`'s answer for the consultation a compiled tick made and left to Python
        (direct[D_NARROWED]; cleared here)."""
        self.direct[_pd.D_NARROWED] = 0
        return self._arbiters()

    def respond_arrays(self) -> tuple:
        """The solver's arrays `_respond_settle` reads and writes besides the poses and the
        broad phase's (id keys, id codes, material table, blocked, moved, travel, pair out);
        `arrays_version` changes whenever one of them is replaced."""
        return (self._id_keys, self._id_codes, self._mat, self._blocked, self._moved,
                self._travel, self._pair_out)

    def _narrow(self, x, y, yaw, dt: float) -> tuple[np.ndarray, np.ndarray]:
        self._counts["consults"] += 1
        if self._space is None:
            self._take_space()
        elif not self._space_touched:  # the usual consultation: pymunk called from compiled code
            if _pd.narrow_direct(self._ptrs, self._flags, self._member, self._idle, self._add,
                                 self._drop, self._slots, x, y, yaw, self._poses, dt) >= 0:
                self._counts["pymunk_steps"] += 1
                return self._arbiters()
        n_add, n_drop = _membership_poses(self._flags, self._member, self._idle, self._add,
                                          self._drop, self._slots, x, y, yaw, self._poses)
        if n_add or n_drop:
            self._sync_members(n_add, n_drop)
            _fill_poses(self._slots, x, y, yaw, self._poses)
        cp, req = self._cp_space, self._set_req
        req.floatArray.num = 0                        # the poses are read from the start
        _lib.cpSpaceEachBody(cp, _SET_BODIES, req)
        if self._space_touched:        # pymunk's own step checks new bodies and drops removed ones
            self._space.step(dt)
            self._space_touched = False
        else:
            _lib.cpSpaceStep(cp, dt)
        self.direct[_pd.D_READY] = 1   # the body set stands until a car enters or leaves
        self._counts["pymunk_steps"] += 1
        req = self._arb_req
        req.intArray.num = req.floatArray.num = 0
        _lib.cpSpaceEachCachedArbiter(cp, _GET_ARBITERS, req)
        return self._arbiters()

    def _arbiters(self) -> tuple[np.ndarray, np.ndarray]:
        """The arbiters pymunk.batch wrote into the get request's arrays (views of them), with
        `_pair_out` grown to hold a response's pairs."""
        req = self._arb_req
        got_i, got_f = req.intArray, req.floatArray
        views = self._arb_views
        if got_i.max != views[0] or got_f.max != views[1]:        # pymunk grew its arrays
            views = self._arb_views = _arbiter_views(req)
        ints = views[2][:got_i.num]
        floats = views[3][:got_f.num]
        need = ints.size // _ARB_INTS + 4 * self._meta[1] + 1
        if need > self._pair_out.shape[0]:
            self._pair_out = np.zeros((2 * need, 2), dtype=np.int64)
            self.arrays_version += 1
        return ints, floats

    def _take_space(self) -> None:
        """Hold a barrier space from the track's pool (built if none is free) until reset()."""
        self._space, self._mat_bodies = self._lease[0] = self._pool.take()
        self._cp_space = self._space._space
        self._ptrs[_pd.P_SPACE] = _pd.address(_ffi, self._cp_space)
        self._space_touched = True
        self.direct[_pd.D_READY] = 0
        n = self.n_cars
        keys = np.array([b.id for b in self._bodies] + [b.id for b in self._mat_bodies], dtype=np.int64)
        codes = np.concatenate([np.arange(n), -1 - np.arange(len(self._mat_bodies))]).astype(np.int64)
        order = np.argsort(keys, kind="stable")
        self._id_keys, self._id_codes = keys[order], codes[order]
        self.arrays_version += 1
        self._code_of = dict(zip(keys.tolist(), codes.tolist()))
        self._refresh_slots()

    def _sync_members(self, n_add: int, n_drop: int) -> None:
        """Put the cars `_membership` chose (self._add[:n_add]: flagged, self._drop[:n_drop]:
        idle for IDLE_CALLS consultations) into and out of the pymunk space."""
        for i in self._add[:n_add]:
            self._space.add(self._bodies[i], self._shapes[i])
        for i in self._drop[:n_drop]:
            self._space.remove(self._bodies[i], self._shapes[i])
        self._space_touched = True
        self.direct[_pd.D_READY] = 0
        self._refresh_slots()

    def _refresh_slots(self) -> None:
        """Read pymunk's body order (set_space_bodies writes bodies in that order)."""
        buf = pmb.Buffer()
        pmb.get_space_bodies(self._space, pmb.BodyFields.BODY_ID, buf)
        ids = np.frombuffer(buf.int_buf(), dtype=np.int64)
        self._slots = np.array([self._code_of[int(i)] for i in ids], dtype=np.int64)
        self._poses = np.zeros(3 * max(1, ids.size))   # static bodies keep pose (0, 0, 0)
        self._set_buf.set_float_buf(self._poses)
        self.narrow_version += 1


# --- set-up helpers (plain Python) ---------------------------------------------------------------


def _batch_request(fields, buf: pmb.Buffer):
    """pymunk.batch's request struct for `fields` over the arrays of `buf` (the struct points
    at the buffer's array headers, which stay put when pymunk grows or replaces their data)."""
    req = _ffi.new("pmBatchedData *")
    req.fields = fields.value
    req.floatArray = buf._float_arr
    req.intArray = buf._int_arr
    return req


def _arbiter_views(req) -> tuple:
    """(int capacity, float capacity, int64 view, float64 view) of a request's arrays at their
    current capacity: valid until pymunk grows them (the capacities then change)."""
    views = []
    for arr, dtype in ((req.intArray, np.int64), (req.floatArray, np.float64)):
        n = arr.max
        views.append(np.frombuffer(_ffi.buffer(arr.arr, 8 * n), dtype=dtype) if n
                     else np.zeros(0, dtype=dtype))
    return (req.intArray.max, req.floatArray.max, *views)


def _barrier_table(track) -> np.ndarray:
    """(P, 9) per piece: barrier offsets from the centre line at its start and end (left start,
    left end, right start, right end; m, road half width + border + side), the radius of the
    barrier line on the inside of the bend (m, >= MIN_RADIUS_M; inf on straights), then from
    column B_PIT the pit wall's inner and outer offsets on the left and on the right (m; inf and
    -inf where that side has none)."""
    p = track.pieces
    geo = track.geo
    half = track.width / 2.0
    out = np.empty((p.shape[0], 9))
    out[:, 0] = half + p[:, COL["border_w_l"]] + p[:, COL["side_w0_l"]]
    out[:, 1] = half + p[:, COL["border_w_l"]] + p[:, COL["side_w1_l"]]
    out[:, 2] = half + p[:, COL["border_w_r"]] + p[:, COL["side_w0_r"]]
    out[:, 3] = half + p[:, COL["border_w_r"]] + p[:, COL["side_w1_r"]]
    kind = geo[:, GEO_KIND]
    inner = np.where(kind == 1, out[:, :2].max(axis=1), out[:, 2:4].max(axis=1))
    out[:, 4] = np.where(kind == 0, np.inf, np.maximum(geo[:, GEO_R] - inner, MIN_RADIUS_M))
    walls = track.pit_wall_pieces()
    for k, sfx in enumerate(("l", "r")):
        out[:, B_PIT + 2 * k] = np.where(walls[:, k], half, np.inf)
        out[:, B_PIT + 2 * k + 1] = np.where(walls[:, k], half + p[:, COL[f"border_w_{sfx}"]], -np.inf)
    return out


def _track_bounds(track, bar: np.ndarray) -> tuple[float, float]:
    """Track-wide bounds for reusing a wall clearance: max centre-line curvature (1/m) and
    `stretch`, the max of ds / (distance moved) for points inside the barriers (inf if a
    barrier line reaches within MIN_RADIUS_M of a bend's centre)."""
    geo = track.geo
    curved = geo[:, GEO_KIND] != 0
    if not curved.any():
        return 0.0, 1.0
    radius = geo[curved, GEO_R]
    inner = bar[curved, 4]
    kappa = float(np.max(1.0 / radius))
    if np.min(inner) <= MIN_RADIUS_M:
        return kappa, math.inf
    return kappa, float(np.max(radius / inner))


def _wall_space(track):
    """pymunk space with the barrier polylines as static segments, one static body per barrier
    material, and the pit walls (`Track.pit_wall_quads`) as the static segments of their
    outlines, neighbours set, on a body of their own (material MAT_PIT_WALL, last). Returns (space, material bodies, surface index of
    each material body or MAT_PIT_WALL)."""
    space = pymunk.Space()
    space.collision_bias = 1.0          # no positional bias: pymunk's bodies never move
    space.collision_persistence = 1     # arbiters left after a step are the current contacts
    space.iterations = 1                # its impulses are not used
    bodies: dict[int, pymunk.Body] = {}
    shapes = []
    for side, col in (("left", "barrier_surf_l"), ("right", "barrier_surf_r")):
        # inside a straight piece the barrier line is straight: keep its first and last samples
        piece = track.piece
        ends_of_piece = np.r_[True, piece[1:] != piece[:-1]] | np.r_[piece[:-1] != piece[1:], True]
        sel = ends_of_piece | (track.geo[piece, GEO_KIND] != 0)
        pts = track.barrier_polyline(side)[sel]
        mats = track.pieces[piece[sel], COL[col]].astype(np.int64)
        ends = np.roll(pts, -1, axis=0)
        seg_len = np.hypot(*(ends - pts).T)
        keep = seg_len > 1e-9
        # the closing segment only if the track closes (TORCS tracks do)
        keep[-1] &= track.closure_gap < 1.0
        for m in np.unique(mats[keep]).tolist():
            if m not in bodies:
                bodies[m] = pymunk.Body(body_type=pymunk.Body.STATIC)
            body = bodies[m]
            sel = keep & (mats == m)
            shapes.extend(pymunk.Segment(body, a, b, 0.0)        # elasticity, friction: 0 (unused)
                          for a, b in zip(map(tuple, pts[sel].tolist()), map(tuple, ends[sel].tolist())))
    mat_ids = sorted(bodies)
    chains = _pit_wall_chains(track.pit_wall_quads()[0])
    if chains:                          # the pit walls: one more static body, the last
        mat_ids.append(MAT_PIT_WALL)
        body = bodies[MAT_PIT_WALL] = pymunk.Body(body_type=pymunk.Body.STATIC)
        for pts in chains:              # closed outline; neighbours set: no ghost hits at joints
            segs = [pymunk.Segment(body, a, b, 0.0) for a, b in zip(pts, pts[1:] + pts[:1])]
            for k, seg in enumerate(segs):
                seg.set_neighbors(segs[k - 1].a, segs[(k + 1) % len(segs)].b)
            shapes.extend(segs)
    space.add(*[bodies[m] for m in mat_ids], *shapes)
    return space, [bodies[m] for m in mat_ids], mat_ids


def _pit_wall_chains(quads: np.ndarray) -> list[list[tuple]]:
    """The outlines of the pit walls: consecutive quads (`Track.pit_wall_quads`) that share an
    edge (to JOIN_M; a wall across the start line included) make one wall, outlined as TORCS
    builds it (inner face, end cap, outer face back, start cap). Returns one closed point list
    per wall."""
    w = quads.shape[0]
    if w == 0:
        return []
    joined = np.abs(quads[:, :2] - np.roll(quads, 1, axis=0)[:, 3:1:-1]).max(axis=(1, 2)) < JOIN_M
    first = int(np.argmin(joined)) if not joined.all() else 0      # a wall starts here
    order = (first + np.arange(w)) % w
    starts = [k for k in range(w) if k == 0 or not joined[order[k]]]
    chains = []
    for a, b in zip(starts, starts[1:] + [w]):
        run = quads[order[a:b]]
        inner = np.vstack([run[:, 0], run[-1:, 3]])
        outer = np.vstack([run[:, 1], run[-1:, 2]])
        chains.append(list(map(tuple, np.vstack([inner, outer[::-1]]).tolist())))
    return chains


class _SpacePool:
    """The free barrier spaces of one track (`_wall_space` results), all built the same way."""

    def __init__(self, track):
        self._track = weakref.ref(track)
        self.free: list = []
        space, bodies, self.mat_ids = _wall_space(track)
        self.free.append((space, bodies))

    def keep_one_free(self) -> None:
        if not self.free:
            self.free.append(_wall_space(self._track())[:2])

    def take(self) -> tuple:
        """(space, material bodies): a free one, or a new one."""
        try:
            return self.free.pop()
        except IndexError:
            return _wall_space(self._track())[:2]

    def put(self, space, bodies) -> None:
        self.free.append((space, bodies))


def _give_back(pool: _SpacePool, lease: list, bodies, shapes, member) -> None:
    """Remove a solver's cars from its held space and return the space to the pool."""
    held, lease[0] = lease[0], None
    if held is None:
        return
    space = held[0]
    for i in np.flatnonzero(member):
        space.remove(bodies[i], shapes[i])
    member[:] = False
    pool.put(*held)


def _material_table(track, mat_ids, wall_friction, rebound) -> np.ndarray:
    """(M, 4) friction, rebound, damage factor and kind (0 barrier, 1 pit wall) of each wall
    material body. A pit wall's row is (0, 1, 1, 1): TORCS's pit-wall rule ignores the surface
    (an elastic impulse, `contact_kernels._pit_wall_response`)."""
    out = np.zeros((max(1, len(mat_ids)), 4))
    for k, m in enumerate(mat_ids):
        if m == MAT_PIT_WALL:
            out[k] = (0.0, 1.0, 1.0, 1.0)
            continue
        srf = track.surfaces[m]
        out[k] = (srf.friction if wall_friction is None else wall_friction,
                  srf.rebound if rebound is None else rebound, srf.dammage, 0.0)
    return out


