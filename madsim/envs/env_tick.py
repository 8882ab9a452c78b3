"""A one-learner env step's ticks as one compiled call: the learner's controls -> the World
advanced one tick -> every car's sensors -> the learner's rewards and dones, for each tick of
the step, then its observation. The Python loop around it only takes the action and keeps the
books.

The stages are the kernels every other door runs (`learner_kernel.tick_controls` and
`tick_outcome`, `world_tick.step_world`, `sensors.sensor_kernel`, `focus_due` and
`focus_kernel`, `learner_kernel.observe_rows`), in the order `MadrasCore.step` calls them one
by one, so a step gives the same bits either way (tests/envs/test_env_tick.py). Whatever a stage
cannot finish compiled stops the call at that stage and is done by `MadrasCore`'s Python path of
the same stage, which then goes on: the traffic cars' controls (`TrafficFleet.act`), something
near a car (the pymunk narrow phase, `World.finish_tick`), sensor noise, a reward or done
written in Python. (The SCR server's tick is built the same way: `madsim.net.server_tick`.)
"""

from __future__ import annotations

import numba
import numpy as np

from madsim.facts import SUBSTEPS_PER_TICK as SUBSTEPS
from madsim.agents.learner_kernel import observe_rows, tick_controls, tick_outcome
from madsim.agents.traffic_kernel import traffic_tick
from madsim.net.array_table import (address_table, b1_matrix, b1_vector, f4_matrix, f8_matrix,
                                    f8_tensor, f8_vector, i1_vector, i8_matrix, i8_vector,
                                    readonly)
from madsim.physics.layout import S_TIME
from madsim.physics.sensors import O_TPOS, focus_due, focus_kernel, sensor_kernel
from madsim.physics.world_tick import step_world

CONTROLS, TRAFFIC, STEP, SENSE, OUTCOME, NEXT, DONE = range(7)
"""A tick's stages in order (NEXT: after the outcome, on to the next tick); `env_tick` returns
the one Python must do, or DONE."""
NO_TRAFFIC, COMPILED_TRAFFIC, PYTHON_TRAFFIC = range(3)
"""`env_tick`'s `traffic`: none; built-in behaviours that draw nothing and report nothing
(`traffic_kernel.traffic_tick` in the call); others (the fleet's `act` in Python)."""

