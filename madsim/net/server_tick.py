"""The SCR server's tick as one compiled call: the clients' control datagrams -> controls and
focus requests -> the World advanced one tick -> every car's sensors -> the state messages'
bytes. The Python loop around it only receives and sends datagrams and keeps the books.

The stages are the engine's own kernels (`codec_kernels.decode_stock`, `world_tick.step_world`,
`sensors.sensor_kernel` and `focus_due`, `codec_kernels.encode_rows`), so the bytes are those of
the in-process doors (World.step, SensorSuite.frame, protocol.encode_sensor_rows). Whatever a
stage cannot finish exactly stops the call at that stage and is done by the Python path of the
same stage (`ServerTick._python_stage`), which then goes on: a datagram in no stock layout, a
control that is not finite, something near a car (the pymunk narrow phase), sensor noise or
the start countdown, a value the compiled encoder leaves to the exact one.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from madsim.facts import TICK_S
from madsim.net import protocol as P
from madsim.array_table import (address_table, b1_vector, f8_matrix, f8_vector, i8_vector,
                                readonly, u1_matrix, u1_vector)
from madsim.net.codec_kernels import decode_stock, encode_rows
from madsim.physics.layout import C_FINISH, S_CURLAP, S_DAMAGE, S_LAPS
from madsim.physics.sensors import (FOCUS_NONE, N_VALUES, O_CURLAP, O_FOCUS, O_GEAR,
                                    SENSOR_OFFSETS, SENSOR_TABLE, SN_CARS, SN_DUE, SN_EARLIEST,
                                    SN_FLAT, SN_NEXT, SN_REQUESTED, focus_request, sense_table,
                                    sensor_table_arrays)
from madsim.physics.world_tick import W_CP, W_NEAR, W_RACE_POS, WORLD_TABLE, step_table, world_table_arrays

DECODE, STEP, SENSE, ENCODE, DONE = 0, 1, 2, 3, 4
"""The stages in order; `server_tick` returns the one Python must do, or DONE."""
EVENT = 8
"""Or-ed into DONE: a car's lap count changed, a car is over the damage limit, or a client
asked for a restart (meta 1): the loop's bookkeeping has work."""

# The arrays `server_tick` reads, in the order of its address table (`madsim.array_table`):
# name, dtype, dimensions, memory order. From row W0 the World's (`world_tick.WORLD_TABLE`), from
# row S0 the sensors' (`sensors.SENSOR_TABLE`).
_OWN_FIRST = (
    ("inbox", "u1", 2, "C"), ("inlen", "i8", 1, "C"), ("meta", "i8", 1, "C"),
    ("cpp_text", "u1", 1, "C"), ("cpp_ends", "i8", 1, "C"), ("cpp_slots", "i8", 1, "C"),
    ("snakeoil_text", "u1", 1, "C"), ("snakeoil_ends", "i8", 1, "C"), ("snakeoil_slots", "i8", 1, "C"),
    ("controls", "f8", 2, "C"), ("steps", "i8", 1, "C"), ("u_tick", "f8", 2, "C"),
)
_OWN_LAST = (
    ("is_int", "b1", 1, "C"), ("literals", "u1", 1, "C"), ("literal_ends", "i8", 1, "C"),
    ("out", "u1", 2, "C"), ("out_len", "i8", 1, "C"), ("laps_seen", "f8", 1, "C"),
    ("decoded", "f8", 1, "C"), ("asked", "i8", 1, "C"), ("asked_focus", "f8", 1, "C"),
)
TABLE = _OWN_FIRST + WORLD_TABLE + SENSOR_TABLE + _OWN_LAST
(INBOX, INLEN, META, CPP_TEXT, CPP_ENDS, CPP_SLOTS, SO_TEXT, SO_ENDS, SO_SLOTS, U, STEPS,
 U_TICK) = (np.int64(k) for k in range(len(_OWN_FIRST)))
W0 = np.int64(len(_OWN_FIRST))
S0 = np.int64(W0 + len(WORLD_TABLE))
(IS_INT, LIT, LIT_END, OUT, OUT_LEN, LAPS_SEEN, DECODED, ASKED, ASKED_FOCUS) = (
    np.int64(S0 + len(SENSOR_TABLE) + k) for k in range(len(_OWN_LAST)))
