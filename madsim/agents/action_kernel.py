"""Compiled action mapping of the learners of a batch (madsim.agents.component_batch.ActionMap).

`take_actions`: this step's checked (and noised) actions (m, dim) of slots (m,) -> S-A-B
controls `sab` (n, 3) or T-S targets `lane_des`, `speed_des_kmh` (n,); `begin_actions`: the
same after the manual gear from the last component. `fill_controls`: the
controls (m, 4: steer, accel, brake, gear) of the coming tick from the latest sensor rows
(m, 79): the T-S controller (madsim.agents.pid.ts_act) or the held S-A-B controls, the gear from
`gear` (manual) or snakeoil's gearbox. `clip_actions`: actions into the Box, finiteness checked.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from madsim.agents.pid import desired_lane_speed, speed_gear, ts_act
from madsim.physics.sensors import O_SX


@njit(cache=True)
def take_actions(slots, chosen, ts, normalised, compat, low, high, target_speed, sab, lane_des,
                 speed_des_kmh):
    for i in range(slots.shape[0]):
        e = slots[i]
        if ts:
            lane_des[e], speed_des_kmh[e] = desired_lane_speed(
                chosen[i, 0], chosen[i, 1], low, high, normalised, compat, target_speed[e])
        elif normalised:
            sab[e, 0] = chosen[i, 0]
            sab[e, 1] = (chosen[i, 1] + 1.0) / 2.0
            sab[e, 2] = (chosen[i, 2] + 1.0) / 2.0
        else:
            sab[e, 0], sab[e, 1], sab[e, 2] = chosen[i, 0], chosen[i, 1], chosen[i, 2]


@njit(cache=True)
def begin_actions(slots, chosen, ts, normalised, manual, compat, low, high, target_speed, sab, gear,
                  lane_des, speed_des_kmh):
    """`take_actions` after gear[slots] = the last component (manual): round(-1 + 3.5 (g + 1))
    normalised, else g, halves to even (np.round's rint)."""
    if manual:
        last = chosen.shape[1] - 1
        for i in range(slots.shape[0]):
            g = chosen[i, last]
            gear[slots[i]] = np.round(-1.0 + 3.5 * (g + 1.0) if normalised else g)
    take_actions(slots, chosen, ts, normalised, compat, low, high, target_speed, sab, lane_des,
                 speed_des_kmh)


@njit(cache=True)
def fill_controls(slots, rows, ts, manual, sab, gear, state, params, fresh, lane_des,
                  speed_des_kmh, out):
    if ts:
        ts_act(state, params, fresh, lane_des, speed_des_kmh, slots, rows, out)
    for i in range(slots.shape[0]):
        e = slots[i]
        if not ts:
            out[i, 0], out[i, 1], out[i, 2] = sab[e, 0], sab[e, 1], sab[e, 2]
        out[i, 3] = gear[e] if manual else float(speed_gear(rows[i, O_SX]))


@njit(cache=True)
def speed_gears(speed_kmh, out):
    """out[i] = speed_gear(speed_kmh[i]) (float gears)."""
    for i in range(speed_kmh.shape[0]):
        out[i] = speed_gear(speed_kmh[i])


@njit(cache=True)
def clip_actions(a, low, high, out):
    """out = a (m, dim) clipped into [low, high] (dim,), as np.minimum(high, np.maximum(low, a))
    to the bit (NaN kept); returns the flat index i * dim + j of the first non-finite a[i, j],
    or -1."""
    bad = -1
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            x = a[i, j]
            if bad < 0 and not math.isfinite(x):
                bad = i * a.shape[1] + j
            y = low[j] if low[j] >= x else x
            out[i, j] = high[j] if high[j] <= y else y
    return bad
