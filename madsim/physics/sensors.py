"""The SCR sensor set for every car, vectorised (spec/scr-protocol.md section 5).

`SensorFrame` holds every field of the SCR state message as arrays with the car axis first, in
SCR units (km/h, rad for `angle`, engine rad/s x 10 for `rpm`, m, s). This module is the one
source of truth for sensor semantics; the wire format lives in `madsim.net.protocol`.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from madsim.array_table import b1_vector, f8_matrix, f8_vector, i8_vector, readonly
from madsim.facts import SCR_CPP_CLIENT_ANGLES_DEG, SCR_FIELDS
from madsim.physics import layout as L
from madsim.physics.kernel import NO_REFCOUNT
from madsim.tracks.kernels import locate_point, piece_at
from madsim.tracks.rays import cast_ray

SCR_DEFAULT_ANGLES_DEG = SCR_CPP_CLIENT_ANGLES_DEG   # a suite's angles before set_angles
SENSOR_RANGE_M = 200.0
FOCUS_COOLDOWN_S = 1.0
FOCUS_NONE = 360.0          # SCR's "no focus requested" sentinel
NOISE_STD = {"track": 0.1, "opponents": 0.02, "focus": 0.01}   # multiplicative N(1, std)
MS_TO_KMH = 3.6


# Wire order and widths (spec section 5); a frame's `flat` array holds the 79 values per car.
SENSOR_WIDTHS = tuple((f.name, f.width) for f in SCR_FIELDS)
SENSOR_OFFSETS = {}
_o = 0
for _name, _w in SENSOR_WIDTHS:
    SENSOR_OFFSETS[_name] = (_o, _w)
    _o += _w
N_VALUES = _o  # 79
(O_ANGLE, O_CURLAP, O_DAMAGE, O_DFS, O_DRACED, O_FUEL, O_GEAR, O_LASTLAP, O_OPP, O_RACEPOS, O_RPM,
 O_SX, O_SY, O_SZ, O_TRACK, O_TPOS, O_WSPIN, O_Z, O_FOCUS) = (SENSOR_OFFSETS[n][0] for n, _ in SENSOR_WIDTHS)

SENSOR_ORDER = tuple(name for name, _ in SENSOR_WIDTHS)
INT_FIELDS = tuple(f.name for f in SCR_FIELDS if f.kind == "int")


class SensorFrame:
    """Every SCR sensor for N cars, backed by one (N, 79) float64 array in wire order.

    Fields are read as attributes with the SCR names: scalars are (N,) views, `track` (N, 19),
    `opponents` (N, 36), `focus` (N, 5), `wheelSpinVel` (N, 4) in TORCS wheel order FR, FL, RR,
    RL; the int fields (damage, gear, racePos) come as int64 copies. `cars` = the World rows.
    """

    __slots__ = ("flat", "cars")

    def __init__(self, flat: np.ndarray, cars: np.ndarray):
        self.flat = flat
        self.cars = cars

    @classmethod
    def from_flat(cls, flat: np.ndarray, cars: np.ndarray) -> "SensorFrame":
        return cls(flat, cars)

    def __getattr__(self, name: str):
        try:
            o, w = SENSOR_OFFSETS[name]
        except KeyError:
            raise AttributeError(name) from None
        v = self.flat[:, o] if w == 1 else self.flat[:, o:o + w]
        return v.astype(np.int64) if name in INT_FIELDS else v

    def __len__(self) -> int:
        return self.flat.shape[0]

    def row(self, k: int) -> dict:
        """One car's sensors as a dict of Python numbers / lists (SCR names)."""
        r = self.flat[k]
        out = {}
        for name, (o, w) in SENSOR_OFFSETS.items():
            if w == 1:
                out[name] = int(r[o]) if name in INT_FIELDS else float(r[o])
            else:
                out[name] = r[o:o + w].tolist()
        return out