# The arrays `env_tick` reads, in the order of its address table: name, dtype, dimensions,
# memory order. World rows follow World.tick_args, sensor rows SensorSuite.kernel_args, the
# learner's rows its action map, component batches and step arrays (madsim.envs.core).
TABLE = (
    ("controls", "f8", 2, "C"), ("u_tick", "f8", 2, "C"), ("steps", "i8", 1, "C"),
    ("car_table", "f8", 2, "C"), ("curve_w", "f8", 2, "C"), ("curve_t", "f8", 2, "C"),
    ("piece_table", "f8", 2, "C"), ("surfaces", "f8", 2, "C"), ("track_scalars", "f8", 1, "C"),
    ("info", "i8", 1, "C"), ("x", "f8", 1, "C"), ("y", "f8", 1, "C"), ("yaw", "f8", 1, "C"),
    ("piece", "i8", 1, "C"),
    ("bp_geo", "f8", 2, "C"), ("bp_bar", "f8", 2, "C"), ("bp_cars", "f8", 2, "C"), ("bp_prm", "f8", 1, "C"),
    ("bp_wall_cache", "f8", 2, "C"), ("bp_vref", "f8", 2, "C"), ("bp_pairs", "i8", 2, "C"),
    ("bp_meta", "i8", 1, "C"), ("bp_flags", "i1", 1, "C"), ("bp_slack", "f8", 1, "C"),
    ("near", "i8", 1, "C"), ("path", "f8", 1, "C"), ("turn", "f8", 1, "C"),
    ("contact_wall", "b1", 1, "C"), ("contact_car", "b1", 1, "C"), ("race_pos", "i8", 1, "C"),
    ("cars", "i8", 1, "C"), ("track_geo", "f8", 2, "C"), ("track_runs", "f8", 2, "C"),
    ("piece_run", "i8", 1, "C"), ("angles", "f8", 2, "C"), ("dist_origin", "f8", 1, "C"),
    ("active", "b1", 1, "C"), ("focus_requested", "f8", 1, "C"), ("focus_next", "f8", 1, "C"),
    ("focus_earliest", "f8", 1, "C"), ("due", "b1", 1, "C"), ("flat", "f8", 2, "C"),
    ("time_s", "f8", 1, "C"), ("on_track", "b1", 1, "C"), ("hits", "b1", 1, "C"),
    ("slot0", "i8", 1, "C"), ("rows", "i8", 1, "C"), ("sab", "f8", 2, "C"), ("gear", "f8", 1, "C"),
    ("pid_state", "f8", 2, "C"), ("pid_params", "f8", 1, "C"), ("pid_fresh", "b1", 1, "C"),
    ("lane_des", "f8", 1, "C"), ("speed_des_kmh", "f8", 1, "C"), ("prev", "f8", 2, "C"),
    ("out4", "f8", 2, "C"),
    ("r_codes", "i8", 1, "C"), ("r_par", "f8", 3, "C"), ("r_state", "f8", 3, "C"),
    ("d_codes", "i8", 1, "C"), ("d_par", "f8", 3, "C"), ("d_state", "f8", 3, "C"),
    ("weights", "f8", 1, "C"), ("is_trunc", "b1", 1, "C"), ("running", "i8", 1, "C"),
    ("track_length", "f8", 1, "C"), ("cur", "f8", 2, "C"), ("length", "f8", 1, "C"),
    ("collision", "b1", 1, "C"), ("r_vals", "f8", 2, "C"), ("d_vals", "f8", 2, "C"),
    ("total", "f8", 1, "C"), ("terms", "f8", 2, "C"), ("ticks", "i8", 1, "C"),
    ("term", "b1", 1, "C"), ("trunc", "b1", 1, "C"), ("fired", "b1", 2, "C"),
    ("wire_index", "i8", 1, "C"), ("scale", "f8", 1, "C"), ("low", "f8", 1, "C"),
    ("high", "f8", 1, "C"), ("gain", "f8", 1, "C"), ("offset", "f8", 1, "C"),
    ("obs", "f4", 2, "C"), ("status", "i8", 1, "C"),
    ("traffic_rows", "i8", 1, "C"), ("traffic_kind", "i8", 1, "C"), ("traffic_s", "f8", 2, "C"),
    ("traffic_p", "f8", 2, "C"), ("traffic_lanes", "f8", 2, "C"), ("traffic_rand", "f8", 2, "C"),
)
(U, U_TICK, STEPS, CP, CURVE_W, CURVE_T, PT, SURF, TSC, INFO, X, Y, YAW, PIECE, BP_GEO, BP_BAR,
 BP_CARS, BP_PRM, BP_WALL, BP_VREF, BP_PAIRS, BP_META, BP_FLAGS, BP_SLACK, NEAR, PATH, TURN, WALL,
 CAR, RACE_POS, CARS, GEO, RUNS, PIECE_RUN, ANGLES, ORIGIN, ACTIVE, REQUESTED, NEXT_ALLOWED,
 EARLIEST, DUE, FLAT, TIME_S, ON_TRACK, HITS, SLOT0, ROWS, SAB, GEAR, PID_STATE, PID_PARAMS,
 PID_FRESH, LANE_DES, SPEED_DES, PREV, OUT4, R_CODES, R_PAR, R_STATE, D_CODES, D_PAR, D_STATE,
 WEIGHTS, IS_TRUNC, RUNNING, TRACK_LENGTH, CUR, LENGTH, COLLISION, R_VALS, D_VALS, TOTAL, TERMS,
 TICKS, TERM, TRUNC, FIRED, WIRE_INDEX, SCALE, LOW, HIGH, GAIN, OFFSET, OBS, STATUS,
 T_ROWS, T_KIND, T_S, T_P, T_LANES, T_RAND) = (np.int64(k) for k in range(len(TABLE)))
