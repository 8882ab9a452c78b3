"""A one-learner env step as one compiled call: the action checked, clipped and taken, then for
each tick of the step the learner's controls -> the World advanced one tick -> every car's
sensors -> the learner's rewards and dones, then its observation. The Python around it only
hands the action in and the results out.

The stages are the kernels every other door runs (`action_kernel.clip_actions` and
`learner_kernel.begin_step`, `tick_controls` and `tick_outcome`, `world_tick.step_world`,
`sensors.sensor_kernel`, `focus_due` and `focus_kernel`, `learner_kernel.observe_rows`), in the
order `MadrasCore.step` calls them
one by one, so a step gives the same bits either way (tests/envs/test_env_tick.py). Whatever a
stage cannot finish compiled stops the call at that stage and is done by `MadrasCore`'s Python
path of the same stage, which then goes on: the traffic cars' controls (`TrafficFleet.act`),
something near a car (the pymunk narrow phase, `World.finish_tick`), sensor noise, a reward or
done written in Python. Action noise (drawn from a numpy Generator) is added in Python, and
that step's call starts at CONTROLS. (The SCR server's tick is built the same way:
`madsim.net.server_tick`.)
"""

from __future__ import annotations

import numba
import numpy as np

from madsim.facts import SUBSTEPS_PER_TICK as SUBSTEPS
from madsim.agents.action_kernel import clip_actions
from madsim.agents.learner_kernel import begin_step, observe_rows, tick_controls, tick_outcome
from madsim.agents.traffic_kernel import traffic_tick
from madsim.array_table import (address_table, b1_matrix, b1_vector, f4_matrix, f8_matrix,
                                f8_tensor, f8_vector, i8_vector)
from madsim.physics.sensors import SENSOR_TABLE, SN_FLAT, sense_table, sensor_table_arrays
from madsim.physics.world_tick import (W_CAR, W_NEAR, W_RACE_POS, W_WALL, WORLD_TABLE, step_table,
                                       world_table_arrays)

ACTION, CONTROLS, TRAFFIC, STEP, SENSE, OUTCOME, NEXT, DONE = range(8)
"""A step's stages in order (ACTION once, then the tick's; NEXT: after the outcome, on to the
next tick); `env_tick` returns the one Python must do, or DONE (ACTION: a non-finite action)."""
NO_TRAFFIC, COMPILED_TRAFFIC, PYTHON_TRAFFIC = range(3)
"""flags[F_TRAFFIC]: none; built-in behaviours that draw nothing and report nothing
(`traffic_kernel.traffic_tick` in the call); others (the fleet's `act` in Python)."""

# The arrays `env_tick` reads, in the order of its address table (`madsim.array_table`): name,
# dtype, dimensions, memory order. From row W0 the World's (`world_tick.WORLD_TABLE`), from row S0
# the sensors' (`sensors.SENSOR_TABLE`); then the learner's: the action handed in, its checked
# copy, the Box, its action map, component batches and step arrays
# (madsim.envs.core), its observation's, the traffic fleet's.
_OWN_FIRST = (("controls", "f8", 2, "C"), ("u_tick", "f8", 2, "C"), ("steps", "i8", 1, "C"),
              ("hits", "b1", 1, "C"), ("status", "i8", 1, "C"), ("flags", "i8", 1, "C"),
              ("scalars", "f8", 1, "C"))
F_TRAFFIC, F_PYTHON, F_PLAIN, F_TS, F_MANUAL, F_NORMALISE, F_NSUB, F_FUEL, F_ACT_NORMALISED, \
    F_COMPAT = range(10)