CARS, FLAT, DUE = S0 + SN_CARS, S0 + SN_FLAT, S0 + SN_DUE
REQUESTED, NEXT, EARLIEST = S0 + SN_REQUESTED, S0 + SN_NEXT, S0 + SN_EARLIEST
RACE_POS, NEAR = W0 + W_RACE_POS, W0 + W_NEAR
# int64 row numbers, not int literals: see array_table's views


@numba.njit(cache=True, error_model="numpy")
def server_tick(first, stop, stepping, plain, nsub, st, snap, t, dt, fuel_on, length, half_width,
                max_range, max_bytes, max_damage, max_lap_s):
    """Run the stages first..stop-1 of one tick on the World state `st`, its scratch copy `snap`
    and the arrays of address table `t` (`TABLE`);
    returns the first stage left to Python (its inputs complete, its outputs not), `stop` if
    it was reached, or DONE (| EVENT). The scalars: the World's sub-step (s), fuel flag and
    track length (m), the track's half width and the sensors' range (m), the state message's
    byte limit, the damage limit, the lap-time limit (s; inf: none).

    DECODE: car i's datagram is inbox[i, :inlen[i]] (inlen[i] < 0: no answer this tick, its
      controls and focus request stay); into controls (N, 5), meta (N,) and the focus
      requests. Stops where a datagram is in no stock layout (meta[i] = -1 marks those).
    STEP (when `stepping`, i.e. not in the countdown): `world_tick.step_world` on u_tick, the
      tick's copy of controls (`world_tick.step_table` , the World's arrays from row W0; a shift's throttle cap
      writes into u_tick); steps[0] = its
      answer. Stops on a non-finite control (steps[0] < 0: nothing was changed) or something
      near (after sub-step steps[0]: World.finish_tick goes on from there).
    SENSE (`sensors.sense_table`, the sensors' arrays from row S0): `sensor_kernel` into flat
      (N, 79), the focus cooldowns (`focus_due`) and the focus readings due (`focus_kernel`); stops when not `plain` (noise or the countdown to apply;
      due (N,) bool says which cars get a focus reading).
    ENCODE: `codec_kernels.encode_rows` into out, out_len; stops when a row is left to the
      exact encoder (out_len -1).
    Then DONE, with EVENT when the lap counts differ from laps_seen (N,), a damage exceeds
    max_damage, a current lap has lasted longer than max_lap_s, the race is over (a car's C_FINISH < 0: `physics.finish`), or a decoded meta is 1.
    Its scratch arrays are in the table too (decoded (8,), asked, asked_focus, time_s,
    on_track (N,)): it allocates nothing. (It keeps numba's reference counting: the table's
    views are new arrays, which a function compiled without it cannot make.)
    """
    u = f8_matrix(t, U)
    n = u.shape[0]
    requested, next_allowed, earliest = f8_vector(t, REQUESTED), f8_vector(t, NEXT), f8_vector(t, EARLIEST)
    event = False
    if first <= DECODE < stop:
        inbox, inlen, meta = u1_matrix(t, INBOX), i8_vector(t, INLEN), i8_vector(t, META)
        cpp = (readonly(u1_vector(t, CPP_TEXT)), i8_vector(t, CPP_ENDS), i8_vector(t, CPP_SLOTS))
        snakeoil = (readonly(u1_vector(t, SO_TEXT)), i8_vector(t, SO_ENDS), i8_vector(t, SO_SLOTS))
        dec, asked, focus = f8_vector(t, DECODED), i8_vector(t, ASKED), f8_vector(t, ASKED_FOCUS)
        m = 0
        whole = True
        for i in range(n):
            if inlen[i] < 0:
                meta[i] = 0
                continue
            if not decode_stock(readonly(inbox[i]), inlen[i], cpp, snakeoil, dec):
                meta[i] = -1
                whole = False
                continue
            for j in range(5):
                u[i, j] = dec[j]
            meta[i] = int(dec[6])
            event = event or meta[i] == 1
            asked[m] = i
            focus[m] = dec[5]
            m += 1
        focus_request(asked[:m], focus[:m], requested, next_allowed, earliest)
        if not whole:
            return DECODE
    race_pos = i8_vector(t, RACE_POS)
    if first <= STEP < stop and stepping:
        # the tick runs on its own copy of the controls: a shift's throttle cap writes into it
        # (TORCS's ctrl->accelCmd, held to the end of the driver call), never into what the
        # client sent, which a silent client's car keeps using
        steps = i8_vector(t, STEPS)
        steps[0] = step_table(u, f8_matrix(t, U_TICK), nsub, st, snap, t, W0, dt, fuel_on, length)
        if steps[0] < 0 or i8_vector(t, NEAR)[0] != 0:
            return STEP
    if first <= SENSE < stop:
        if not sense_table(st, t, S0, race_pos, length, half_width, max_range, plain):
            return SENSE                    # noise or the countdown: Python finishes the frame
    if first <= ENCODE < stop:
        out_len = i8_vector(t, OUT_LEN)
        encode_rows(f8_matrix(t, FLAT), b1_vector(t, IS_INT), readonly(u1_vector(t, LIT)), i8_vector(t, LIT_END),
                    max_bytes, u1_matrix(t, OUT), out_len)
        for i in range(out_len.shape[0]):
            if out_len[i] < 0:
                return ENCODE
    if stop < DONE:
        return stop
    laps_seen, cp = f8_vector(t, LAPS_SEEN), f8_matrix(t, W0 + W_CP)
    for i in range(n):
        if st[i, S_LAPS] != laps_seen[i] or st[i, S_DAMAGE] > max_damage or cp[i, C_FINISH] < 0.0 \
                or st[i, S_CURLAP] > max_lap_s:
            event = True
    return DONE | EVENT if event else DONE