@numba.njit(cache=True, inline="always")
def _opponent_sectors(st, i, active, max_range, row):
    """row[O_OPP + a] = nearest distance of another active car in 10-degree sector a around car i
    (poses from the World state st); bearing positive clockwise from the heading, sector 0
    starts dead astern (SCR section 5.2); cars at 0 or >= max_range m are skipped; empty
    sectors = max_range."""
    for a in range(36):
        row[O_OPP + a] = max_range
    xi, yi, yawi = st[i, L.S_X], st[i, L.S_Y], st[i, L.S_YAW]
    for j in range(st.shape[0]):
        if j == i or not active[j]:
            continue
        dx = st[j, L.S_X] - xi
        dy = st[j, L.S_Y] - yi
        d = math.sqrt(dx * dx + dy * dy)
        if d <= 0.0 or d >= max_range:
            continue
        beta = math.degrees(yawi - math.atan2(dy, dx))
        beta = beta - 360.0 * math.floor((beta + 180.0) / 360.0)   # [-180, 180)
        if beta <= -180.0:
            beta += 360.0                                            # (-180, 180]
        sector = int(math.floor((beta + 180.0) / 10.0))
        if sector >= 36:
            continue  # dead astern after wrapping: SCR drops it
        if d < row[O_OPP + sector]:
            row[O_OPP + sector] = d


RAY_UNCAST = math.nan
"""The `track` value of a ray left out (its angle NaN in the angles `sensor_kernel` is given: see
`uncast_angles`); `fill_rays` casts it later from the same state, bit for bit as if cast."""


def uncast_angles(angles_deg: np.ndarray, read: np.ndarray) -> np.ndarray:
    """A copy of one car's 19 rangefinder angles (deg) with NaN (not cast) at every ray index
    not in `read`."""
    out = np.full(19, np.nan)
    idx = np.asarray(read, dtype=np.int64)
    out[idx] = np.asarray(angles_deg, dtype=np.float64)[idx]
    return out


@numba.njit(cache=True, inline="always")
def _ray(runs, half_width, run, x, y, yaw, angle_deg, max_range):
    """The rangefinder ray at `angle_deg` (SCR's sign: positive to the right) of a car at (x, y,
    yaw) on piece run `run`: its distance to the road's edge, capped at max_range."""
    h = yaw - math.radians(angle_deg)
    return cast_ray(runs, half_width, run, x, y, math.cos(h), math.sin(h), max_range)


@numba.njit(cache=True, **NO_REFCOUNT)
def fill_rays(cars, st, runs, piece_run, half_width, angles_deg, max_range, flat):
    """Cast the rays `sensor_kernel` left out (RAY_UNCAST) in flat[k] of car cars[k], from the
    World state `st` it was sensed from and the car's full angles: the same operations as
    `sensor_kernel`'s, so the rows equal a full cast bit for bit. Returns the rays cast."""
    count = 0
    for k in range(cars.shape[0]):
        i = cars[k]
        row = flat[k]
        for j in range(19):
            if row[O_TRACK + j] == row[O_TRACK + j]:
                continue
            row[O_TRACK + j] = _ray(runs, half_width, piece_run[int(st[i, L.S_PIECE])],
                                    st[i, L.S_X], st[i, L.S_Y], st[i, L.S_YAW], angles_deg[i, j], max_range)
            count += 1
    return count