"""`flags`: traffic (NO_TRAFFIC...), a Python reward or done, no sensor noise, the action map's
T-S, manual gear, the observation normalised, sub-steps per tick, fuel on, the actions
normalised, the PID's MADRaS-compatible mode."""
X_DT, X_LENGTH, X_HALF, X_RANGE, X_LANE_LOW, X_LANE_HIGH = range(6)
"""`scalars`: sub-step (s), track length (m), half width (m), sensor range (m), the T-S lane
limits (track position)."""
_LEARNER = (
    ("action", "f8", 2, "C"), ("chosen", "f8", 2, "C"), ("a_low", "f8", 1, "C"),
    ("a_high", "f8", 1, "C"), ("target_speed", "f8", 1, "C"), ("slot0", "i8", 1, "C"), ("rows", "i8", 1, "C"), ("sab", "f8", 2, "C"), ("gear", "f8", 1, "C"),
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
    ("obs", "f4", 2, "C"),
    ("traffic_rows", "i8", 1, "C"), ("traffic_kind", "i8", 1, "C"), ("traffic_s", "f8", 2, "C"),
    ("traffic_p", "f8", 2, "C"), ("traffic_lanes", "f8", 2, "C"), ("traffic_rand", "f8", 2, "C"),
)
TABLE = _OWN_FIRST + WORLD_TABLE + SENSOR_TABLE + _LEARNER
U, U_TICK, STEPS, HITS, STATUS, FLAGS, SCALARS = (
    np.int64(k) for k in range(len(_OWN_FIRST)))
W0 = np.int64(len(_OWN_FIRST))
S0 = np.int64(W0 + len(WORLD_TABLE))
(ACT, CHOSEN, A_LOW, A_HIGH, TARGET_SPEED, SLOT0, ROWS, SAB, GEAR, PID_STATE, PID_PARAMS,
 PID_FRESH, LANE_DES, SPEED_DES, PREV, OUT4, R_CODES,
 R_PAR, R_STATE, D_CODES, D_PAR, D_STATE, WEIGHTS, IS_TRUNC, RUNNING, TRACK_LENGTH, CUR, LENGTH,
 COLLISION, R_VALS, D_VALS, TOTAL, TERMS, TICKS, TERM, TRUNC, FIRED, WIRE_INDEX, SCALE, LOW, HIGH,
 GAIN, OFFSET, OBS, T_ROWS, T_KIND, T_S, T_P, T_LANES, T_RAND) = (
    np.int64(S0 + len(SENSOR_TABLE) + k) for k in range(len(_LEARNER)))
FLAT, RACE_POS, NEAR = S0 + SN_FLAT, W0 + W_RACE_POS, W0 + W_NEAR
WALL, CAR = W0 + W_WALL, W0 + W_CAR
# int64 row numbers, not int literals: see array_table's views


