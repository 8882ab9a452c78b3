"""The learners' side of a batched tick (make_vec) in three compiled calls, no numpy per tick.

`tick_controls` before the tick: the learners' sensor rows before it (the rewards' and dones'
`prev`) and their controls written into the batch's control rows. `tick_outcome` after it:
the built-in rewards and dones (madsim.agents.component_kernel.evaluate), the weighted sum, the
step's running totals, which episodes ended and their stop controls. `observe_rows`: the
observation vectors (madsim.agents.observations.ObservationBuilder's arithmetic) of many rows.
Each does what the numpy code of `madsim.envs.vector` around the same kernels did, in the same
order on the same values: the results are the same bits.

Shapes: slot axis first; `flat` (C, 79) the batch's sensor rows (wire order), `u` (C, 5) its
controls; `run` (m,) episodes, `rows` (m,) their learners' rows of flat and u.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from madsim.agents.action_kernel import begin_actions, fill_controls
from madsim.agents.component_kernel import evaluate
from madsim.physics.sensors import N_VALUES


class LearnerScratch:
    """Per-tick scratch of `tick_controls` / `tick_outcome` for up to n learners: their sensor
    rows before and after the tick, track lengths and contact flags, the k rewards' and kd
    dones' values, the controls."""

    def __init__(self, n: int, k: int, kd: int):
        self.prev, self.cur = np.zeros((n, N_VALUES)), np.zeros((n, N_VALUES))
        self.length, self.collision = np.zeros(n), np.zeros(n, dtype=bool)
        self.r_vals, self.d_vals = np.zeros((k, n)), np.zeros((kd, n))
        self.controls = np.zeros((n, 4))


@njit(cache=True)
def tick_controls(run, rows, flat, prev, ts, manual, sab, gear, state, params, fresh, lane_des,
                  speed_des_kmh, out, u):
    """prev[:m] = flat[rows]; u[rows, :4] = the controls of the coming tick (`fill_controls`
    from prev; out (>= m, 4) scratch). m = len(run)."""
    m = run.shape[0]
    for i in range(m):
        for j in range(flat.shape[1]):
            prev[i, j] = flat[rows[i], j]
    fill_controls(run, prev[:m], ts, manual, sab, gear, state, params, fresh, lane_des,
                  speed_des_kmh, out[:m])
    for i in range(m):
        for j in range(4):
            u[rows[i], j] = out[i, j]


@njit(cache=True)
def start_outcome(total, ticks, term, trunc, fired, running):
    """A step's outcome arrays (M,) cleared before its first tick, every position running."""
    for p in range(total.shape[0]):
        total[p] = 0.0
        ticks[p] = 0
        term[p] = trunc[p] = False
        for c in range(fired.shape[1]):
            fired[p, c] = False
        running[p] = p


@njit(cache=True)
def begin_step(slots, chosen, ts, normalised, manual, compat, low, high, target_speed, sab, gear,
               lane_des, speed_des_kmh, total, ticks, term, trunc, fired, running):
    """A step's start in one call: the checked (and noised) actions (m, dim) of slots taken
    (`action_kernel.begin_actions`) and the outcome arrays cleared (`start_outcome`)."""
    begin_actions(slots, chosen, ts, normalised, manual, compat, low, high, target_speed, sab,
                  gear, lane_des, speed_des_kmh)
    start_outcome(total, ticks, term, trunc, fired, running)


@njit(cache=True)
def tick_outcome(r_codes, r_par, r_state, d_codes, d_par, d_state, weights, is_trunc, running,
                 run, rows, flat, hits, track_length, prev, cur, length, collision, r_vals,
                 d_vals, first, total, terms, ticks, term, trunc, fired, u):
    """The rewards and dones of the tick just done for episodes run (m,) at positions running
    (m,) of the step's arrays (total (M,), terms (k, M) reward terms: assigned on the step's
    first tick, else added; ticks (M,) counted; term, trunc (M,) bool, fired (M, kd) bool: set
    for the episodes that ended). cur, length, collision, r_vals (k, >= m), d_vals (kd, >= m):
    scratch (cur = flat[rows] after the tick, prev before it). An ended episode's controls
    become the stop action (u[row, :3] = 0, 0, 1; clutch 0). Compacts `running` to the
    episodes still running, in order, and returns their number."""
    m = run.shape[0]
    for i in range(m):
        for j in range(flat.shape[1]):
            cur[i, j] = flat[rows[i], j]
        length[i] = track_length[run[i]]
        collision[i] = hits[rows[i]]
    rv, dv = r_vals[:, :m], d_vals[:, :m]
    evaluate(r_codes, r_par, r_state, run, prev[:m], cur[:m], length[:m], collision[:m], rv)
    evaluate(d_codes, d_par, d_state, run, prev[:m], cur[:m], length[:m], collision[:m], dv)
    return tally(weights, is_trunc, running, rows, rv, dv, first, total, terms, ticks, term, trunc,
                 fired, u)


@njit(cache=True)
def tally(weights, is_trunc, running, rows, rv, dv, first, total, terms, ticks, term, trunc, fired,
          u):
    """The bookkeeping of `tick_outcome` from the tick's reward values rv (k, m) and done values
    dv (kd, m) (1.0 / 0.0) of the m episodes at positions running (m,) of the step's arrays,
    whose control rows are rows (m,): weighted terms and totals, ticks, which ended (their
    stop controls). Compacts `running` to the episodes still running; returns their number.
    (The envs call it directly when a reward or done is plain Python.)"""
    m = running.shape[0]
    left = 0
    for i in range(m):
        p = running[i]
        r = 0.0
        for c in range(rv.shape[0]):
            t = weights[c] * rv[c, i]
            r += t
            if first:
                terms[c, p] = t
            else:
                terms[c, p] += t
        total[p] += r
        ticks[p] += 1
        ended_term = ended_trunc = False
        for c in range(dv.shape[0]):
            if dv[c, i] != 0.0:
                if is_trunc[c]:
                    ended_trunc = True
                else:
                    ended_term = True
        if ended_term or ended_trunc:
            term[p], trunc[p] = ended_term, ended_trunc
            for c in range(dv.shape[0]):
                fired[p, c] = dv[c, i] != 0.0
            u[rows[i], 0], u[rows[i], 1], u[rows[i], 2] = 0.0, 0.0, 1.0
            u[rows[i], 4] = 0.0
        else:
            running[left] = p
            left += 1
    return left


@njit(cache=True)
def observe_rows(flat, rows, wire_index, scale, low, high, normalise, gain, offset, out, out_rows):
    """out[out_rows[i]] = the observation of sensor row flat[rows[i]] (float32): the values at
    wire_index, times scale, clipped into [low, high]; with normalise, times gain plus offset,
    clipped into [-1, 1] (float64 arithmetic, rounded to float32 once)."""
    for i in range(rows.shape[0]):
        r, o = rows[i], out_rows[i]
        for j in range(wire_index.shape[0]):
            x = flat[r, wire_index[j]] * scale[j]
            x = _clip(x, low[j], high[j])
            if normalise:
                x = _clip(x * gain[j] + offset[j], -1.0, 1.0)
            out[o, j] = x


@njit(cache=True, inline="always")
def _clip(x, lo, hi):
    """np.clip(x, lo, hi) to the bit: numpy's min(max(x, lo), hi) with NaN kept (so -0.0 at a
    bound of 0.0 becomes 0.0, as numpy's max picks the bound when neither is greater)."""
    y = x if (x != x or x > lo) else lo
    return y if (y != y or y < hi) else hi