# int64 row numbers, not int literals: see array_table's views


@numba.njit(cache=True, error_model="numpy")
def env_tick(first, tick0, ticks, traffic, python, plain, ts, manual, normalise, nsub, st, snap,
             t, dt, fuel_on, length, half_width, max_range):
    """Run the step's ticks tick0..ticks-1 from stage `first` of tick tick0 on the World state
    `st`, its scratch copy `snap` and the arrays of address table `t` (`TABLE`); returns the
    first stage left to Python (its inputs complete, its outputs not; status[0] = its tick), or
    DONE when the step is over (status[0] = its last tick).

    CONTROLS: the learner's controls from its sensor row before the tick (`tick_controls`).
    TRAFFIC: the traffic cars' controls, compiled (`traffic_tick`) or Python's (`traffic`).
    STEP: `world_tick.step_world` on u_tick, the tick's copy of the controls; steps[0] = its
      answer. Stops on a non-finite control or something near (after sub-step steps[0]).
    SENSE: `sensor_kernel` into flat (N, 79), the focus cooldowns and readings due; stops when
      not `plain` (noise to apply; due (N,) says which cars get a focus reading).
    OUTCOME: the contact flags hits = wall | car, then `tick_outcome` (its answer, the learners
      still running, in status[1]); stops first when a reward or done is `python`.
    NEXT: status[1] == 0 ends the step; else on to the next tick.
    At the end the learner's observation (`observe_rows`) goes into obs (1, size) float32.
    ts, manual: the action map's modes; normalise: the observation's. The scalars: the World's
    sub-steps per tick and sub-step (s), fuel flag and track length (m), the track's half width
    and the sensors' range (m). It allocates nothing but the table's views."""
    u = f8_matrix(t, U)
    n = u.shape[0]
    status = i8_vector(t, STATUS)
    slot0, rows, flat = i8_vector(t, SLOT0), i8_vector(t, ROWS), f8_matrix(t, FLAT)
    race_pos = i8_vector(t, RACE_POS)
    stage = first
    for k in range(tick0, ticks):
        status[0] = k
        if stage <= CONTROLS:
            tick_controls(slot0, rows, flat, f8_matrix(t, PREV), ts, manual, f8_matrix(t, SAB),
                          f8_vector(t, GEAR), f8_matrix(t, PID_STATE), f8_vector(t, PID_PARAMS),
                          b1_vector(t, PID_FRESH), f8_vector(t, LANE_DES), f8_vector(t, SPEED_DES),
                          f8_matrix(t, OUT4), u)
            if traffic == COMPILED_TRAFFIC:
                traffic_tick(flat, u, i8_vector(t, T_ROWS), i8_vector(t, T_KIND), f8_matrix(t, T_S),
                             f8_matrix(t, T_P), f8_matrix(t, T_LANES), f8_matrix(t, T_RAND))
            elif traffic == PYTHON_TRAFFIC:
                return TRAFFIC
        if stage <= STEP:
            near, steps = i8_vector(t, NEAR), i8_vector(t, STEPS)
            bp = (readonly(f8_matrix(t, BP_GEO)), f8_matrix(t, BP_BAR), f8_matrix(t, BP_CARS),
                  f8_vector(t, BP_PRM), f8_matrix(t, BP_WALL), f8_matrix(t, BP_VREF),
                  i8_matrix(t, BP_PAIRS), i8_vector(t, BP_META), i1_vector(t, BP_FLAGS),
                  f8_vector(t, BP_SLACK))
            # the tick's own copy of the controls: a shift's throttle cap writes into it
            u_tick = f8_matrix(t, U_TICK)
            for i in range(n):
                for j in range(u.shape[1]):
                    u_tick[i, j] = u[i, j]
            steps[0] = step_world(u_tick, nsub, st, f8_matrix(t, CP), f8_matrix(t, CURVE_W),
                                  f8_matrix(t, CURVE_T), f8_matrix(t, PT), f8_matrix(t, SURF),
                                  f8_vector(t, TSC), dt, fuel_on, length, i8_vector(t, INFO),
                                  f8_vector(t, X), f8_vector(t, Y), f8_vector(t, YAW),
                                  i8_vector(t, PIECE), bp, near, snap, f8_vector(t, PATH),
                                  f8_vector(t, TURN), b1_vector(t, WALL), b1_vector(t, CAR),
                                  race_pos)
            if steps[0] < 0 or near[0] != 0:
                return STEP
        if stage <= SENSE:
            cars, due = i8_vector(t, CARS), b1_vector(t, DUE)
            requested, next_allowed = f8_vector(t, REQUESTED), f8_vector(t, NEXT_ALLOWED)
            earliest = f8_vector(t, EARLIEST)
            geo, runs = readonly(f8_matrix(t, GEO)), readonly(f8_matrix(t, RUNS))
            piece_run = readonly(i8_vector(t, PIECE_RUN))
            sensor_kernel(cars, st, geo, runs, piece_run, half_width, f8_matrix(t, ANGLES),
                          race_pos, f8_vector(t, ORIGIN), b1_vector(t, ACTIVE), max_range, flat)
            count = 0
            if st[0, S_TIME] >= earliest[0]:        # one clock for all cars
                time_s, on_track = f8_vector(t, TIME_S), b1_vector(t, ON_TRACK)
                for c in range(cars.shape[0]):
                    time_s[c] = st[cars[c], S_TIME]
                    on_track[c] = abs(flat[c, O_TPOS]) <= 1.0
                count = focus_due(cars, time_s, on_track, requested, next_allowed, earliest, due)
            if not plain:                           # noise: Python finishes the frame
                if count == 0:
                    due[:] = False
                return SENSE
            if count > 0:
                focus_kernel(cars, st, due, requested, geo, length, runs, piece_run, half_width,
                             max_range, flat)
        if stage <= OUTCOME:
            hits, wall, car = b1_vector(t, HITS), b1_vector(t, WALL), b1_vector(t, CAR)
            for i in range(n):
                hits[i] = wall[i] or car[i]
            if python:
                return OUTCOME
            status[1] = tick_outcome(
                i8_vector(t, R_CODES), f8_tensor(t, R_PAR), f8_tensor(t, R_STATE),
                i8_vector(t, D_CODES), f8_tensor(t, D_PAR), f8_tensor(t, D_STATE),
                f8_vector(t, WEIGHTS), b1_vector(t, IS_TRUNC), i8_vector(t, RUNNING), slot0, rows,
                flat, hits, f8_vector(t, TRACK_LENGTH), f8_matrix(t, PREV), f8_matrix(t, CUR),
                f8_vector(t, LENGTH), b1_vector(t, COLLISION), f8_matrix(t, R_VALS),
                f8_matrix(t, D_VALS), k == 0, f8_vector(t, TOTAL), f8_matrix(t, TERMS),
                i8_vector(t, TICKS), b1_vector(t, TERM), b1_vector(t, TRUNC), b1_matrix(t, FIRED),
                u)
        stage = CONTROLS
        if status[1] == 0:
            break
    observe_rows(flat, rows, i8_vector(t, WIRE_INDEX), f8_vector(t, SCALE), f8_vector(t, LOW),
                 f8_vector(t, HIGH), normalise, f8_vector(t, GAIN), f8_vector(t, OFFSET),
                 f4_matrix(t, OBS), slot0)
    return DONE


