"""The SCR server's tick as one compiled call: the clients' control datagrams -> controls and
focus requests -> the World advanced one tick -> every car's sensors -> the state messages'
bytes. The Python loop around it only receives and sends datagrams and keeps the books.

The stages are the engine's own kernels (`codec_kernels.decode_stock`, `world_tick.step_world`,
`sensors.sensor_kernel` and `focus_due`, `codec_kernels.encode_rows`), so the bytes are those of
the in-process doors (World.step, SensorSuite.frame, protocol.encode_sensor_rows). Whatever a
stage cannot finish exactly stops the call at that stage and is done by the Python path of the
same stage (`ScrServer._finish_tick`), which then goes on: a datagram in no stock layout, a
control that is not finite, something near a car (the pymunk narrow phase), a focus reading
due, sensor noise or the start countdown, a value the compiled encoder leaves to the exact one.
"""

from __future__ import annotations

import numba
import numpy as np

from madsim.facts import TICK_S
from madsim.net import protocol as P
from madsim.net.codec_kernels import decode_stock, encode_rows
from madsim.physics.layout import S_DAMAGE, S_LAPS, S_TIME
from madsim.physics.sensors import (FOCUS_NONE, N_VALUES, O_CURLAP, O_FOCUS, O_GEAR, O_TPOS,
                                    SENSOR_OFFSETS, focus_due, focus_request, sensor_kernel)
from madsim.physics.world_tick import NEAR_ARG, step_world

DECODE, STEP, SENSE, ENCODE, DONE = 0, 1, 2, 3, 4
"""The stages in order; `server_tick` returns the one Python must do, or DONE."""
EVENT = 8
"""Or-ed into DONE: a car's lap count changed, a car is over the damage limit, or a client
asked for a restart (meta 1): the loop's bookkeeping has work."""