@numba.njit(cache=True, error_model="numpy")
def env_tick(first, tick0, ticks, st, snap, t):
    """Run the step's ticks tick0..ticks-1 from stage `first` of tick tick0 on the World state
    `st`, its scratch copy `snap` and the arrays of address table t (`TABLE`); returns the
    first stage left to Python (its inputs complete, its outputs not; status[0] = its tick), or
    DONE when the step is over (status[0] = its last tick).

    ACTION (before tick 0): the action (1, dim) clipped into [a_low, a_high] as `chosen`
      (`clip_actions`; a non-finite one stops here, status[0] = its index, nothing changed),
      taken and the step's outcome cleared (`begin_step`).
    CONTROLS: the learner's controls from its sensor row before the tick (`tick_controls`).
    TRAFFIC: the traffic cars' controls, compiled (`traffic_tick`) or Python's (`traffic`).
    STEP: `world_tick.step_table` (`step_world` on u_tick, the tick's copy of the controls);
      steps[0] = its answer. Stops on a non-finite control or something near (after sub-step
      steps[0]).
    SENSE: `sensors.sense_table` (`sensor_kernel` into flat (N, 79), the focus cooldowns and
      readings due); stops when not plain (noise to apply; due (N,) says which cars get a
      focus reading).
    OUTCOME: the contact flags hits = wall | car, then `tick_outcome` (its answer, the learners
      still running, in status[1]); stops first when a reward or done is Python.
    NEXT: status[1] == 0 ends the step; else on to the next tick.
    At the end the learner's observation (`observe_rows`) goes into obs (1, size) float32. The
    modes and scalars are the rows flags (F_*) and scalars (X_*). It allocates nothing but the table's views."""
    flags, x = i8_vector(t, FLAGS), f8_vector(t, SCALARS)
    traffic, python, plain = flags[F_TRAFFIC], flags[F_PYTHON] != 0, flags[F_PLAIN] != 0
    ts, manual, normalise = flags[F_TS] != 0, flags[F_MANUAL] != 0, flags[F_NORMALISE] != 0
    nsub, fuel_on = flags[F_NSUB], flags[F_FUEL] != 0
    dt, length, half_width, max_range = x[X_DT], x[X_LENGTH], x[X_HALF], x[X_RANGE]
    u = f8_matrix(t, U)
    n = u.shape[0]
    status = i8_vector(t, STATUS)
    slot0, rows, flat = i8_vector(t, SLOT0), i8_vector(t, ROWS), f8_matrix(t, FLAT)
    race_pos = i8_vector(t, RACE_POS)
    total, tick_counts, term, trunc = (f8_vector(t, TOTAL), i8_vector(t, TICKS),
                                       b1_vector(t, TERM), b1_vector(t, TRUNC))
    terms, fired, running = f8_matrix(t, TERMS), b1_matrix(t, FIRED), i8_vector(t, RUNNING)
    stage = first
    if stage == ACTION:
        chosen = f8_matrix(t, CHOSEN)
        bad = clip_actions(f8_matrix(t, ACT), f8_vector(t, A_LOW), f8_vector(t, A_HIGH), chosen)
        if bad >= 0:
            status[0] = bad
            return ACTION
        begin_step(slot0, chosen, ts, flags[F_ACT_NORMALISED] != 0, manual, flags[F_COMPAT] != 0,
                   x[X_LANE_LOW], x[X_LANE_HIGH], f8_vector(t, TARGET_SPEED), f8_matrix(t, SAB),
                   f8_vector(t, GEAR), f8_vector(t, LANE_DES), f8_vector(t, SPEED_DES), total,
                   tick_counts, term, trunc, fired, running)
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
            steps = i8_vector(t, STEPS)
            steps[0] = step_table(u, f8_matrix(t, U_TICK), nsub, st, snap, t, W0, dt, fuel_on, length)
            if steps[0] < 0 or i8_vector(t, NEAR)[0] != 0:
                return STEP
        if stage <= SENSE:
            if not sense_table(st, t, S0, race_pos, length, half_width, max_range, plain):
                return SENSE                        # noise: Python finishes the frame
        if stage <= OUTCOME:
            hits, wall, car = b1_vector(t, HITS), b1_vector(t, WALL), b1_vector(t, CAR)
            for i in range(n):
                hits[i] = wall[i] or car[i]
            if python:
                return OUTCOME
            status[1] = tick_outcome(
                i8_vector(t, R_CODES), f8_tensor(t, R_PAR), f8_tensor(t, R_STATE),
                i8_vector(t, D_CODES), f8_tensor(t, D_PAR), f8_tensor(t, D_STATE),
                f8_vector(t, WEIGHTS), b1_vector(t, IS_TRUNC), running, slot0, rows,
                flat, hits, f8_vector(t, TRACK_LENGTH), f8_matrix(t, PREV), f8_matrix(t, CUR),
                f8_vector(t, LENGTH), b1_vector(t, COLLISION), f8_matrix(t, R_VALS),
                f8_matrix(t, D_VALS), k == 0, total, terms, tick_counts, term, trunc, fired, u)
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
    controls the World ran the last tick on, `obs_row` (size,) the learner's observation after
    the last call, `status` [tick, learners still running], `action_row` (dim,) the action a
    call from ACTION takes (`fused`: the learner draws no action noise, so a step may start
    there)."""

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
        self.obs_row = self.obs[0]
        self.status = np.zeros(2, dtype=np.int64)
        self._scratch = (np.zeros(n), np.zeros(n, dtype=np.bool_))      # time_s, on_track
        self._slot0 = np.zeros(1, dtype=np.int64)
        self.builder = builder
        a = agent.actions
        self.action = np.zeros((1, a.dim))
        self.action_row = self.action[0]
        self.fused = agent.noise_std == 0.0
        if self.fused:
            agent.action = agent.chosen[0]          # what a Python reward is handed
        self.fleet, self.traffic_rows = fleet, np.ascontiguousarray(traffic_rows, dtype=np.int64)
        traffic = (NO_TRAFFIC if self.traffic_rows.size == 0 else
                   COMPILED_TRAFFIC if fleet.compiled_only() else PYTHON_TRAFFIC)
        self.flags = np.zeros(10, dtype=np.int64)
        f = self.flags
        f[F_TRAFFIC], f[F_PYTHON], f[F_PLAIN] = traffic, agent.python, not suite.noisy
        f[F_TS], f[F_MANUAL], f[F_NORMALISE] = a.ts, a.manual, builder.normalise
        f[F_NSUB], f[F_ACT_NORMALISED], f[F_COMPAT] = SUBSTEPS, a.normalised, a.controller.compat
        self.scalars = np.zeros(6)
        self.scalars[X_LANE_LOW], self.scalars[X_LANE_HIGH] = a.controller.low, a.controller.high
        self._world_args = None
        self._set_args()

    def _set_args(self) -> None:
        """The address table of `env_tick`, built again when the World's arguments are a new
        tuple (its contact solver replaced an array)."""
        w = self.world.tick_args
        if w is self._world_args:
            return
        self._world_args = w
        _, _, _, half, _, _, _, _, max_range, *_ = self.suite.kernel_args()
        self.flags[F_FUEL] = w[8]
        x = self.scalars
        x[X_DT], x[X_LENGTH], x[X_HALF], x[X_RANGE] = w[7], w[9], half, max_range
        ag = self.agent
        ctl, sc = ag.actions.controller, ag.scratch
        rw, dn, fleet = ag.rewards, ag.dones, self.fleet
        arrays = (self.u, self.u_tick, self.steps, self.hits, self.status, self.flags, x,
                  *world_table_arrays(w),
                  *sensor_table_arrays(self.suite, self.cars, self.due, self.flat, self._scratch),
                  self.action, ag.chosen, ag.actions.low, ag.actions.high, ctl.target_speed,
                  self._slot0, ag.rows, ag.actions.sab, ag.actions.gear, ctl.state,
                  ctl.params, ctl.fresh, ctl.lane_des, ctl.speed_des_kmh, sc.prev, sc.controls,
                  rw.codes, rw.par, rw.state, dn.codes, dn.par, dn.state, ag.weights, ag.is_trunc,
                  ag.running, ag.track_length, sc.cur, sc.length, sc.collision, sc.r_vals,
                  sc.d_vals, ag.total, ag.terms, ag.ticks, ag.term, ag.trunc, ag.fired,
                  *self.builder.kernel_args(), self.obs, self.traffic_rows, fleet.kind, fleet.S,
                  fleet.P, fleet.lanes, fleet.rand)
        self._arrays = arrays             # alive as long as the table is used
        self.args = (w[0], w[17], address_table(arrays, TABLE))     # state, snap, table

    def run(self, first: int, tick0: int, ticks: int) -> int:
        """Stages from `first` of tick `tick0` to the end of the step (`ticks` ticks); returns
        the stage left to Python (status[0]: its tick) or DONE."""
        return env_tick(first, tick0, ticks, *self.args)

    def finish_step(self) -> None:
        """The STEP stage in Python: the pymunk narrow phase (or World.step's handling of a
        non-finite control), then the table again if the World replaced an array."""
        if self.steps[0] >= 0:
            self.world.finish_tick(self.u_tick, SUBSTEPS, int(self.steps[0]))
        else:
            self.world.step(self.u)
        self._set_args()
