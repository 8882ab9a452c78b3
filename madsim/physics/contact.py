"""Car-car and car-wall contact: a compiled broad phase, pymunk narrow phase, TORCS response.

`ContactSolver.resolve` runs after every 0.002 s sub-step with the cars' poses and global
velocities, which it changes in place (positions separated, velocities changed by the contact),
and returns a `ContactReport` (per car: wall contact, car contact, damage added; car pairs).

1. Broad phase (compiled, no pymunk). Walls: per car a conservative clearance to the barrier
   lines (lateral extent of the box at the car's track position against the narrowest barrier
   offset within reach, less the bulge of a curved barrier over the box and the polylines'
   chord error), reused while the car cannot have moved enough to use it up. Cars: exact box
   overlap (separating axes) on a neighbour list rebuilt from a hashed grid when some car has
   moved `REBUILD_M`. Contacts act after penetration, so "near" means overlapping (cars) or
   within the bulge allowance + `WALL_REACH_M` (walls). Nothing near: pymunk is not touched.
2. Narrow phase (pymunk). Cars are box bodies of their size, barriers static segments built once
   from the track's barrier polylines (one static body per barrier material). Only cars near
   something are in the pymunk space (they leave after `IDLE_CALLS` consultations without);
   their poses go in through `pymunk.batch`, one `space.step` finds the contacts, and the
   manifolds come back through `pymunk.batch` as arrays. pymunk's bodies never move (no
   velocities, no bias), so no contact state carries over between calls.
3. Response (compiled; TORCS rules, spec torcs-car-format.md 4.12), in a canonical order that
   does not depend on pymunk's internal order:
   - wall, per car and per wall direction, at the deepest point of the car inside the wall:
     position pushed out by the penetration (+ `SLOP_M`); with vn = velocity of that point along
     the wall normal n (pointing away from the wall; < 0 = into it) and p = the point relative
     to the CG: `v -= n vn k_friction`, `r -= (n . p) vn k_friction / 10` (|r| <= 6 rad/s),
     and when vn < 0 damage `k_damage (0.5 (c v.n)^2 + 0.005 |1 - c| V) x skill` (V =
     max(1, |v|), c = v.n / V) and `v -= n vn rebound`. So the into-wall speed is multiplied
     by (1 - k_friction - rebound) per contact step (0.5 for TORCS's barrier: friction 0,
     rebound 0.5; TORCS's "friction" damps the normal speed) and the tangential speed is kept.
   - car-car, at the manifold's mid point along pymunk's normal, when the points approach:
     `j = -(1 + e) v_rel.n / (1/m1 + 1/m2 + (r1 x n)^2/I1 + (r2 x n)^2/I2)` on both velocities
     and yaw rates (capped at 3 rad/s), e = 1 as in TORCS (`car_restitution` lowers it), damage
     `0.1 |j| x skill` per car, x1.5 if the point is within +-60 deg of that car's nose; the
     cars separated by the full penetration (+ `SLOP_M`), split by mass (a car a wall already
     pushed stays).
   Then position-only passes (compiled, exact tests, up to `SETTLE_ITERS`): moved boxes that
   still overlap are separated along their smallest-overlap axis, and every car near a barrier
   or moved is projected until its four corners are inside the exact barrier lines.

Why pymunk detects but does not respond: TORCS's wall rule is not a restitution law (the car
keeps moving into the wall at half speed and the position push stops it; pymunk's elasticity e
gives -e times the speed), pymunk removes penetration gradually through bias velocities (we
need it gone now, at 300 km/h), and its solver would integrate positions that the World
integrates. The car-car impulse is the physical one (r x n lever arms): momentum is conserved
and, with e <= 1, kinetic energy is not created. TORCS's code uses r . n there, which does not
conserve energy; we do not copy that.

Differences from TORCS, on purpose: damage is a float (TORCS truncates each hit to an int); a
wall direction responds once per step (TORCS once per corner, with stale corner velocities);
cars are separated fully, not by at most 5 cm; walls are pymunk segments, so the side of a box
hits a convex wall corner (TORCS tests corners only), with TORCS's exact corner test as the
safety net. Boxes are centred on (x, y) (TORCS's CG offset in the body is ignored). pymunk is
2-D: contacts between cars far apart along the track, and wall contacts whose car point is well
inside the car's own barrier lines, are ignored (bridges). Cars with a non-finite pose are
ignored.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
import pymunk
import pymunk.batch as pmb

from madsim.tracks.build import COL
from madsim.tracks.kernels import GEO_A0, GEO_KIND, GEO_LEN, GEO_R, GEO_S0, locate_from

# --- TORCS response constants (spec torcs-car-format.md 4.12) ---------------------------------
WALL_YAW_SCALE = 10.0       # yaw-rate change divisor of the wall friction term
WALL_YAW_MAX = 6.0          # rad/s, cap after a wall friction term
CAR_YAW_MAX = 3.0           # rad/s, cap after a car-car impulse
CAR_DAMAGE_PER_NS = 0.1     # damage points per N s of impulse
FRONTAL_FACTOR = 1.5        # car-car damage factor for hits within +-60 deg of the nose
FRONTAL_HALF_ANGLE = math.pi / 3.0
SKILL_SEMI_PRO = 0.8        # TORCS damage skill factor (rookie 0, amateur 0.5, semi-pro 0.8, pro 1)

# --- solver tuning ----------------------------------------------------------------------------
SLOP_M = 1e-3               # extra separation beyond the measured penetration
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

# columns of the per-car constant table
C_HL, C_HW, C_RAD, C_MASS, C_IZZ, C_GAIN, C_WIN = range(7)
# entries of the scalar parameter array
(P_LENGTH, P_MOVE_CAP, P_RMAX, P_E_CAR, P_SKILL, P_STRETCH, P_CHORD2) = range(7)

_BODY_FIELDS = pmb.BodyFields.POSITION | pmb.BodyFields.ANGLE
_ARB_FIELDS = (pmb.ArbiterFields.BODY_A_ID | pmb.ArbiterFields.BODY_B_ID | pmb.ArbiterFields.NORMAL
               | pmb.ArbiterFields.CONTACT_COUNT | pmb.ArbiterFields.POINT_A_1
               | pmb.ArbiterFields.POINT_B_1 | pmb.ArbiterFields.DISTANCE_1
               | pmb.ArbiterFields.POINT_A_2 | pmb.ArbiterFields.POINT_B_2
               | pmb.ArbiterFields.DISTANCE_2)
_ARB_INTS, _ARB_FLOATS = 3, 12    # per arbiter: (a id, b id, count), (normal, 2 x (pa, pb, dist))
_F64, _I64 = np.dtype(np.float64), np.dtype(np.int64)


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
                              min(stretch, LEVEL_STRETCH_MAX), chord ** 2])

        # --- broad-phase caches and outputs -------------------------------------------------
        self._wall_cache = np.zeros((n, 4))          # x, y, yaw at the last full check, budget
        self._vref = np.zeros((n, 2))                # positions when the neighbour list was built
        self._pairs = np.zeros((max(64, 8 * n), 2), dtype=np.int64)
        self._meta = np.zeros(3, dtype=np.int64)     # list valid, n pairs, rebuild count
        self._flags = np.zeros(n, dtype=np.int8)
        self._slack = np.zeros(n)
        self._travel = np.zeros(n)

        # --- pymunk ----------------------------------------------------------------------------
        self._space, self._mat_bodies, mat_ids = _wall_space(track)
        self._mat = _material_table(track, mat_ids, wall_friction, rebound)
        self._bodies, self._shapes = [], []
        for i in range(n):
            body = pymunk.Body(float(arrays["mass"][i]), float(arrays["izz"][i]))
            shape = pymunk.Poly(body, [(-hl[i], -hw[i]), (hl[i], -hw[i]), (hl[i], hw[i]), (-hl[i], hw[i])],
                                radius=0.0)
            shape.elasticity = 0.0
            shape.friction = 0.0
            self._bodies.append(body)
            self._shapes.append(shape)
        keys = np.array([b.id for b in self._bodies] + [b.id for b in self._mat_bodies], dtype=np.int64)
        codes = np.concatenate([np.arange(n), -1 - np.arange(len(self._mat_bodies))]).astype(np.int64)
        order = np.argsort(keys, kind="stable")
        self._id_keys, self._id_codes = keys[order], codes[order]
        self._code_of = dict(zip(keys.tolist(), codes.tolist()))
        self._member = np.zeros(n, dtype=bool)
        self._idle = np.zeros(n, dtype=np.int64)
        self._add = np.zeros(n, dtype=np.int64)
        self._drop = np.zeros(n, dtype=np.int64)
        self._set_buf = pmb.Buffer()
        self._arb_buf = pmb.Buffer()
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
        self.reset()

    # --- public -----------------------------------------------------------------------------

    def reset(self) -> None:
        """Forget every cached contact, clearance and neighbour list (new episode)."""
        for i in np.flatnonzero(self._member):
            self._space.remove(self._bodies[i], self._shapes[i])
        self._member[:] = False
        self._idle[:] = 0
        self._wall_cache[:, 3] = -1.0
        self._meta[:2] = 0
        self._refresh_slots()

    def wall_segments(self) -> np.ndarray:
        """(S, 4) the static wall segments pymunk collides with: x0, y0, x1, y1 (m)."""
        segs = [sh for sh in self._space.shapes if isinstance(sh, pymunk.Segment)]
        return np.array([(sh.a.x, sh.a.y, sh.b.x, sh.b.y) for sh in segs]).reshape(-1, 4)

    @property
    def stats(self) -> dict:
        """Counters since construction: resolve() calls, calls that consulted pymunk, pymunk
        steps, neighbour-list rebuilds."""
        return dict(self._counts, list_rebuilds=int(self._meta[2]))

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
        return (self._geo, self._bar, self._cars, self._prm, self._wall_cache, self._vref,
                self._pairs, self._meta, self._flags, self._slack)

    def resolve(self, x, y, yaw, vx, vy, yaw_rate, piece, dt) -> ContactReport:
        """Find and resolve contacts after one sub-step. x, y, yaw, vx, vy (global frame),
        yaw_rate: (N,) float64 arrays, changed in place; piece: (N,) int64 track piece of each
        car (a hint, not changed); dt: the sub-step, s."""
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
        while True:
            near = _broad_phase(x, y, yaw, piece, *self.broad_phase_args)
            if near >= 0:
                break
            if near < -1:
                i = -2 - near
                raise ValueError(f"ContactSolver.resolve: piece[{i}] = {piece[i]} is not a piece "
                                 f"index of track {self.track.name!r} (0..{self._geo.shape[0] - 1})")
            self._pairs = np.zeros((2 * self._pairs.shape[0], 2), dtype=np.int64)
            self._meta[0] = 0
        if near == 0:
            return self._empty
        return self._consult(x, y, yaw, vx, vy, yaw_rate, piece, float(dt))

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
        self._counts["consults"] += 1
        n = self.n_cars
        self._sync_members()
        wall = np.zeros(n, dtype=bool)
        car = np.zeros(n, dtype=bool)
        damage = np.zeros(n)
        _fill_poses(self._slots, x, y, yaw, self._poses)
        pmb.set_space_bodies(self._space, _BODY_FIELDS, self._set_buf)
        self._space.step(dt)
        self._counts["pymunk_steps"] += 1
        buf = self._arb_buf
        buf.clear()
        pmb.get_space_arbiters(self._space, _ARB_FIELDS, buf)
        ints = np.frombuffer(buf.int_buf(), dtype=np.int64)
        floats = np.frombuffer(buf.float_buf(), dtype=np.float64)
        need = ints.size // _ARB_INTS + 4 * self._meta[1] + 1
        if need > self._pair_out.shape[0]:
            self._pair_out = np.zeros((2 * need, 2), dtype=np.int64)
        count = _respond(ints, floats, self._id_keys, self._id_codes, x, y, yaw, vx, vy, w, piece,
                         self._cars, self._mat, self._geo, self._bar, self._prm, wall, car, damage,
                         self._blocked, self._moved, self._travel, self._pair_out)
        count = _settle(x, y, yaw, piece, self._cars, self._geo, self._bar, self._prm, self._pairs,
                        self._meta, self._flags, self._slack, wall, car, self._blocked, self._moved,
                        self._travel, self._pair_out, count)
        pairs = sorted(map(tuple, self._pair_out[:count].tolist()))
        return ContactReport(wall=wall, car=car, damage=damage, pairs=pairs)

    def _sync_members(self) -> None:
        """Add flagged cars to the pymunk space; drop cars idle for IDLE_CALLS consultations."""
        n_add, n_drop = _membership(self._flags, self._member, self._idle, self._add, self._drop)
        for i in self._add[:n_add]:
            self._space.add(self._bodies[i], self._shapes[i])
        for i in self._drop[:n_drop]:
            self._space.remove(self._bodies[i], self._shapes[i])
        if n_add or n_drop:
            self._refresh_slots()

    def _refresh_slots(self) -> None:
        """Read pymunk's body order (set_space_bodies writes bodies in that order)."""
        buf = pmb.Buffer()
        pmb.get_space_bodies(self._space, pmb.BodyFields.BODY_ID, buf)
        ids = np.frombuffer(buf.int_buf(), dtype=np.int64)
        self._slots = np.array([self._code_of[int(i)] for i in ids], dtype=np.int64)
        self._poses = np.zeros(3 * max(1, ids.size))   # static bodies keep pose (0, 0, 0)
        self._set_buf.set_float_buf(self._poses)


