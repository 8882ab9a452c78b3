"""Compiled built-in rewards and dones: every component of a set over many slots, one call.

`evaluate` computes out[c, i] for component c (its code, C_* below) and slot slots[i] from the
SCR sensor rows before and after the tick, prev[i] and cur[i] ((m, 79), wire order),
length[i] (track length, m) and collision[i] (contact during the tick). Per slot e each
component has parameters par[c, e, :NPAR] and state state[c, e, :NSTATE] (set at episode start
by the Python side, madsim.agents.component_batch.ComponentBatch). Dones return 1.0 / 0.0.
The formulas and their docs are those of the classes in madsim.agents.rewards / dones.
"""

from __future__ import annotations

import math

from numba import njit

from madsim.physics.sensors import O_ANGLE, O_DAMAGE, O_DRACED, O_LASTLAP, O_RACEPOS, O_TPOS, O_TRACK

TICK_S = 0.02
NPAR = 2
NSTATE = 3

# rewards
(C_PROGRESS, C_PROGRESS2, C_PROGRESS3, C_AVG_SPEED, C_COLLISION, C_TURN_BACKWARD, C_ANG_ACCEL,
 C_OVERTAKE, C_RANK_ONE, C_TASK) = range(1, 11)
# dones
(C_RACE_OVER, C_LAP_COMPLETED, C_TIME_OUT, C_COLLISION_DONE, C_TURN_BACKWARD_DONE,
 C_OUT_OF_TRACK, C_RANK1) = range(11, 18)


@njit(cache=True, inline="always")
def _wrap(a):
    return a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi))


@njit(cache=True)
def evaluate(codes, par, state, slots, prev, cur, length, collision, out):
    """out[c, i] = component c at slot slots[i] (see the module docstring)."""
    for c in range(codes.shape[0]):
        code = codes[c]
        if code == 0:                       # a Python component: the caller fills its row
            continue
        for i in range(slots.shape[0]):
            e = slots[i]
            d = cur[i, O_DRACED] - prev[i, O_DRACED]
            hit = collision[i] or cur[i, O_DAMAGE] > prev[i, O_DAMAGE]
            v = 0.0
            if code == C_PROGRESS:
                v = d / length[i]
            elif code == C_PROGRESS2:
                v = min(1.0, d / par[c, e, 0])
            elif code == C_PROGRESS3:
                v = d / par[c, e, 0]
            elif code == C_AVG_SPEED:           # s: ticks since the last paid lap, laps paid
                state[c, e, 0] += 1.0
                if not cur[i, O_DRACED] < (state[c, e, 1] + 1.0) * length[i]:
                    state[c, e, 1] += 1.0
                    avg_speed = length[i] / (state[c, e, 0] * TICK_S)
                    state[c, e, 0] = 0.0
                    v = avg_speed / par[c, e, 0]
            elif code == C_COLLISION or code == C_COLLISION_DONE:
                v = 1.0 if hit else 0.0
            elif code == C_TURN_BACKWARD or code == C_TURN_BACKWARD_DONE:
                v = 1.0 if math.cos(cur[i, O_ANGLE]) < 0.0 else 0.0
            elif code == C_ANG_ACCEL:           # s: a_{t-2}, a_{t-1}, fresh
                if state[c, e, 2] != 0.0:
                    state[c, e, 0] = state[c, e, 1] = prev[i, O_ANGLE]
                    state[c, e, 2] = 0.0
                a0, a1, a2 = state[c, e, 0], state[c, e, 1], cur[i, O_ANGLE]
                state[c, e, 0], state[c, e, 1] = a1, a2
                acc = abs(_wrap(a2 - a1) - _wrap(a1 - a0))
                v = acc / par[c, e, 0] if acc > par[c, e, 1] else 0.0
            elif code == C_OVERTAKE:            # s: best position so far, fresh
                if state[c, e, 1] != 0.0:
                    state[c, e, 0] = prev[i, O_RACEPOS]
                    state[c, e, 1] = 0.0
                gained = state[c, e, 0] - cur[i, O_RACEPOS]
                if gained > 0:
                    state[c, e, 0] = cur[i, O_RACEPOS]
                    v = gained
            elif code == C_RANK_ONE or code == C_RANK1:
                v = 1.0 if cur[i, O_RACEPOS] == 1.0 else 0.0
            elif code == C_TASK:                # s: paid
                if not (state[c, e, 0] != 0.0 or cur[i, O_RACEPOS] > par[c, e, 0]):
                    state[c, e, 0] = 1.0
                    v = par[c, e, 1]
            elif code == C_RACE_OVER:
                v = 1.0 if cur[i, O_DRACED] >= par[c, e, 0] * length[i] else 0.0
            elif code == C_LAP_COMPLETED:
                last = cur[i, O_LASTLAP]
                v = 1.0 if last > 0.0 and last != prev[i, O_LASTLAP] else 0.0
            elif code == C_TIME_OUT:            # s: ticks since reset
                state[c, e, 0] += 1.0
                v = 1.0 if state[c, e, 0] >= par[c, e, 0] else 0.0
            elif code == C_OUT_OF_TRACK:
                pos = cur[i, O_TPOS]
                off = pos < par[c, e, 0] or pos > par[c, e, 1]
                for j in range(19):
                    if cur[i, O_TRACK + j] < 0.0:
                        off = True
                v = 1.0 if off else 0.0
            out[c, i] = v
