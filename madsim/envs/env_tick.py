"""An env step of every learner as one compiled call: the actions checked, clipped and taken,
then for each tick of the step each learner's controls -> the World advanced one tick -> every
car's sensors -> each learner's rewards and dones, then the observations. The Python around it
only hands the actions in and the results out.

The stages are the kernels every other door runs (`action_kernel.clip_actions` and
`learner_kernel.begin_step`, `tick_controls` and `tick_outcome`, `world_tick.step_world`,
`sensors.sensor_kernel`, `focus_due` and `focus_kernel`, `learner_kernel.observe_rows`), in the
order `MadrasCore.step` calls them
one by one, so a step gives the same bits either way (tests/envs/test_env_tick.py). Whatever a
stage cannot finish compiled stops the call at that stage and is done by `MadrasCore`'s Python
path of the same stage, which then goes on: the messages of communication (`CommHub.send`),
the traffic cars' controls (`TrafficFleet.act`), sensor noise, a reward or done written in
Python, and the rare contact consultation that needs Python (`World.finish_tick`: a car entering
or leaving the pymunk space, a buffer to grow); the usual one is compiled too
(`world_tick.contact_direct`: pymunk's C functions called by address, `physics.pymunk_direct`;
World.contact_pairs is then not refreshed, as after a tick without contact). Action noise (drawn
from a numpy Generator) is added in Python, and that step's call starts at CONTROLS. (The SCR
server's tick is built the same way: `madsim.net.server_tick`.)

The learners are a block of the address table each (`_LEARNER`, learner j's rows from
L0 + j * NL): one learner's arrays as its `_StageAgent` holds them, each learner with its own
action space, controller, rewards, dones and observation.
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
from madsim.physics.pymunk_direct import NARROW_TABLE
from madsim.physics.world_tick import (TICK_DONE, W_CAR, W_NEAR, W_RACE_POS, W_WALL, WORLD_TABLE,
                                       contact_direct, step_table, world_table_arrays)

ACTION, COMM, CONTROLS, TRAFFIC, STEP, SENSE, OUTCOME, NEXT, DONE = range(9)
"""A step's stages in order (ACTION and COMM once, then the tick's; NEXT: after the outcome, on
to the next tick); `env_tick` returns the one Python must do, or DONE (ACTION: a non-finite
action)."""
NO_TRAFFIC, COMPILED_TRAFFIC, PYTHON_TRAFFIC = range(3)
"""flags[F_TRAFFIC]: none; built-in behaviours that draw nothing and report nothing
(`traffic_kernel.traffic_tick` in the call); others (the fleet's `act` in Python)."""
NO_END, EPISODE_END, SERVER_END = range(3)
"""A learner's `why`: its step ended by one of its dones or not at all; by another learner's
done (server.episode_end "any"); by the server (Python only)."""

# The arrays `env_tick` reads, in the order of its address table (`madsim.array_table`): name,
# dtype, dimensions, memory order. From row W0 the World's (`world_tick.WORLD_TABLE`), from row S0
# the sensors' (`sensors.SENSOR_TABLE`); from row L0 a block per learner: the action handed in,
# its checked copy, the Box, its action map, component batches and step arrays
# (madsim.envs.core._StageAgent), its observation's.
_OWN_FIRST = (("controls", "f8", 2, "C"), ("u_tick", "f8", 2, "C"), ("steps", "i8", 1, "C"),
              ("hits", "b1", 1, "C"), ("status", "i8", 1, "C"), ("flags", "i8", 1, "C"),
              ("scalars", "f8", 1, "C"), ("live", "i8", 1, "C"), ("going", "i8", 1, "C"),
              ("traffic_rows", "i8", 1, "C"), ("traffic_kind", "i8", 1, "C"),
              ("traffic_s", "f8", 2, "C"), ("traffic_p", "f8", 2, "C"),
              ("traffic_lanes", "f8", 2, "C"), ("traffic_rand", "f8", 2, "C"))
F_TRAFFIC, F_PLAIN, F_NSUB, F_FUEL, F_TOGETHER, F_COMM, F_DIRECT, F_DAMAGE = range(8)
"""`flags`: traffic (NO_TRAFFIC...), no sensor noise, sub-steps per tick, fuel on, the first
done ends every learner's step (server.episode_end "any"), communication (stop at COMM),
contact ticks finished in the call (`world_tick.contact_direct`: the World has a contact
solver), damage on."""
X_DT, X_LENGTH, X_HALF, X_RANGE = range(4)
"""`scalars`: sub-step (s), track length (m), half width (m), sensor range (m)."""
ST_TICK, ST_RUNNING, ST_LEARNER, ST_ANSWER, ST_ENDED = range(5)
"""`status`: the tick (ACTION: the non-finite value's index), the learners still running, the
learner of the stage left to Python (ACTION, OUTCOME; else -1), the answer of its Python
outcome (learners still running, 0 or 1), the learners that ended in this tick."""
M_TS, M_MANUAL, M_NORMALISE, M_ACT_NORMALISED, M_COMPAT, M_PYTHON = range(6)
"""A learner's `modes`: the action map's T-S, manual gear, the observation normalised, the
actions normalised, the PID's MADRaS-compatible mode, a Python reward or done."""
_LEARNER = (
    ("modes", "i8", 1, "C"), ("lane_limits", "f8", 1, "C"), ("why", "i8", 1, "C"),
    ("action", "f8", 2, "C"), ("chosen", "f8", 2, "C"), ("a_low", "f8", 1, "C"),
    ("a_high", "f8", 1, "C"), ("target_speed", "f8", 1, "C"), ("slot0", "i8", 1, "C"),
    ("rows", "i8", 1, "C"), ("sab", "f8", 2, "C"), ("gear", "f8", 1, "C"),
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
)


def table_spec(learners: int) -> tuple:
    """`env_tick`'s address table spec for a step of `learners` learners (the contact
    solver's `NARROW_TABLE` last, at row L0 + learners * NL)."""
    return _OWN_FIRST + WORLD_TABLE + SENSOR_TABLE + _LEARNER * learners + NARROW_TABLE


(U, U_TICK, STEPS, HITS, STATUS, FLAGS, SCALARS, LIVE, GOING, T_ROWS, T_KIND, T_S, T_P, T_LANES,
 T_RAND) = (np.int64(k) for k in range(len(_OWN_FIRST)))
W0 = np.int64(len(_OWN_FIRST))
S0 = np.int64(W0 + len(WORLD_TABLE))
L0 = np.int64(S0 + len(SENSOR_TABLE))
NL = np.int64(len(_LEARNER))
(MODES, LANE_LIMITS, WHY, ACT, CHOSEN, A_LOW, A_HIGH, TARGET_SPEED, SLOT0, ROWS, SAB, GEAR,
 PID_STATE, PID_PARAMS, PID_FRESH, LANE_DES, SPEED_DES, PREV, OUT4, R_CODES, R_PAR, R_STATE,
 D_CODES, D_PAR, D_STATE, WEIGHTS, IS_TRUNC, RUNNING, TRACK_LENGTH, CUR, LENGTH, COLLISION, R_VALS,
 D_VALS, TOTAL, TERMS, TICKS, TERM, TRUNC, FIRED, WIRE_INDEX, SCALE, LOW, HIGH, GAIN, OFFSET,
 OBS) = (np.int64(k) for k in range(len(_LEARNER)))
"""Rows of a learner's block, from its first row b = L0 + j * NL."""
FLAT, RACE_POS, NEAR = S0 + SN_FLAT, W0 + W_RACE_POS, W0 + W_NEAR
WALL, CAR = W0 + W_WALL, W0 + W_CAR
# int64 row numbers, not int literals: see array_table's views


@numba.njit(cache=True)
def _clip(t, b):
    """Learner b's action clipped into its Box as `chosen`; the non-finite index or -1."""
    return clip_actions(f8_matrix(t, b + ACT), f8_vector(t, b + A_LOW), f8_vector(t, b + A_HIGH),
                        f8_matrix(t, b + CHOSEN))


@numba.njit(cache=True)
def _begin(t, b):
    """Learner b takes its checked action; its step's outcome cleared."""
    md, lane = i8_vector(t, b + MODES), f8_vector(t, b + LANE_LIMITS)
    begin_step(i8_vector(t, b + SLOT0), f8_matrix(t, b + CHOSEN), md[M_TS] != 0,
               md[M_ACT_NORMALISED] != 0, md[M_MANUAL] != 0, md[M_COMPAT] != 0, lane[0], lane[1],
               f8_vector(t, b + TARGET_SPEED), f8_matrix(t, b + SAB), f8_vector(t, b + GEAR),
               f8_vector(t, b + LANE_DES), f8_vector(t, b + SPEED_DES), f8_vector(t, b + TOTAL),
               i8_vector(t, b + TICKS), b1_vector(t, b + TERM), b1_vector(t, b + TRUNC),
               b1_matrix(t, b + FIRED), i8_vector(t, b + RUNNING))
    i8_vector(t, b + WHY)[0] = NO_END


@numba.njit(cache=True)
def _controls(t, b, flat, u):
    """Learner b's controls of the coming tick into u (`tick_controls`)."""
    md = i8_vector(t, b + MODES)
    tick_controls(i8_vector(t, b + SLOT0), i8_vector(t, b + ROWS), flat, f8_matrix(t, b + PREV),
                  md[M_TS] != 0, md[M_MANUAL] != 0, f8_matrix(t, b + SAB), f8_vector(t, b + GEAR),
                  f8_matrix(t, b + PID_STATE), f8_vector(t, b + PID_PARAMS),
                  b1_vector(t, b + PID_FRESH), f8_vector(t, b + LANE_DES),
                  f8_vector(t, b + SPEED_DES), f8_matrix(t, b + OUT4), u)


@numba.njit(cache=True)
def _outcome(t, b, flat, hits, first, u):
    """Learner b's built-in rewards and dones of the tick (`tick_outcome`): 1 while it runs."""
    return tick_outcome(
        i8_vector(t, b + R_CODES), f8_tensor(t, b + R_PAR), f8_tensor(t, b + R_STATE),
        i8_vector(t, b + D_CODES), f8_tensor(t, b + D_PAR), f8_tensor(t, b + D_STATE),
        f8_vector(t, b + WEIGHTS), b1_vector(t, b + IS_TRUNC), i8_vector(t, b + RUNNING),
        i8_vector(t, b + SLOT0), i8_vector(t, b + ROWS), flat, hits,
        f8_vector(t, b + TRACK_LENGTH), f8_matrix(t, b + PREV), f8_matrix(t, b + CUR),
        f8_vector(t, b + LENGTH), b1_vector(t, b + COLLISION), f8_matrix(t, b + R_VALS),
        f8_matrix(t, b + D_VALS), first, f8_vector(t, b + TOTAL), f8_matrix(t, b + TERMS),
        i8_vector(t, b + TICKS), b1_vector(t, b + TERM), b1_vector(t, b + TRUNC),
        b1_matrix(t, b + FIRED), u)


@numba.njit(cache=True)
def _episode_end(t, b, u):
    """Learner b's step ended by another's done: terminated, its car given the stop controls
    (steer 0, accel 0, brake 1, clutch 0), as `_StageAgent.end`."""
    b1_vector(t, b + TERM)[0], b1_vector(t, b + TRUNC)[0] = True, False
    i8_vector(t, b + WHY)[0] = EPISODE_END
    k = i8_vector(t, b + ROWS)[0]
    u[k, 0], u[k, 1], u[k, 2] = 0.0, 0.0, 1.0
    u[k, 4] = 0.0


@numba.njit(cache=True)
def _observe(t, b, flat):
    """Learner b's observation of the latest sensors into its obs (1, size) float32."""
    observe_rows(flat, i8_vector(t, b + ROWS), i8_vector(t, b + WIRE_INDEX),
                 f8_vector(t, b + SCALE), f8_vector(t, b + LOW), f8_vector(t, b + HIGH),
                 i8_vector(t, b + MODES)[M_NORMALISE] != 0, f8_vector(t, b + GAIN),
                 f8_vector(t, b + OFFSET), f4_matrix(t, b + OBS), i8_vector(t, b + SLOT0))


@numba.njit(cache=True, error_model="numpy")
def env_tick(first, tick0, ticks, st, snap, t):
    """Run the step's ticks tick0..ticks-1 from stage `first` of tick tick0 on the World state
    `st`, its scratch copy `snap` and the arrays of address table t (`table_spec`); returns the
    first stage left to Python (its inputs complete, its outputs not; status[ST_TICK] = its
    tick), or DONE when the step is over (status[ST_TICK] = its last tick).

    The learners stepped are those with live[j] (at the step's start); going[j] says which are
    still running in the step. Each stage takes them in order j = 0, 1, ...
    ACTION (before tick 0): every action (1, dim) clipped into [a_low, a_high] as `chosen`
      (`clip_actions`; the first non-finite one stops here, status = its index and learner,
      nothing changed), then each taken and the step's outcome cleared (`begin_step`).
    COMM: with communication, Python sends the messages (the sensors before the step, the
      checked actions).
    CONTROLS: each learner's controls from its sensor row before the tick (`tick_controls`).
    TRAFFIC: the traffic cars' controls, compiled (`traffic_tick`) or Python's (`traffic`).
    STEP: `world_tick.step_table` (`step_world` on u_tick, the tick's copy of the controls);
      steps[0] = its answer. Stops on a non-finite control or something near (after sub-step
      steps[0]).
    SENSE: `sensors.sense_table` (`sensor_kernel` into flat (N, 79), the focus cooldowns and
      readings due); stops when not plain (noise to apply; due (N,) says which cars get a
      focus reading).
    OUTCOME: the contact flags hits = wall | car, then each learner's `tick_outcome` (a Python
      reward or done: stops with status[ST_LEARNER] = the learner, resumed from OUTCOME with
      its answer in status[ST_ANSWER]); a learner that ended gets its observation now; with
      flags[F_TOGETHER] the first done ends the others' steps too (MADRaS's episode end).
    NEXT: no learner running ends the step; else on to the next tick.
    At the end each learner still running gets its observation (`observe_rows`) into its obs
    (1, size) float32, and live = going. The modes and scalars are the rows flags (F_*),
    scalars (X_*) and each learner's modes (M_*). It allocates nothing but the table's
    views."""
    flags, x = i8_vector(t, FLAGS), f8_vector(t, SCALARS)
    traffic, plain, nsub = flags[F_TRAFFIC], flags[F_PLAIN] != 0, flags[F_NSUB]
    fuel_on, together = flags[F_FUEL] != 0, flags[F_TOGETHER] != 0
    dt, length, half_width, max_range = x[X_DT], x[X_LENGTH], x[X_HALF], x[X_RANGE]
    u = f8_matrix(t, U)
    n = u.shape[0]
    status, live, going = i8_vector(t, STATUS), i8_vector(t, LIVE), i8_vector(t, GOING)
    m = live.shape[0]
    flat = f8_matrix(t, FLAT)
    race_pos = i8_vector(t, RACE_POS)
    stage = first
    status[ST_TICK] = tick0
    if stage == ACTION:
        for j in range(m):
            if live[j] != 0:
                bad = _clip(t, L0 + j * NL)
                if bad >= 0:
                    status[ST_TICK], status[ST_LEARNER] = bad, j
                    return ACTION
        for j in range(m):
            if live[j] != 0:
                _begin(t, L0 + j * NL)
        if flags[F_COMM] != 0:
            return COMM
    if stage <= CONTROLS:
        status[ST_LEARNER] = -1
        status[ST_RUNNING] = 0
        for j in range(m):
            going[j] = live[j]
            status[ST_RUNNING] += live[j]
    for k in range(tick0, ticks):
        status[ST_TICK] = k
        if stage <= CONTROLS:
            for j in range(m):
                if going[j] != 0:
                    _controls(t, L0 + j * NL, flat, u)
            if traffic == COMPILED_TRAFFIC:
                traffic_tick(flat, u, i8_vector(t, T_ROWS), i8_vector(t, T_KIND), f8_matrix(t, T_S),
                             f8_matrix(t, T_P), f8_matrix(t, T_LANES), f8_matrix(t, T_RAND))
            elif traffic == PYTHON_TRAFFIC:
                return TRAFFIC
        if stage <= STEP:
            steps = i8_vector(t, STEPS)
            u_tick = f8_matrix(t, U_TICK)
            steps[0] = step_table(u, u_tick, nsub, st, snap, t, W0, dt, fuel_on, length)
            if steps[0] < 0:
                return STEP
            if i8_vector(t, NEAR)[0] != 0:
                if flags[F_DIRECT] == 0:
                    return STEP
                k_sub = contact_direct(steps[0], nsub, u_tick, st, snap, t, W0, L0 + m * NL, dt,
                                       fuel_on, flags[F_DAMAGE] != 0)
                if k_sub != TICK_DONE:
                    steps[0] = k_sub
                    return STEP
        if stage <= SENSE:
            if not sense_table(st, t, S0, race_pos, length, half_width, max_range, plain):
                return SENSE                        # noise: Python finishes the frame
        if stage <= OUTCOME:
            hits = b1_vector(t, HITS)
            j0 = status[ST_LEARNER]
            if j0 < 0:                              # not resumed after a Python outcome
                j0 = 0
                status[ST_ENDED] = 0
                wall, car = b1_vector(t, WALL), b1_vector(t, CAR)
                for i in range(n):
                    hits[i] = wall[i] or car[i]
            for j in range(j0, m):
                if going[j] == 0:
                    continue
                b = L0 + j * NL
                if i8_vector(t, b + MODES)[M_PYTHON] != 0:
                    if status[ST_LEARNER] != j:
                        status[ST_LEARNER] = j
                        return OUTCOME
                    status[ST_LEARNER] = -1
                    left = status[ST_ANSWER]
                else:
                    left = _outcome(t, b, flat, hits, k == 0, u)
                if left == 0:
                    going[j] = 0
                    status[ST_ENDED] += 1
                    _observe(t, b, flat)
            if together and status[ST_ENDED] > 0:
                for j in range(m):      # MADRaS: the first done ends every learner's episode
                    if going[j] != 0:
                        going[j] = 0
                        _episode_end(t, L0 + j * NL, u)
                        _observe(t, L0 + j * NL, flat)
            status[ST_RUNNING] = 0
            for j in range(m):
                status[ST_RUNNING] += going[j]
        stage = CONTROLS
        if status[ST_RUNNING] == 0:
            break
    for j in range(m):
        if going[j] != 0:
            _observe(t, L0 + j * NL, flat)
        live[j] = going[j]
    return DONE


class EnvTick:
    """One episode's compiled step for its learners on a LocalBackend's World: the buffers
    `env_tick` reads and writes and the call. `MadrasCore` builds one at each reset (the
    World's, the suite's and the agents' arrays may be new ones) and does the stages the call
    leaves to Python.

    agents, builders: the learners (`_StageAgent`s) in the episode's order and their
    observation builders. `flat` (N, 79) holds the latest sensors (the episode's frame is a
    view of it), `u_tick` the controls the World ran the last tick on, `obs_rows[j]` (size,)
    learner j's observation after the last call, `action_rows[j]` (dim,) the action a call from
    ACTION takes, `live` (M,) the learners stepped (1) or gone (0), `status` (ST_*); `fused`: no
    learner draws action noise, so a step may start at ACTION."""

    def __init__(self, world, suite, controls: np.ndarray, agents, builders, first: np.ndarray,
                 fleet, traffic_rows: np.ndarray, *, together: bool = False, comm: bool = False):
        n = world.n_cars
        self.world, self.suite = world, suite
        self.agents, self.builders = list(agents), list(builders)
        self.m = len(self.agents)
        self.u = controls
        self.u_tick = np.zeros_like(controls)
        self.steps = np.zeros(1, dtype=np.int64)
        self.cars = np.arange(n, dtype=np.int64)
        self.flat = np.array(first, dtype=np.float64, order="C")
        self.due = np.zeros(n, dtype=np.bool_)
        self.hits = np.zeros(n, dtype=np.bool_)
        self.status = np.zeros(5, dtype=np.int64)
        self.status[ST_LEARNER] = -1
        self.live = np.ones(self.m, dtype=np.int64)
        self.going = np.zeros(self.m, dtype=np.int64)
        self._scratch = (np.zeros(n), np.zeros(n, dtype=np.bool_))      # time_s, on_track
        self._slot0 = np.zeros(1, dtype=np.int64)
        self.obs = [np.zeros((1, b.size), dtype=np.float32) for b in self.builders]
        self.obs_rows = [o[0] for o in self.obs]
        self.actions = [np.zeros((1, ag.actions.dim)) for ag in self.agents]
        self.action_rows = [a[0] for a in self.actions]
        self.fused = all(ag.noise_std == 0.0 for ag in self.agents)
        self.modes, self.lane_limits = [], []
        for ag, builder in zip(self.agents, self.builders):
            if self.fused:
                ag.action = ag.chosen[0]          # what a Python reward is handed
            a = ag.actions
            md = np.zeros(6, dtype=np.int64)
            md[M_TS], md[M_MANUAL], md[M_NORMALISE] = a.ts, a.manual, builder.normalise
            md[M_ACT_NORMALISED], md[M_COMPAT], md[M_PYTHON] = (a.normalised, a.controller.compat,
                                                              ag.python)
            self.modes.append(md)
            self.lane_limits.append(np.array([a.controller.low, a.controller.high],
                                             dtype=np.float64))
        self.fleet, self.traffic_rows = fleet, np.ascontiguousarray(traffic_rows, dtype=np.int64)
        traffic = (NO_TRAFFIC if self.traffic_rows.size == 0 else
                   COMPILED_TRAFFIC if fleet.compiled_only() else PYTHON_TRAFFIC)
        self.flags = np.zeros(8, dtype=np.int64)
        f = self.flags
        f[F_TRAFFIC], f[F_PLAIN], f[F_NSUB] = traffic, not suite.noisy, SUBSTEPS
        f[F_TOGETHER], f[F_COMM] = together, comm
        f[F_DIRECT] = world.tick_args is not None and world.contact_active
        f[F_DAMAGE] = world.damage_on
        self._no_narrow = (np.zeros((1, 3), dtype=np.int64), np.zeros(1, dtype=np.int64),
                           np.zeros(1, dtype=np.bool_), *(np.zeros(1, dtype=np.int64),) * 4,
                           np.zeros(1), np.zeros(3, dtype=np.int64))
        self.scalars = np.zeros(4)
        self.spec = table_spec(self.m)
        self._world_args = self._narrow_key = None
        self._set_args()

    def _set_args(self) -> None:
        """The address table of `env_tick`, built again when the World's arguments are a new
        tuple (its contact solver replaced an array)."""
        w = self.world.tick_args
        narrow_key, narrow = (self.world.narrow_table() if self.flags[F_DIRECT]
                              else (None, self._no_narrow))
        if w is self._world_args and narrow_key == self._narrow_key:
            return
        self._world_args, self._narrow_key = w, narrow_key
        _, _, _, half, _, _, _, _, max_range, *_ = self.suite.kernel_args()
        self.flags[F_FUEL] = w[8]
        x = self.scalars
        x[X_DT], x[X_LENGTH], x[X_HALF], x[X_RANGE] = w[7], w[9], half, max_range
        fleet = self.fleet
        arrays = [self.u, self.u_tick, self.steps, self.hits, self.status, self.flags, x,
                  self.live, self.going, self.traffic_rows, fleet.kind, fleet.S, fleet.P,
                  fleet.lanes, fleet.rand, *world_table_arrays(w),
                  *sensor_table_arrays(self.suite, self.cars, self.due, self.flat, self._scratch)]
        for j, ag in enumerate(self.agents):
            ctl, sc = ag.actions.controller, ag.scratch
            rw, dn = ag.rewards, ag.dones
            arrays += [self.modes[j], self.lane_limits[j], ag.why, self.actions[j], ag.chosen,
                       ag.actions.low, ag.actions.high, ctl.target_speed, self._slot0, ag.rows,
                       ag.actions.sab, ag.actions.gear, ctl.state, ctl.params, ctl.fresh,
                       ctl.lane_des, ctl.speed_des_kmh, sc.prev, sc.controls, rw.codes, rw.par,
                       rw.state, dn.codes, dn.par, dn.state, ag.weights, ag.is_trunc,
                       ag.running, ag.track_length, sc.cur, sc.length, sc.collision, sc.r_vals,
                       sc.d_vals, ag.total, ag.terms, ag.ticks, ag.term, ag.trunc, ag.fired,
                       *self.builders[j].kernel_args(), self.obs[j]]
        arrays += narrow
        self._arrays = arrays             # alive as long as the table is used
        self.args = (w[0], w[17], address_table(arrays, self.spec))     # state, snap, table

    def run(self, first: int, tick0: int, ticks: int) -> int:
        """Stages from `first` of tick `tick0` to the end of the step (`ticks` ticks); returns
        the stage left to Python (status[ST_TICK]: its tick) or DONE."""
        return env_tick(first, tick0, ticks, *self.args)

    def finish_step(self) -> None:
        """The STEP stage in Python: the pymunk narrow phase (or World.step's handling of a
        non-finite control), then the table again if the World replaced an array."""
        if self.steps[0] >= 0:
            self.world.finish_tick(self.u_tick, SUBSTEPS, int(self.steps[0]),
                                   keep_pairs=bool(self.flags[F_DIRECT]))
        else:
            self.world.step(self.u)
        self._set_args()