class ServerTick:
    """One race's tick: the buffers `server_tick` reads and writes, the call, and the Python path
    of each stage for what the call leaves (or for every stage, for a World without
    `tick_args`).

    The server receives car i's datagram into `inbox[i]` and sets `inlen[i]` (-1: no answer),
    runs `run(...)`, and sends `message(i)`. `u` (N, 5) holds the controls applied (a car that
    did not answer keeps its last ones); `meta` (N,) the meta values of this tick's answers.
    """

    def __init__(self, world, suite, controls: np.ndarray, inbox: np.ndarray, inlen: np.ndarray,
                 max_damage: float, max_lap_s: float = math.inf):
        n = world.n_cars
        self.world, self.suite, self.u = world, suite, controls
        self.inbox, self.inlen = inbox, inlen
        inlen[:] = -1
        self.meta = np.zeros(n, dtype=np.int64)
        self.due = np.zeros(n, dtype=np.bool_)
        self.steps = np.zeros(1, dtype=np.int64)
        self.u_tick = np.zeros_like(controls)     # the tick's copy the compiled step runs on
        self.cars = np.arange(n, dtype=np.int64)
        self.flat = np.zeros((n, N_VALUES))
        self.out = np.zeros((n, P.STATE_ENCODER.message_width), dtype=np.uint8)
        self.out_len = np.zeros(n, dtype=np.int64)
        self._messages = [memoryview(self.out[i]) for i in range(n)]
        self.laps_seen = world.state[:, S_LAPS].copy()
        self._scratch = (np.zeros(8), np.zeros(n, dtype=np.int64), np.zeros(n), np.zeros(n),
                         np.zeros(n, dtype=np.bool_))     # server_tick's (see TABLE)
        self.max_damage = float(max_damage)
        self.max_lap_s = float(max_lap_s)     # TORCS's lap-time limit (inf: none)
        self.bad_datagrams = 0             # answers not well formed (applied as TORCS reads them)
        self.compiled = world.tick_args is not None
        self._world_args = None
        self._set_args()

    def _set_args(self) -> None:
        """The address table and scalars of `server_tick`, built again when the World's
        arguments are a new tuple (its contact solver replaced an array)."""
        w = self.world.tick_args
        if w is None or w is self._world_args:
            return
        self._world_args = w
        _, _, _, half, _, _, _, _, max_range, *_ = self.suite.kernel_args()
        is_int, lit, lit_end, max_bytes = P.STATE_ENCODER.kernel_args()
        decoded, asked, asked_focus, time_s, on_track = self._scratch
        arrays = (self.inbox, self.inlen, self.meta, *P.STOCK_LAYOUTS[0], *P.STOCK_LAYOUTS[1], self.u,
                  self.steps, self.u_tick, *world_table_arrays(w),
                  *sensor_table_arrays(self.suite, self.cars, self.due, self.flat, (time_s, on_track)),
                  is_int, lit, lit_end, self.out, self.out_len, self.laps_seen, decoded, asked,
                  asked_focus)
        self._arrays = arrays             # alive as long as the table is used
        # the state and its scratch copy go as arguments: typed as World.step's callers see them
        # (C order for one car), so the physics kernels are compiled once for both
        self.args = (w[0], w[17], address_table(arrays, TABLE), w[7], w[8], w[9], half, max_range,
                     max_bytes, self.max_damage, self.max_lap_s)

    def refresh(self) -> None:
        """Call after the World or the suite replaced an array (e.g. World.reset)."""
        self._world_args = None
        self._set_args()

    def message(self, car: int) -> memoryview:
        """Car `car`'s state message (with its NUL) as the last run left it."""
        return self._messages[car][:self.out_len[car]]

    def run(self, first: int, stop: int, stepping: bool, nsub: int, countdown: int) -> int:
        """Stages first..stop-1 (DECODE, STEP, SENSE, ENCODE); returns stop, or for stop = DONE
        DONE | EVENT when the bookkeeping has work (always after a stage done in Python).
        stepping: advance the World (False in the countdown); countdown: the ticks still to
        wait before the start, shown in the state being built (curLapTime < 0, gear 0, no focus)."""
        status = first
        if self.compiled:           # the usual tick: one call, nothing left
            status = server_tick(first, stop, stepping, countdown == 0 and not self.suite.noisy, nsub,
                                 *self.args)
            if status >= stop:
                return status
        return self.resume(status, stop, stepping, nsub, countdown)

    def resume(self, status: int, stop: int, stepping: bool, nsub: int, countdown: int) -> int:
        """Go on from stage `status`, which the compiled call left to Python (its inputs
        complete), to `stop`; returns as `run`."""
        plain = countdown == 0 and not self.suite.noisy
        python = False
        while status < stop:
            self._python_stage(status, stepping, nsub, countdown)
            python = True
            status += 1
            if self.compiled and status < stop:
                status = server_tick(status, stop, stepping, plain, nsub, *self.args)
        if python and stop == DONE:
            return DONE | EVENT
        return status

    def _python_stage(self, stage: int, stepping: bool, nsub: int, countdown: int) -> None:
        """The Python path of one stage (the compiled call did the stages before it)."""
        n = self.u.shape[0]
        if stage == DECODE:
            for i in range(n):
                if self.inlen[i] < 0:
                    self.meta[i] = 0
                elif not self.compiled or self.meta[i] == -1:
                    ctl = P.decode_controls(self.inbox[i, :self.inlen[i]].tobytes())
                    if not ctl.well_formed:
                        self.bad_datagrams += 1
                    self.u[i] = (ctl.steer, ctl.accel, ctl.brake, ctl.gear, ctl.clutch)
                    self.suite.request_focus([i], [FOCUS_NONE if ctl.focus is None else ctl.focus])
                    self.meta[i] = ctl.meta
        elif stage == STEP and stepping:
            if self.compiled and self.steps[0] >= 0:
                self.world.finish_tick(self.u_tick, nsub, int(self.steps[0]))
            else:
                self.world.step(self.u, nsub)
            self._set_args()            # the World's contact arrays may have been replaced
        elif stage == SENSE:
            if self.compiled:
                self.suite.finish_frame(self.flat, self.cars, self.due)
            else:
                self.flat[:] = self.suite.frame().flat
            if countdown > 0:
                self.flat[:, O_CURLAP] = -TICK_S * countdown
                self.flat[:, O_GEAR] = 0.0
                self.flat[:, O_FOCUS:O_FOCUS + 5] = -1.0
        elif stage == ENCODE:
            for i in range(n):
                if not self.compiled or self.out_len[i] < 0:
                    msg = encode_exact(self.flat[i:i + 1])[0]
                    self.out[i, :len(msg)] = np.frombuffer(msg, dtype=np.uint8)
                    self.out_len[i] = len(msg)


def encode_exact(rows: np.ndarray) -> list[bytes]:
    """Every car's state message from its (79,) wire-order sensor row, whatever the values: only
    pathological ones exceed 999 bytes, and then the noisy arrays are rounded and retried."""
    try:
        return P.encode_sensor_rows(rows)
    except P.ProtocolError:
        rows = rows.copy()
        for name in ("track", "opponents", "focus"):
            o, w = SENSOR_OFFSETS[name]
            rows[:, o:o + w] = np.round(rows[:, o:o + w], 2)
        return P.encode_sensor_rows(rows)