# --- set-up helpers (plain Python) ---------------------------------------------------------------


def _barrier_table(track) -> np.ndarray:
    """(P, 5) per piece: barrier offsets from the centre line at its start and end (left start,
    left end, right start, right end; m, road half width + border + side) and the radius of the
    barrier line on the inside of the bend (m, >= MIN_RADIUS_M; inf on straights)."""
    p = track.pieces
    geo = track.geo
    half = track.width / 2.0
    out = np.empty((p.shape[0], 5))
    out[:, 0] = half + p[:, COL["border_w_l"]] + p[:, COL["side_w0_l"]]
    out[:, 1] = half + p[:, COL["border_w_l"]] + p[:, COL["side_w1_l"]]
    out[:, 2] = half + p[:, COL["border_w_r"]] + p[:, COL["side_w0_r"]]
    out[:, 3] = half + p[:, COL["border_w_r"]] + p[:, COL["side_w1_r"]]
    kind = geo[:, GEO_KIND]
    inner = np.where(kind == 1, out[:, :2].max(axis=1), out[:, 2:4].max(axis=1))
    out[:, 4] = np.where(kind == 0, np.inf, np.maximum(geo[:, GEO_R] - inner, MIN_RADIUS_M))
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
    material. Returns (space, material bodies, surface index of each material body)."""
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
    space.add(*[bodies[m] for m in mat_ids], *shapes)
    return space, [bodies[m] for m in mat_ids], mat_ids


def _material_table(track, mat_ids, wall_friction, rebound) -> np.ndarray:
    """(M, 3) friction, rebound, damage factor of each wall material body."""
    out = np.zeros((max(1, len(mat_ids)), 3))
    for k, m in enumerate(mat_ids):
        srf = track.surfaces[m]
        out[k] = (srf.friction if wall_friction is None else wall_friction,
                  srf.rebound if rebound is None else rebound, srf.dammage)
    return out


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
def _barrier_min(geo, bar, i, q, reach):
    """Smallest (left, right) barrier offset and smallest inner barrier radius over s in
    [s(i, q) - reach, s(i, q) + reach]."""
    npieces = geo.shape[0]
    bl, br, rc = np.inf, np.inf, np.inf
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
    return bl, br, rc


@numba.njit(cache=True)
def _wall_margin(geo, bar, cars, prm, i, x, y, yaw, hint):
    """Conservative clearance (m) between car i's box and the nearest barrier line, minus what
    pymunk may already call a contact: the lateral extent of the box at the car's track
    position against the narrowest barrier offset within reach, less the bulge of a curved
    barrier over the box (rad^2 / 2 r), the polylines' chord error (chord^2 / 8 r) and
    WALL_REACH_M. <= 0: consult pymunk."""
    p, q, n = locate_from(geo, hint, x, y)
    psi = yaw - _heading(geo, p, q)
    lat = cars[i, C_HL] * abs(math.sin(psi)) + cars[i, C_HW] * abs(math.cos(psi))
    bl, br, rc = _barrier_min(geo, bar, p, q, cars[i, C_WIN])
    bulge = (cars[i, C_RAD] ** 2 / 2.0 + prm[P_CHORD2] / 8.0) / rc
    return min(bl - (n + lat), br - (lat - n)) - bulge - WALL_REACH_M


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
    """How far a point is beyond the nearer barrier line (m, <= 0 inside), located by walking
    from piece `hint`, and the unit inward normal there."""
    p, q, n = locate_from(geo, hint, px, py)
    u = min(max(q / geo[p, GEO_LEN], 0.0), 1.0)
    a = _heading(geo, p, q)
    if n >= 0.0:
        b = bar[p, 0] + u * (bar[p, 1] - bar[p, 0])
        return n - b, math.sin(a), -math.cos(a)
    b = bar[p, 2] + u * (bar[p, 3] - bar[p, 2])
    return -n - b, -math.sin(a), math.cos(a)


@numba.njit(cache=True)
def _wall_response(i, nx, ny, px, py, mat, x, y, vx, vy, w, prm, damage):
    """TORCS barrier rule (car spec 4.12 steps 2-6) for car i at point (px, py), wall normal
    (nx, ny) pointing away from the wall, material row `mat` = (friction, rebound, dammage)."""
    rx, ry = px - x[i], py - y[i]
    vn = (vx[i] - w[i] * ry) * nx + (vy[i] + w[i] * rx) * ny
    speed = max(1.0, math.sqrt(vx[i] * vx[i] + vy[i] * vy[i]))
    vcn = vx[i] * nx + vy[i] * ny
    cosa = vcn / speed
    kf = mat[0] * vn
    vx[i] -= nx * kf
    vy[i] -= ny * kf
    w[i] -= (nx * rx + ny * ry) * kf / WALL_YAW_SCALE
    w[i] = min(max(w[i], -WALL_YAW_MAX), WALL_YAW_MAX)
    if vn < 0.0:
        damage[i] += mat[2] * (0.5 * (cosa * vcn) ** 2 + 0.005 * abs(1.0 - cosa) * speed) * prm[P_SKILL]
        vx[i] -= nx * vn * mat[1]
        vy[i] -= ny * vn * mat[1]


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
        damage[m] += CAR_DAMAGE_PER_NS * jn * factor * prm[P_SKILL]
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
            excess, sx, sy = _point_excess(geo, bar, piece[i], px, py)
            if excess < -OTHER_LEVEL_M or sgn * nx * sx + sgn * ny * sy <= 0.0:
                continue     # another level's wall, or seen from behind: the projection handles it
            ri[nrec], rk[nrec], ro[nrec] = i, 0, m
            rf[nrec, 0], rf[nrec, 1], rf[nrec, 2], rf[nrec, 3], rf[nrec, 4] = sgn * nx, sgn * ny, px, py, dmax
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
    # walls: per car, one response per wall direction at its deepest point
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
            need = rf[g, 4] - (pushx * rf[g, 0] + pushy * rf[g, 1])
            if need > 0.0:
                pushx += need * rf[g, 0]
                pushy += need * rf[g, 1]
            _wall_response(i, rf[g, 0], rf[g, 1], rf[g, 2], rf[g, 3], mat[ro[g]], x, y, vx, vy, w,
                               prm, damage)
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


@numba.njit(cache=True)
def _add_pair(pair_out, count, i, j):
    for k in range(count):
        if pair_out[k, 0] == i and pair_out[k, 1] == j:
            return count
    if count < pair_out.shape[0]:
        pair_out[count, 0], pair_out[count, 1] = i, j
        count += 1
    return count


@numba.njit(cache=True)
def _push_inside(i, x, y, yaw, piece, cars, geo, bar):
    """Move car i so that its four corners are inside the exact barrier lines (TORCS's corner
    test), along the inward normal at the worst corner. Returns True if it moved."""
    pushed = False
    for _ in range(3):
        worst, wx, wy = 0.0, 0.0, 0.0
        for k in range(4):
            e, nx, ny = _corner_excess(geo, bar, x, y, yaw, piece, cars, i, k)
            if e > worst:
                worst, wx, wy = e, nx, ny
        if worst <= 0.0:
            break
        x[i] += wx * (worst + SLOP_M)
        y[i] += wy * (worst + SLOP_M)
        pushed = True
    return pushed


@numba.njit(cache=True)
def _settle(x, y, yaw, piece, cars, geo, bar, prm, pairs, meta, flags, slack, wall, car, blocked,
            moved, travel, pair_out, count):
    """Position-only relaxation after the pymunk contacts, with exact tests: corners of cars
    near a barrier, or moved further than their clearance allows, inside the barrier lines;
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
