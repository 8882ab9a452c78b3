"""`World`: cars on a track, advanced together in ticks of exactly 0.02 s.

State lives in one array `World.state` (N, len(STATE_COLUMNS)), one row per car, Fortran order
so that each column is a contiguous (N,) array; columns and units are listed in
`madsim.physics.layout.STATE_COLUMNS` / `STATE_DOC` and exposed as read-only attributes
(`world.x`, `world.speed`, ...). The physics is the compiled kernel in `kernel.py`.
"""

from __future__ import annotations

import importlib
import importlib.util
import math

import numpy as np

from madsim.array_table import address_table
from madsim.cars.spec import CarSpec
from madsim.facts import SUBSTEP_S, SUBSTEPS_PER_TICK, TICK_S
from madsim.physics import kernel, suspension, world_tick
from madsim.physics import layout as L
from madsim.physics.pymunk_direct import D_NARROWED as _D_NARROWED
from madsim.physics.tables import DAMAGE_SKILL, QUICKRACE_GRID, SKID, car_table, grid_positions, piece_table
from madsim.tracks.track import Track

DT = SUBSTEP_S
"""Physics sub-step, s (TORCS's simulation step)."""
SUBSTEPS = SUBSTEPS_PER_TICK
"""Sub-steps per tick: controls are held for DT * SUBSTEPS = 0.02 s."""
TICK = TICK_S
_W0 = np.int64(0)        # `world_tick.step_table`'s first row: the table holds the World's alone

NAN_POLICIES = ("raise", "zero")


def contact_available() -> bool:
    """True if `madsim.physics.contact` (the contact solver) is installed."""
    return importlib.util.find_spec("madsim.physics.contact") is not None