class EnvTick:
    """One episode's compiled step for one learner on a LocalBackend's World: the buffers
    `env_tick` reads and writes and the call. `MadrasCore` builds one at each reset (the
    World's, the suite's and the agent's arrays may be new ones) and does the stages the call
    leaves to Python.

    `flat` (N, 79) holds the latest sensors (the episode's frame is a view of it), `u_tick` the
    controls the World ran the last tick on, `obs` (1, size) the learner's observation after the
    last call, `status` [tick, learners still running]."""

    def __init__(self, world, suite, controls: np.ndarray, agent, builder, first: np.ndarray,
                 fleet, traffic_rows: np.ndarray):
        n = world.n_cars
        self.world, self.suite, self.agent = world, suite, agent
        self.u = controls
        self.u_tick = np.zeros_like(controls)
        self.steps = np.zeros(1, dtype=np.int64)
        self.cars = np.arange(n, dtype=np.int64)
        self.flat = np.array(first, dtype=np.float64, order="C")
        self.due = np.zeros(n, dtype=np.bool_)
        self.hits = np.zeros(n, dtype=np.bool_)
        self.obs = np.zeros((1, builder.size), dtype=np.float32)
        self.status = np.zeros(2, dtype=np.int64)
        self._scratch = (np.zeros(n), np.zeros(n, dtype=np.bool_))      # time_s, on_track
        self._slot0 = np.zeros(1, dtype=np.int64)
        self.builder = builder
        self.normalise = bool(builder.normalise)
        self.plain = not suite.noisy
        a = agent.actions
        self.ts, self.manual = bool(a.ts), bool(a.manual)
        self.python = agent.python
        self.fleet, self.traffic_rows = fleet, np.ascontiguousarray(traffic_rows, dtype=np.int64)
        self.traffic = (NO_TRAFFIC if self.traffic_rows.size == 0 else
                        COMPILED_TRAFFIC if fleet.compiled_only() else PYTHON_TRAFFIC)
        self._world_args = None
        self._set_args()

    def _set_args(self) -> None:
        """The address table and scalars of `env_tick`, built again when the World's arguments
        are a new tuple (its contact solver replaced an array)."""
        w = self.world.tick_args
        if w is self._world_args:
            return
        self._world_args = w
        geo, runs, piece_run, half, angles, race_pos, origin, active, max_range, *focus = \
            self.suite.kernel_args()
        ag = self.agent
        ctl, sc = ag.actions.controller, ag.scratch
        rw, dn = ag.rewards, ag.dones
        arrays = (self.u, self.u_tick, self.steps, *w[1:7], *w[10:15], *w[15], w[16], *w[18:],
                  self.cars, geo, runs, piece_run, angles, origin, active, *focus, self.due,
                  self.flat, *self._scratch, self.hits, self._slot0, ag.rows, ag.actions.sab,
                  ag.actions.gear, ctl.state, ctl.params, ctl.fresh, ctl.lane_des,
                  ctl.speed_des_kmh, sc.prev, sc.controls, rw.codes, rw.par, rw.state, dn.codes,
                  dn.par, dn.state, ag.weights, ag.is_trunc, ag.running, ag.track_length, sc.cur,
                  sc.length, sc.collision, sc.r_vals, sc.d_vals, ag.total, ag.terms, ag.ticks,
                  ag.term, ag.trunc, ag.fired, *self.builder.kernel_args(), self.obs, self.status,
                  self.traffic_rows, self.fleet.kind, self.fleet.S, self.fleet.P, self.fleet.lanes,
                  self.fleet.rand)
        self._arrays = arrays             # alive as long as the table is used
        self.args = (w[0], w[17], address_table(arrays, TABLE), w[7], w[8], w[9], half, max_range)

    def run(self, first: int, tick0: int, ticks: int) -> int:
        """Stages from `first` of tick `tick0` to the end of the step (`ticks` ticks); returns
        the stage left to Python (status[0]: its tick) or DONE."""
        return env_tick(first, tick0, ticks, self.traffic, self.python, self.plain, self.ts,
                        self.manual, self.normalise, SUBSTEPS, *self.args)

    def finish_step(self) -> None:
        """The STEP stage in Python: the pymunk narrow phase (or World.step's handling of a
        non-finite control), then the table again if the World replaced an array."""
        if self.steps[0] >= 0:
            self.world.finish_tick(self.u_tick, SUBSTEPS, int(self.steps[0]))
        else:
            self.world.step(self.u)
        self._set_args()