@numba.njit(cache=True, **NO_REFCOUNT)
def sensor_kernel(cars, st, geo, runs, piece_run, half_width, angles_deg, race_pos, dist_origin,
                  active, max_range, out):
    """out[k] = the 79 wire-order SCR values of car cars[k] (focus left at -1, no noise) from the
    World state `st` (layout.STATE_COLUMNS): units converted, rangefinders cast exactly (-1 off
    the road; RAY_UNCAST where the car's angle is NaN, `uncast_angles`), opponents by sector.
    One pass; it allocates nothing, so it runs without numba's reference counting
    (`kernel.NO_REFCOUNT`). `geo` (the track's piece table) is not read."""
    for k in range(cars.shape[0]):
        i = cars[k]
        row = out[k]
        a = st[i, L.S_THEAD] - st[i, L.S_YAW]
        a = a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))
        if a == -math.pi:
            a = math.pi
        row[O_ANGLE] = a
        row[O_CURLAP] = st[i, L.S_CURLAP]
        row[O_DAMAGE] = math.floor(st[i, L.S_DAMAGE])
        row[O_DFS] = st[i, L.S_S]
        row[O_DRACED] = st[i, L.S_DIST] - dist_origin[i]
        row[O_FUEL] = st[i, L.S_FUEL]
        row[O_GEAR] = st[i, L.S_GEAR]
        row[O_LASTLAP] = st[i, L.S_LASTLAP]
        _opponent_sectors(st, i, active, max_range, row)
        row[O_RACEPOS] = race_pos[i]
        row[O_RPM] = st[i, L.S_WE] * 10.0
        row[O_SX] = st[i, L.S_VX] * MS_TO_KMH
        row[O_SY] = st[i, L.S_VY] * MS_TO_KMH
        row[O_SZ] = st[i, L.S_VZ] * MS_TO_KMH      # the body's vertical velocity, as TORCS's DynGC.vel.z
        tpos = st[i, L.S_N] / half_width
        row[O_TPOS] = tpos
        if abs(tpos) <= 1.0:
            run = piece_run[int(st[i, L.S_PIECE])]
            x, y, yaw = st[i, L.S_X], st[i, L.S_Y], st[i, L.S_YAW]
            for j in range(19):
                angle = angles_deg[i, j]
                if angle != angle:      # NaN: a ray no reader of this car needs (RAY_UNCAST)
                    row[O_TRACK + j] = RAY_UNCAST
                    continue
                row[O_TRACK + j] = _ray(runs, half_width, run, x, y, yaw, angle, max_range)
        else:
            for j in range(19):
                row[O_TRACK + j] = -1.0
        for w in range(4):
            row[O_WSPIN + w] = st[i, L.S_SPIN + w]
        row[O_Z] = st[i, L.S_Z] - st[i, L.S_ROADZ]
        for j in range(5):
            row[O_FOCUS + j] = -1.0


@numba.njit(cache=True, **NO_REFCOUNT)
def focus_kernel(cars, st, due, requested, geo, length, runs, piece_run, half_width, max_range, flat):
    """flat[k, O_FOCUS:O_FOCUS + 5] = the five focus rays of car cars[k] where due[k] (bool
    (N,)): 1 deg apart around its requested angle requested[cars[k]] (deg, SCR sense), m, as
    `Track.rangefinders` casts them (the piece walk from the piece at the car's S_S, the run of
    the piece at the located s), bit for bit. Rows not due are left alone. Allocates nothing."""
    for k in range(cars.shape[0]):
        if not due[k]:
            continue
        i = cars[k]
        x, y, yaw = st[i, L.S_X], st[i, L.S_Y], st[i, L.S_YAW]
        s, _, _ = locate_point(geo, length, piece_at(geo, length, st[i, L.S_S]), x, y)
        run = piece_run[piece_at(geo, length, s)]
        centre = requested[i]
        for j in range(5):
            h = yaw - math.radians(centre + (j - 2.0))
            flat[k, O_FOCUS + j] = cast_ray(runs, half_width, run, x, y, math.cos(h), math.sin(h),
                                            max_range)


def wrap_angle(a):
    """Wrap radians to (-pi, pi]."""
    a = np.asarray(a, dtype=np.float64)
    w = np.mod(a + np.pi, 2 * np.pi) - np.pi
    return np.where(w == -np.pi, np.pi, w)


def apply_noise(frame: SensorFrame, rng: np.random.Generator) -> None:
    """SCR `-noisy`: multiply track, opponents and focus by N(1, std) draws (in place); the -1
    sentinels of track and focus stay exact (spec 5.1, 5.2, 5.3)."""
    for name, std in NOISE_STD.items():
        values = getattr(frame, name)
        draw = rng.normal(1.0, std, size=values.shape)
        if name in ("track", "focus"):
            draw = np.where(values == -1.0, 1.0, draw)
        values *= draw


@numba.njit(cache=True)
def focus_request(cars, focus_deg, requested, next_allowed, earliest):
    """requested[cars[k]] = focus_deg[k] where it is in [-90, 90] deg, else FOCUS_NONE;
    earliest[0] lowered to the cooldown end of a car that now asks (see focus_due)."""
    for k in range(cars.shape[0]):
        i = cars[k]
        f = focus_deg[k]
        if -90.0 <= f <= 90.0:
            requested[i] = f
            earliest[0] = min(earliest[0], next_allowed[i])
        else:
            requested[i] = FOCUS_NONE