class World:
    """Cars on a track: `step(controls)` advances every car by 0.02 s (10 sub-steps of 0.002 s).

    Args:
        track: the `Track`.
        cars: one `CarSpec` per car (N >= 1).
        rng: the only source of randomness a World may use (the physics itself is deterministic).
        fuel: consume fuel as TORCS does (spec 4.13); False keeps the initial fuel (and mass).
        damage: add contact damage to `damage` (damage raises drag by damage/10000).
        skill: TORCS driver skill level(s) for the tyre's skid term: "rookie", "amateur",
            "semi-pro" (SCR/MADRaS default), "pro"; one string or one per car.
        contact: use the contact solver (`madsim.physics.contact`) when it is installed.
        nan_policy: "raise" rejects non-finite controls with a ValueError naming car and column;
            "zero" replaces them by 0 and counts them per car in `nan_count`.
        threads: share the cars among numba's threads when there are many (>= 64); results are
            bit-identical either way. Off by default: it only pays on an otherwise idle machine.
        race_laps: the race's length in laps (None: no end). A car that has crossed the
            start line more than `race_laps` times, or once after another car has finished, has
            finished (TORCS's RM_CAR_STATE_FINISH): its laps stop, it takes no more damage, and
            its controls follow TORCS's slow pace (accel <= 0.2, brake >= 0.05 above 30 m/s);
            a finished car's next crossing ends the race (`race_over`; docs/physics.md, "The
            finish of a race", `physics.finish`). Settable; `reset` starts the race again.
    """

    def __init__(self, track: Track, cars: list[CarSpec], rng: np.random.Generator, *,
                 fuel: bool = False, damage: bool = True, skill: str | list[str] = "semi-pro",
                 contact: bool = True, nan_policy: str = "raise", threads: bool = False,
                 race_laps: int | None = None):
        if not isinstance(track, Track):
            raise TypeError(f"track must be a Track, got {type(track).__name__}")
        cars = list(cars)
        if not cars or not all(isinstance(c, CarSpec) for c in cars):
            raise TypeError("cars must be a non-empty list of CarSpec")
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        if nan_policy not in NAN_POLICIES:
            raise ValueError(f"nan_policy must be one of {NAN_POLICIES}, got {nan_policy!r}")
        skills = [skill] * len(cars) if isinstance(skill, str) else list(skill)
        if len(skills) != len(cars):
            raise ValueError(f"skill: {len(skills)} values for {len(cars)} cars")
        for s in skills:
            if s not in SKID:
                raise ValueError(f"skill must be one of {tuple(SKID)}, got {s!r}")
        self.track = track
        self.cars = tuple(cars)
        self.rng = rng
        self.fuel_on = bool(fuel)
        self.damage_on = bool(damage)
        self.skills = tuple(skills)
        self.nan_policy = nan_policy
        n = len(cars)
        self.n_cars = n
        self._cp, self._curve_w, self._curve_t = car_table(self.cars, skills, self.damage_on)
        self._pt, self._surf, self._tsc = piece_table(track)
        self._top_gear = self._cp[:, L.C_TOP].astype(np.int64)
        self.race_laps = race_laps
        # cars are independent inside a call, so threads give bit-identical results
        parallel = threads and n >= kernel.PARALLEL_MIN_CARS
        self._advance = kernel.advance_parallel if parallel else kernel.advance
        self.state = np.zeros((n, L.N_STATE), order="F")
        self._info = np.zeros(2, dtype=np.int64)
        self.nan_count = np.zeros(n, dtype=np.int64)
        self.contact_wall = np.zeros(n, dtype=bool)
        self.contact_car = np.zeros(n, dtype=bool)
        self.contact_pairs: list[tuple[int, int]] = []
        self.race_pos = np.arange(1, n + 1, dtype=np.int64)
        self._solver = None
        if contact and contact_available():
            mod = importlib.import_module("madsim.physics.contact")
            cp = self._cp
            kw = {"damage_factor": DAMAGE_SKILL[skills[0]]} if len(set(skills)) == 1 else {}
            self._solver = mod.ContactSolver(track, cp[:, L.C_HALF_LEN].copy(), cp[:, L.C_HALF_WID].copy(),
                                             np.array([c.mass_total for c in self.cars]),
                                             cp[:, L.C_IZZ].copy(), **kw)
            self._piece_i = np.zeros(n, dtype=np.int64)
            self._near = np.zeros(1, dtype=np.int64)
            # whole-tick scratch (contact_kernels.whole_tick): state and controls, the state's order
            order = "F" if np.isfortran(self.state) else "C"
            self._snap = np.zeros((n, world_tick.SNAP_COLUMNS), order=order)
            self._path, self._turn = np.zeros(n), np.zeros(n)
            st = self.state
            self._contact_cols = tuple(st[:, c] for c in (L.S_X, L.S_Y, L.S_YAW, L.S_VXG, L.S_VYG, L.S_R))
            self._stepper_serial = mod.advance_until_near
            self._stepper = mod.advance_until_near_parallel if parallel else mod.advance_until_near
            # finish_tick's: one response's flags and damage, the tick's car pairs and count
            self._hits = (np.zeros(n, dtype=bool), np.zeros(n, dtype=bool), np.zeros(n))
            self._pairs_tick = np.zeros((16, 2), dtype=np.int64)
            self._pair_count = np.zeros(1, dtype=np.int64)
            self._no_arbiters = (np.zeros(0, dtype=np.int64), np.zeros(0))
            self._set_contact_table()
        self.tick_args: tuple | None = None
        """`world_tick.step_world`'s arguments after (u, nsub) (contact worlds with serial
        stepping; else None): what a compiled caller such as the SCR server passes."""
        self._args = None
        self._set_tick_args()
        self.reset()

    # --- set-up -------------------------------------------------------------------------------

    @property
    def race_laps(self) -> int | None:
        """The race's laps (None: no end); past them a car has finished: no damage, slow pace."""
        return self._race_laps

    @race_laps.setter
    def race_laps(self, laps: int | None) -> None:
        self._cp[:, L.C_FINISH] = finish_crossings(laps)
        self._race_laps = None if laps is None else int(laps)

    @property
    def finished(self) -> np.ndarray:
        """(N,) bool: the cars that have finished the race (TORCS's rule, `physics.finish`: more
        start-line crossings than `race_laps`, or one more after another car's finish; all False
        without `race_laps`)."""
        finish = self._cp[:, L.C_FINISH]
        return (finish < 0) | ((finish > 0) & (self.state[:, L.S_LAPS] >= finish))

    @property
    def race_over(self) -> bool:
        """True once the race has ended (TORCS's RM_RACE_ENDED): every car has finished, or a
        finished car has crossed the start line again. Always False without `race_laps`."""
        return self._race_laps is not None and bool((self._cp[:, L.C_FINISH] < 0).any()
                                                    or self.finished.all())

    @property
    def contact_active(self) -> bool:
        """True if the contact solver runs (requested and installed)."""
        return self._solver is not None

    def reset(self, placements=None, *, gears=0, grid: dict | None = None) -> None:
        """Put the cars on the starting grid (track spec 7) or at explicit placements, at rest or
        with a speed, and clear all counters.

        placements: None, or array-like (N, 3) of (s [m], n [m, left +], speed [m/s]); the car
        points along the centre-line tangent. gears: engaged gear per car (int or (N,)), default
        neutral as TORCS; clipped to [-1, top gear].
        grid: without placements, the race's `Starting Grid` values as a TORCS race file gives
        them ("rows", "distance to start", "distance between columns", "offset within a column",
        m), over quickrace's (2, 25, 20, 10); the track's own grid overrides both, as in TORCS.
        E.g. {"rows": 1, "distance to start": 100} is the real-TORCS traces' start.
        """
        n = self.n_cars
        tr = self.track
        if placements is None:
            s, off = grid_positions(tr, n, check_grid(grid))
            speed = np.zeros(n)
        else:
            if grid is not None:
                raise ValueError("reset: give placements or grid, not both")
            pl = np.asarray(placements, dtype=np.float64)
            if pl.shape != (n, 3):
                raise ValueError(f"placements must have shape ({n}, 3) = (s, n, speed) per car, got {pl.shape}")
            if not np.all(np.isfinite(pl)):
                bad = np.argwhere(~np.isfinite(pl))[0]
                raise ValueError(f"placements: car {bad[0]} {('s', 'n', 'speed')[bad[1]]} is not finite")
            s, off, speed = np.mod(pl[:, 0], tr.length), pl[:, 1], pl[:, 2]
        st = self.state
        st[:] = 0.0
        st[:, L.S_FUEL] = [c.fuel for c in self.cars]
        self._cp[:, L.C_FINISH] = finish_crossings(self._race_laps)     # a new race
        self._set_motion(np.arange(n), s, off, np.zeros(n), speed, gears)
        self.nan_count[:] = 0
        self.contact_wall[:] = False
        self.contact_car[:] = False
        self.contact_pairs = []
        if self._solver is not None:
            self._solver.reset()
        self._update_race_pos()

    def place(self, car: int, s: float, n: float = 0.0, *, yaw_rel: float = 0.0, speed: float = 0.0,
              gear: int | None = None) -> None:
        """Put one car at a pose, moving straight ahead: `s` m along the centre line from the start
        line, `n` m from it (left +), heading `yaw_rel` rad from the track's tangent there (left +),
        at `speed` m/s along its own heading, wheels rolling, yaw rate 0, static wheel loads.
        `gear`: engaged gear (default: keep). Laps, times, damage and fuel are kept; the other
        cars are untouched. Read its sensors with `SensorSuite(world).frame()`.
        """
        if not (isinstance(car, (int, np.integer)) and 0 <= car < self.n_cars):
            raise ValueError(f"car must be an index in 0..{self.n_cars - 1}, got {car!r}")
        vals = {"s": s, "n": n, "yaw_rel": yaw_rel, "speed": speed}
        for name, v in vals.items():
            if not (isinstance(v, (int, float, np.integer, np.floating)) and math.isfinite(v)):
                raise ValueError(f"place: {name} must be a finite number, got {v!r}")
        rows = np.array([car])
        g = int(self.state[car, L.S_GEAR]) if gear is None else gear
        self._set_motion(rows, np.array([float(s) % self.track.length]), np.array([float(n)]),
                         np.array([float(yaw_rel)]), np.array([float(speed)]), g)
        if self._solver is not None:
            self._solver.reset()

    def _set_motion(self, rows: np.ndarray, s, off, yaw_rel, speed, gears) -> None:
        """Pose, velocity, wheel spin, engine speed and static loads of `rows`; then re-locate them."""
        st, cp, tr = self.state, self._cp, self.track
        m = rows.shape[0]
        g = np.broadcast_to(np.asarray(gears), (m,))
        if not np.all(np.isfinite(g.astype(np.float64))):
            raise ValueError("gears must be finite")
        g = np.clip(np.rint(g).astype(np.int64), -1, self._top_gear[rows])
        x, y, _, heading = tr.pose(s, off)
        yaw = heading + yaw_rel
        keep = [L.S_FUEL, L.S_DAMAGE, L.S_LAPS, L.S_BACK, L.S_LAPSTART, L.S_CURLAP, L.S_LASTLAP,
                L.S_BESTLAP, L.S_TIME]
        kept = st[np.ix_(rows, keep)].copy()
        st[rows, :] = 0.0
        st[np.ix_(rows, keep)] = kept
        st[rows, L.S_X], st[rows, L.S_Y], st[rows, L.S_YAW] = x, y, yaw
        st[rows, L.S_DRAGK] = 1.0
        st[rows, L.S_VXG], st[rows, L.S_VYG] = speed * np.cos(yaw), speed * np.sin(yaw)
        for k in range(4):
            st[rows, L.S_SPIN + k] = st[rows, L.S_SPINRAW + k] = speed / cp[rows, L.C_RAD + k]
        st[rows, L.S_GEAR] = g
        ratio = cp[rows, L.C_RATIO + g + 1]
        driven_w = np.where(cp[rows, L.C_DRIVEN_R] > 0, st[rows, L.S_SPIN + 2], st[rows, L.S_SPIN])
        st[rows, L.S_WE] = np.clip(np.abs(driven_w * ratio), cp[rows, L.C_TICK], cp[rows, L.C_MAXI])
        for k in range(4):   # static loads of the dynamic mass
            st[rows, L.S_FZ + k] = (cp[rows, L.C_W0 + k] * (cp[rows, L.C_MASS] + st[rows, L.S_FUEL])
                                    / cp[rows, L.C_MASS])
        st[rows, L.S_PIECE] = tr.piece_at(s)
        kernel.refresh(st, cp, self._pt, self._surf, self._tsc, False)
        suspension.settle(st, cp, self._pt, self._tsc, np.asarray(rows, dtype=np.int64))

    # --- the tick -------------------------------------------------------------------------------

    def step(self, controls, substeps: int = SUBSTEPS) -> None:
        """Advance `substeps` sub-steps of 0.002 s (default 10: exactly 0.02 s) with `controls` held.

        controls: (N, 5) = steer [-1, 1] (left +), accel [0, 1], brake [0, 1], gear (integer,
        -1 reverse, 0 neutral, 1..top), clutch [0, 1]. Out-of-range values are clipped (gear
        rounded, then clipped); non-finite values follow `nan_policy`.
        substeps: 1..100; TORCS's own driver-call schedule gives 10 or 11
        (`madsim.physics.schedule.TorcsClock`).
        """
        if substeps != SUBSTEPS and not (isinstance(substeps, (int, np.integer)) and 1 <= substeps <= 100):
            raise ValueError(f"substeps must be an integer in 1..100, got {substeps!r}")
        nsub = int(substeps)
        if self.tick_args is not None:
            u = np.ascontiguousarray(controls, dtype=np.float64)
            if u.shape != (self.n_cars, 5):
                raise ValueError(f"controls must have shape ({self.n_cars}, 5) = "
                                 f"(steer, accel, brake, gear, clutch) per car, got {u.shape}")
            if not u.flags.writeable:
                u = u.copy()
            a, u_tick = self.tick_args, self._u_tick   # the tick runs on u_tick, a copy of u
            k = world_tick.step_table(u, u_tick, nsub, a[0], a[17], self._tick_table, _W0, DT,
                                      self.fuel_on, a[9])
            if k == world_tick.NONFINITE:
                k = world_tick.step_table(self._nonfinite(u), u_tick, nsub, a[0], a[17],
                                          self._tick_table, _W0, DT, self.fuel_on, a[9])
            self.finish_tick(u_tick, nsub, k)
            return
        u = np.array(controls, dtype=np.float64, order="C")   # a copy: a shift's cap writes its accel
        if u.shape != (self.n_cars, 5):
            raise ValueError(f"controls must have shape ({self.n_cars}, 5) = "
                             f"(steer, accel, brake, gear, clutch) per car, got {u.shape}")
        kernel.check_controls(u, self._info)
        if self._info[0]:
            u = self._nonfinite(u)
        st = self.state
        if self.n_cars > 1:      # finish and slipstream: from the state at the tick's start
            kernel.tick_start(st, self._cp, 0, self.n_cars, self.track.length)
        if self._solver is None:
            self._advance(st, self._cp, self._curve_w, self._curve_t, self._pt, self._surf, self._tsc,
                          u, nsub, DT, self.fuel_on)
        else:        # the threaded stepper
            self.contact_wall[:] = False
            self.contact_car[:] = False
            k = self._contact_steps(u, 0, nsub)
            if self._near[0]:
                self.finish_tick(u, nsub, k)
                return
            self.contact_pairs = []
        if self.n_cars > 1:
            self._update_race_pos()

    def _nonfinite(self, u: np.ndarray) -> np.ndarray:
        """`nan_policy` for controls u with non-finite values (self._info from check_controls):
        raise, or a copy with them zeroed (counted per car in nan_count)."""
        info = self._info
        car, col = divmod(int(info[1]), 5)
        if self.nan_policy == "raise":
            raise ValueError(f"controls: car {car} {L.CONTROL_COLUMNS[col]} is "
                             f"{u[car, col]!r} (must be finite); {int(info[0])} non-finite value(s)")
        u = u.copy()
        bad = ~np.isfinite(u)
        self.nan_count += bad.sum(axis=1)
        u[bad] = 0.0
        return u

    def finish_tick(self, u: np.ndarray, nsub: int, k: int, keep_pairs: bool = False) -> None:
        """Complete a tick that the compiled stepper (`world_tick.step_world`, or the sub-step
        loop) left after sub-step k with something near (self._near[0] != 0): the pymunk narrow
        phase (`ContactSolver.narrow`), then `world_tick.finish_contact` responds and goes on to
        the next sub-step where something is near, until the tick is done (contact flags, pairs
        and damage of the tick, race positions). With nothing near (the usual tick) only the
        pairs are cleared. u: the (N, 5) controls of the tick, already checked. keep_pairs: the
        rest of a tick `world_tick.contact_direct` began (its pairs kept; with the solver's
        direct[D_NARROWED] set, pymunk was already consulted at sub-step k)."""
        near = self._near
        if near[0] == 0:
            if self.contact_pairs:
                self.contact_pairs = []
            return
        solver, cols, piece = self._solver, self._contact_cols, self._piece_i
        walk = self._stepper is self._stepper_serial     # finish_contact runs the sub-steps
        if not keep_pairs:
            self._pair_count[0] = 0
        direct = solver.direct
        no_arbiters = self._no_arbiters
        while True:
            if near[0] < 0:                  # the pair list overflowed: grown, broad phase again
                near[0] = solver.broad_phase(cols[0], cols[1], cols[2], piece)
                self._set_tick_args()
            ints, floats = no_arbiters
            respond = near[0] > 0
            if respond:
                if direct[_D_NARROWED]:
                    ints, floats = solver.arbiters_after_direct()
                else:
                    ints, floats = solver.narrow(cols[0], cols[1], cols[2], DT)
                if (solver.arrays_version != self._contact_version
                        or self._pair_count[0] + solver.respond_arrays()[6].shape[0] > self._pairs_tick.shape[0]):
                    self._set_contact_table()
            k = world_tick.finish_contact(ints, floats, respond, k, nsub, u, self.state, self._snap,
                                          self._tick_table, _W0, self._contact_table, DT,
                                          self.fuel_on, self.damage_on, walk)
            if k == world_tick.TICK_DONE:
                break
            if not walk:                     # the threaded stepper, from Python
                k = self._contact_steps(u, k, nsub)
                if near[0] == 0:
                    if self.n_cars > 1:
                        self._update_race_pos()
                    break
        m = int(self._pair_count[0])
        self.contact_pairs = list(map(tuple, self._pairs_tick[:m].tolist())) if m else []

    def _contact_steps(self, u: np.ndarray, k: int, nsub: int) -> int:
        """Sub-steps k.. up to the next one after which something is near (see finish_tick)."""
        cols = self._contact_cols
        return self._stepper(self.state, self._cp, self._curve_w, self._curve_t, self._pt, self._surf,
                             self._tsc, u, k, nsub, DT, self.fuel_on, cols[0], cols[1], cols[2],
                             self._piece_i, self._solver.broad_phase_args, self._near, self._snap,
                             self._path, self._turn)

    def _set_tick_args(self) -> None:
        """(Re)build the World's address table (`world_tick.WORLD_TABLE`) when the contact
        solver replaced one of its arrays, and `tick_args` (serial stepping only: what a
        compiled caller such as the SCR server passes)."""
        if self._solver is None:
            return
        bp = self._solver.broad_phase_args
        if self._args is not None and self._args[15] is bp:
            return
        cols = self._contact_cols
        self._args = (self.state, self._cp, self._curve_w, self._curve_t, self._pt, self._surf,
                      self._tsc, DT, self.fuel_on, self.track.length, self._info, cols[0], cols[1],
                      cols[2], self._piece_i, bp, self._near, self._snap, self._path, self._turn,
                      self.contact_wall, self.contact_car, self.race_pos)
        self._tick_table = address_table(world_tick.world_table_arrays(self._args),
                                         world_tick.WORLD_TABLE)
        if self._stepper is self._stepper_serial:
            self.tick_args = self._args
        self._u_tick = np.zeros((self.n_cars, 5))

    def _set_contact_table(self) -> None:
        """(Re)build `world_tick.finish_contact`'s second table (`CONTACT_TABLE`): the solver's
        response arrays, the response scratch, the velocity columns and the tick's pairs (grown
        to hold as many more as one response can write)."""
        solver, cols = self._solver, self._contact_cols
        arrays = solver.respond_arrays()
        room = self._pair_count[0] + arrays[6].shape[0]
        if room > self._pairs_tick.shape[0]:
            grown = np.zeros((2 * room, 2), dtype=np.int64)
            grown[:self._pair_count[0]] = self._pairs_tick[:self._pair_count[0]]
            self._pairs_tick = grown
        self._contact_version = solver.arrays_version
        self._contact_arrays = (*arrays, *self._hits, *cols[3:6], self._pairs_tick, self._pair_count)
        self._contact_table = address_table(self._contact_arrays, world_tick.CONTACT_TABLE)

    def narrow_table(self) -> tuple:
        """(key, arrays): the arrays of `pymunk_direct.NARROW_TABLE` for a compiled tick that
        consults pymunk itself (`world_tick.contact_direct`), and a key that changes whenever
        one of them is replaced (the caller then builds its table again)."""
        solver = self._solver
        return ((id(self._contact_table), solver.narrow_version),
                solver.narrow_table_arrays(self._contact_table))

    def _update_race_pos(self) -> None:
        world_tick.race_positions(self.state, self.race_pos)

    # --- read-only views ---------------------------------------------------------------------------

    def column(self, name: str) -> np.ndarray:
        """Read-only (N,) view of one state column (see layout.STATE_COLUMNS)."""
        v = self.state[:, L.S[name]]
        v.flags.writeable = False
        return v

    @property
    def time(self) -> float:
        """Simulated time since reset, s."""
        return float(self.state[0, L.S_TIME])

    @property
    def speed(self) -> np.ndarray:
        """Horizontal speed |v|, m/s, (N,)."""
        return np.hypot(self.state[:, L.S_VXG], self.state[:, L.S_VYG])

    @property
    def piece(self) -> np.ndarray:
        return self.state[:, L.S_PIECE].astype(np.int64)

    @property
    def gear(self) -> np.ndarray:
        return self.state[:, L.S_GEAR].astype(np.int64)

    @property
    def laps(self) -> np.ndarray:
        return self.state[:, L.S_LAPS].astype(np.int64)

    @property
    def wheel_spin(self) -> np.ndarray:
        """(N, 4) wheel spin rad/s in wheel order FR, FL, RR, RL (a copy)."""
        return self.state[:, L.S_SPIN:L.S_SPIN + 4].copy()

    @property
    def wheel_load(self) -> np.ndarray:
        """(N, 4) wheel loads, N, wheel order FR, FL, RR, RL."""
        return np.array(self.state[:, L.S_FZ:L.S_FZ + 4])