@numba.njit(cache=True, error_model="numpy")
def server_tick(first, stop, stepping, plain, nsub, inbox, inlen, meta, layouts, u, world, steps,
                cars, sense, due, flat, codec, out, out_len, laps_seen, max_damage):
    """Run the stages first..stop-1 of one tick; returns the first stage left to Python (its
    inputs are complete, its outputs not), `stop` if it was reached, or DONE (| EVENT).

    DECODE: inbox (N, B) uint8 holds car i's datagram in inbox[i, :inlen[i]] (inlen[i] < 0: no
      answer this tick, its controls and focus request stay); into u (N, 5) controls, meta (N,)
      and the focus requests; `layouts` = protocol.STOCK_LAYOUTS. Stops where a datagram is in
      no stock layout (meta[i] = -1 marks those).
    STEP (when `stepping`, i.e. not in the countdown): `world_tick.step_world(u, nsub,
      *world)`, world = World.tick_args; steps[0] = its answer. Stops on a non-finite control
      (steps[0] < 0: nothing was changed) or something near (after sub-step steps[0]: the
      World's finish_tick goes on from there).
    SENSE: sensor_kernel(cars, st, *sense[:9], flat) and the focus cooldowns (sense[9:] =
      requested, next allowed, earliest: SensorSuite.kernel_args); stops when a focus reading
      is due (due (N,) bool), and always when not `plain` (noise or countdown to apply).
    ENCODE: codec_kernels.encode_rows(flat, *codec, out, out_len) (codec =
      SensorEncoder.kernel_args); stops when a row is left to the exact encoder (out_len -1).
    Then DONE, with EVENT when st's lap counts differ from laps_seen (N,), a damage exceeds
    max_damage, or a decoded meta is 1.
    """
    n = u.shape[0]
    st = world[0]
    event = False
    if first <= DECODE < stop:
        dec = np.empty(8)
        asked = np.empty(n, dtype=np.int64)
        focus = np.empty(n)
        m = 0
        whole = True
        for i in range(n):
            if inlen[i] < 0:
                meta[i] = 0
                continue
            if not decode_stock(inbox[i], inlen[i], layouts[0], layouts[1], dec):
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
        focus_request(asked[:m], focus[:m], sense[9], sense[10], sense[11])
        if not whole:
            return DECODE
    if first <= STEP < stop and stepping:
        steps[0] = step_world(u, nsub, *world)
        if steps[0] < 0 or world[NEAR_ARG][0] != 0:
            return STEP
    if first <= SENSE < stop:
        sensor_kernel(cars, st, sense[0], sense[1], sense[2], sense[3], sense[4], sense[5], sense[6],
                      sense[7], sense[8], flat)
        earliest = sense[11]
        count = 0
        if st[0, S_TIME] >= earliest[0]:        # one clock for all cars
            time_s = np.empty(cars.shape[0])
            on_track = np.empty(cars.shape[0], dtype=np.bool_)
            for k in range(cars.shape[0]):
                time_s[k] = st[cars[k], S_TIME]
                on_track[k] = abs(flat[k, O_TPOS]) <= 1.0
            count = focus_due(cars, time_s, on_track, sense[9], sense[10], earliest, due)
        if count > 0 or not plain:
            if count == 0:
                due[:] = False
            return SENSE
    if first <= ENCODE < stop:
        encode_rows(flat, codec[0], codec[1], codec[2], codec[3], out, out_len)
        for i in range(out_len.shape[0]):
            if out_len[i] < 0:
                return ENCODE
    if stop < DONE:
        return stop
    for i in range(n):
        if st[i, S_LAPS] != laps_seen[i] or st[i, S_DAMAGE] > max_damage:
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
                 max_damage: float):
        n = world.n_cars
        self.world, self.suite, self.u = world, suite, controls
        self.inbox, self.inlen = inbox, inlen
        inlen[:] = -1
        self.meta = np.zeros(n, dtype=np.int64)
        self.due = np.zeros(n, dtype=np.bool_)
        self.steps = np.zeros(1, dtype=np.int64)
        self.cars = np.arange(n, dtype=np.int64)
        self.flat = np.zeros((n, N_VALUES))
        self.out = np.zeros((n, P.STATE_ENCODER.message_width), dtype=np.uint8)
        self.out_len = np.zeros(n, dtype=np.int64)
        self._messages = [memoryview(self.out[i]) for i in range(n)]
        self.laps_seen = world.state[:, S_LAPS].copy()
        self.max_damage = float(max_damage)
        self.bad_datagrams = 0             # answers not well formed (applied as TORCS reads them)
        self.compiled = world.tick_args is not None
        self._set_args()

    def _set_args(self) -> None:
        self.args = (self.inbox, self.inlen, self.meta, P.STOCK_LAYOUTS, self.u, self.world.tick_args,
                     self.steps, self.cars, self.suite.kernel_args(), self.due, self.flat,
                     P.STATE_ENCODER.kernel_args(), self.out, self.out_len, self.laps_seen, self.max_damage)

    def message(self, car: int) -> memoryview:
        """Car `car`'s state message (with its NUL) as the last run left it."""
        return self._messages[car][:self.out_len[car]]

    def run(self, first: int, stop: int, *, stepping: bool, nsub: int, countdown: int) -> int:
        """Stages first..stop-1 (DECODE, STEP, SENSE, ENCODE); returns stop, or for stop = DONE
        DONE | EVENT when the bookkeeping has work (always after a stage done in Python).
        stepping: advance the World (False in the countdown); countdown: the ticks still to
        wait before the start, shown in the state being built (curLapTime < 0, gear 0, no focus)."""
        plain = countdown == 0 and not self.suite.noisy
        status = first
        python = False
        while status < stop:
            if self.compiled:
                status = server_tick(status, stop, stepping, plain, nsub, *self.args)
                if status >= stop:
                    break
            self._python_stage(status, stepping, nsub, countdown)
            python = True
            status += 1
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
                self.world.finish_tick(self.u, nsub, int(self.steps[0]))
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