@numba.njit(cache=True)
def focus_due(cars, time_s, on_track, requested, next_allowed, earliest, due):
    """due[k] = car cars[k] gets a focus reading at time_s[k]: on the road (on_track[k]), a focus
    requested, its cooldown over; starts those cars' cooldowns. earliest[0] = the first time at
    which any car with a request may be due (inf: none asks). Returns how many are due."""
    count = 0
    for k in range(cars.shape[0]):
        i = cars[k]
        ok = on_track[k] and requested[i] != FOCUS_NONE and time_s[k] >= next_allowed[i]
        due[k] = ok
        if ok:
            next_allowed[i] = time_s[k] + FOCUS_COOLDOWN_S
            count += 1
    first = math.inf
    for i in range(requested.shape[0]):
        if requested[i] != FOCUS_NONE:
            first = min(first, next_allowed[i])
    earliest[0] = first
    return count


class FocusState:
    """Per-car focus bookkeeping: the angle requested in the previous control message and the
    simulated time from which the next valid reading may be produced (one per second)."""

    def __init__(self, n: int):
        self.requested_deg = np.zeros(n)          # a client that never asks gets focus 0
        self.next_allowed_s = np.zeros(n)
        self.earliest = np.zeros(1)                # (1,): no car can be due before this time, s

    @property
    def earliest_s(self) -> float:
        """No car can get a reading before this simulated time (s): due() need not run."""
        return float(self.earliest[0])

    def request(self, cars: np.ndarray, focus_deg: np.ndarray) -> None:
        """Store the focus requests of this tick's control messages (used for the next state)."""
        f = np.array(np.broadcast_to(np.asarray(focus_deg, dtype=np.float64), cars.shape))   # writable, as the compiled tick passes it (no 2nd compile)
        focus_request(np.ascontiguousarray(cars, dtype=np.int64), f, self.requested_deg,
                      self.next_allowed_s, self.earliest)

    def due(self, cars: np.ndarray, race_time_s: np.ndarray, on_track: np.ndarray) -> np.ndarray:
        """Which of `cars` get a valid reading now; advances their cooldown."""
        due = np.zeros(cars.shape[0], dtype=np.bool_)
        focus_due(np.ascontiguousarray(cars, dtype=np.int64), np.ascontiguousarray(race_time_s, dtype=np.float64),
                  np.ascontiguousarray(on_track, dtype=np.bool_), self.requested_deg, self.next_allowed_s,
                  self.earliest, due)
        return due