def finish_crossings(laps) -> int:
    """A race of `laps` laps as the car table stores it (C_FINISH): the start-line crossings at
    which a car has finished, laps + 1 (the first crossing, from the grid, starts lap 1), or 0
    for None (no end)."""
    if laps is None:
        return 0
    if isinstance(laps, bool) or not isinstance(laps, (int, np.integer)) or laps < 0:
        raise ValueError(f"race_laps must be None or an integer >= 0, got {laps!r}")
    return int(laps) + 1


def check_grid(grid: dict | None) -> dict | None:
    """The grid values, checked: known names, finite numbers, at least one row, no negative distance."""
    if grid is None:
        return None
    out = {}
    for key, value in dict(grid).items():
        if key not in QUICKRACE_GRID or key == "initial height":
            known = ", ".join(k for k in QUICKRACE_GRID if k != "initial height")
            raise ValueError(f"grid: unknown value {key!r} (known: {known})")
        if not (isinstance(value, (int, float, np.integer, np.floating)) and math.isfinite(value)):
            raise ValueError(f"grid: {key!r} must be a finite number, got {value!r}")
        if value < (1 if key == "rows" else 0):
            raise ValueError(f"grid: {key!r} must be {'>= 1' if key == 'rows' else '>= 0'}, got {value!r}")
        out[key] = float(value)
    return out


def _column_property(name: str, doc: str) -> property:
    idx = L.S[name]

    def get(self: World) -> np.ndarray:
        v = self.state[:, idx]
        v.flags.writeable = False
        return v

    return property(get, doc=f"(N,) {doc}")


for _attr, _col in (("x", "x"), ("y", "y"), ("z", "z"), ("yaw", "yaw"), ("vx", "vx"), ("vy", "vy"),
                    ("vx_global", "vx_g"), ("vy_global", "vy_g"), ("yaw_rate", "yaw_rate"),
                    ("s", "s"), ("n", "n"), ("engine_speed", "engine_speed"),
                    ("steer_angle", "steer_angle"), ("dist_raced", "dist_raced"),
                    ("cur_lap_time", "cur_lap_time"), ("last_lap_time", "last_lap_time"),
                    ("best_lap_time", "best_lap_time"), ("damage", "damage"), ("fuel", "fuel"),
                    ("track_heading", "track_heading")):
    setattr(World, _attr, _column_property(_col, L.STATE_DOC[_col]))