class SensorSuite:
    """Computes SensorFrames for a World: per-car rangefinder angles, focus requests and
    cooldowns, the SCR `distRaced` origin, optional noise from a Generator.

    One suite per door (server, env): it holds what SCR keeps per client between ticks.
    """

    def __init__(self, world, *, noisy: bool = False, rng: np.random.Generator | None = None):
        self.world = world
        self.noisy = bool(noisy)
        self.rng = rng if rng is not None else world.rng
        n = world.n_cars
        self.angles_deg = np.tile(np.asarray(SCR_DEFAULT_ANGLES_DEG), (n, 1))
        self.cast_angles = self.angles_deg.copy()   # the kernels' angles: NaN = not cast
        self._partial = np.zeros(n, dtype=np.bool_)  # cars of which only some rays are cast
        self.focus = FocusState(n)
        self.dist_origin = np.zeros(n)
        self._all = np.arange(n, dtype=np.int64)
        self._all_active = np.ones(n, dtype=np.bool_)
        track = world.track
        self._track_args = (track.geo, track.runs, track.piece_run, track.width / 2)
        self._length = float(track.length)
        self.reset()

    def reset(self) -> None:
        """Call after `world.reset()`: distRaced restarts from 0, focus cooldowns clear."""
        self.dist_origin = np.array(self.world.state[:, L.S_DIST], dtype=np.float64)
        self.focus = FocusState(self.world.n_cars)

    def set_angles(self, car: int, angles_deg) -> None:
        """The 19 rangefinder angles a client asked for in its identification (degrees)."""
        a = np.asarray(angles_deg, dtype=np.float64)
        if a.shape != (19,):
            raise ValueError(f"rangefinder angles must be 19 values, got shape {a.shape}")
        self.angles_deg[car] = a
        self.cast_angles[car] = a
        self._partial[car] = False

    def cast_only(self, cars, read) -> None:
        """Cast only the rays `read` (indices 0..18) of `cars` from now on (a compiled traffic
        behaviour's, `traffic_kernel.RAYS_READ`); frames hold RAY_UNCAST in their other rays
        until `complete`. Not for a noisy suite (noise would be drawn on the missing rays)."""
        if self.noisy:
            raise ValueError("a noisy suite casts every ray")
        for car in np.atleast_1d(np.asarray(cars, dtype=np.int64)).tolist():
            self.cast_angles[car] = uncast_angles(self.angles_deg[car], read)
            self._partial[car] = True

    def cast_all(self) -> None:
        """Every car's 19 rays cast again (in place: compiled callers keep their arrays)."""
        self.cast_angles[...] = self.angles_deg
        self._partial[:] = False

    def complete(self, flat: np.ndarray, cars: np.ndarray) -> int:
        """Cast the rays left out of `flat` (rows of `cars`, sensed from the world's current
        state): every row then equals a full cast's bit for bit. Returns the rays cast."""
        if not self._partial.any():
            return 0
        runs, piece_run, half = self._track_args[1:]
        return fill_rays(np.ascontiguousarray(cars, dtype=np.int64), self.world.state, runs,
                         piece_run, half, self.angles_deg, SENSOR_RANGE_M, flat)

    def request_focus(self, cars, focus_deg) -> None:
        """Focus angles from this tick's control messages (used for the next frame)."""
        self.focus.request(np.atleast_1d(np.asarray(cars, dtype=np.int64)), np.atleast_1d(focus_deg))

    def frame(self, cars=None) -> SensorFrame:
        """Sensors of `cars` (default: all) at the world's current state, in SCR units."""
        w = self.world
        cars = self._all if cars is None else np.atleast_1d(np.asarray(cars, dtype=np.int64))
        flat = np.empty((cars.shape[0], N_VALUES))
        geo, runs, piece_run, half = self._track_args
        sensor_kernel(cars, w.state, geo, runs, piece_run, half, self.cast_angles, w.race_pos,
                      self.dist_origin, _active(w, self), SENSOR_RANGE_M, flat)
        st = w.state
        due = None
        if st.shape[0] and st[0, L.S_TIME] >= self.focus.earliest[0]:   # one clock for all cars
            due = self.focus.due(cars, st[cars, L.S_TIME], np.abs(flat[:, O_TPOS]) <= 1.0)
        return self.finish_frame(flat, cars, due)

    def kernel_args(self) -> tuple:
        """`sensor_kernel`'s arguments after (cars, st) up to the output, and the focus
        arrays (requested, next allowed, earliest): what a compiled caller such as the SCR
        server's tick passes."""
        w = self.world
        return (*self._track_args, self.cast_angles, w.race_pos, self.dist_origin, _active(w, self),
                SENSOR_RANGE_M, self.focus.requested_deg, self.focus.next_allowed_s, self.focus.earliest)

    def finish_frame(self, flat: np.ndarray, cars: np.ndarray, due) -> SensorFrame:
        """The frame of `sensor_kernel`'s rows `flat` (N, 79) of `cars`: focus readings where
        `due` (bool (N,) from FocusState.due, or None) and noise if the suite is noisy."""
        if due is not None:
            geo, runs, piece_run, half = self._track_args
            focus_kernel(cars, self.world.state, due, self.focus.requested_deg, geo, self._length,
                         runs, piece_run, half, SENSOR_RANGE_M, flat)
        frame = SensorFrame(flat, cars)
        if self.noisy:
            apply_noise(frame, self.rng)
        return frame


def _active(world, suite) -> np.ndarray:
    """Cars still in the race (all, unless the world says otherwise)."""
    active = getattr(world, "active", None)
    return suite._all_active if active is None else np.asarray(active, dtype=np.bool_)



# --- the sensors of a compiled door (the SCR server's, MadrasEnv's), from an address table ---

SENSOR_TABLE = (
    ("cars", "i8", 1, "C"), ("track_geo", "f8", 2, "C"), ("track_runs", "f8", 2, "C"),
    ("piece_run", "i8", 1, "C"), ("angles", "f8", 2, "C"), ("dist_origin", "f8", 1, "C"),
    ("active", "b1", 1, "C"), ("focus_requested", "f8", 1, "C"), ("focus_next", "f8", 1, "C"),
    ("focus_earliest", "f8", 1, "C"), ("due", "b1", 1, "C"), ("flat", "f8", 2, "C"),
    ("time_s", "f8", 1, "C"), ("on_track", "b1", 1, "C"),
)
"""The rows a door's address table (`madsim.array_table`) holds for `sense_table`, in this order
from its row s0 (`sensor_table_arrays`)."""
(SN_CARS, SN_GEO, SN_RUNS, SN_PIECE_RUN, SN_ANGLES, SN_ORIGIN, SN_ACTIVE, SN_REQUESTED, SN_NEXT,
 SN_EARLIEST, SN_DUE, SN_FLAT, SN_TIME_S, SN_ON_TRACK) = (np.int64(k) for k in range(len(SENSOR_TABLE)))


def sensor_table_arrays(suite: SensorSuite, cars: np.ndarray, due: np.ndarray, flat: np.ndarray,
                        scratch: tuple) -> tuple:
    """The arrays of `SENSOR_TABLE`, in its order: the suite's (`SensorSuite.kernel_args`), the
    cars sensed (N,) int64, the focus readings due (N,) bool, the rows (N, 79) and the scratch
    (time_s (N,) float64, on_track (N,) bool)."""
    geo, runs, piece_run, _, angles, _, origin, active, _, *focus = suite.kernel_args()
    return (cars, geo, runs, piece_run, angles, origin, active, *focus, due, flat, *scratch)


@numba.njit(cache=True)
def sense_table(st, t, s0, race_pos, length, half_width, max_range, plain):
    """`SensorSuite.frame` from the arrays at rows s0.. of address table t (`SENSOR_TABLE`): the
    rows of `cars` into flat (`sensor_kernel`), the focus cooldowns (`focus_due`) and the
    readings due (`focus_kernel`). Returns False, the frame unfinished, when not `plain` (noise
    to apply: `SensorSuite.finish_frame` with due, cleared if none is due); else True."""
    cars, flat, due = i8_vector(t, s0 + SN_CARS), f8_matrix(t, s0 + SN_FLAT), b1_vector(t, s0 + SN_DUE)
    requested, next_allowed = f8_vector(t, s0 + SN_REQUESTED), f8_vector(t, s0 + SN_NEXT)
    earliest = f8_vector(t, s0 + SN_EARLIEST)
    geo, runs = readonly(f8_matrix(t, s0 + SN_GEO)), readonly(f8_matrix(t, s0 + SN_RUNS))
    piece_run = readonly(i8_vector(t, s0 + SN_PIECE_RUN))
    sensor_kernel(cars, st, geo, runs, piece_run, half_width, f8_matrix(t, s0 + SN_ANGLES), race_pos,
                  f8_vector(t, s0 + SN_ORIGIN), b1_vector(t, s0 + SN_ACTIVE), max_range, flat)
    count = 0
    if st[0, L.S_TIME] >= earliest[0]:        # one clock for all cars
        time_s, on_track = f8_vector(t, s0 + SN_TIME_S), b1_vector(t, s0 + SN_ON_TRACK)
        for k in range(cars.shape[0]):
            time_s[k] = st[cars[k], L.S_TIME]
            on_track[k] = abs(flat[k, O_TPOS]) <= 1.0
        count = focus_due(cars, time_s, on_track, requested, next_allowed, earliest, due)
    if not plain:
        if count == 0:
            due[:] = False
        return False
    if count > 0:
        focus_kernel(cars, st, due, requested, geo, length, runs, piece_run, half_width, max_range,
                     flat)
    return True
