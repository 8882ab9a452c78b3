"""World.step's compiled part as one call: the control check, slipstream, the sub-step loop with
the contact broad phase (`contact_kernels.advance_until_near`, whole ticks where nothing can be
near) and race positions. `World.step` calls it for worlds with contact, and so does the SCR
server's compiled tick (`madsim.net.server_tick`), so both run the same code; only a sub-step
where something is near goes back to Python (the pymunk narrow phase, `World.finish_tick`).
"""

from __future__ import annotations

import numba
import numpy as np

from madsim.physics.contact_kernels import SNAP_COLUMNS, advance_until_near
from madsim.physics.kernel import check_controls, slipstream
from madsim.physics.layout import S_DIST, S_LAPS

NONFINITE = -1
"""`step_world`'s answer when a control is not finite (nothing was changed)."""
FIRST_CAR = np.int64(0)
"""An int64, not the literal 0: numba compiles a callee once per literal argument value, and
`advance_until_near` (~5 s to compile) is also called with a variable (World.finish_tick)."""


@numba.njit(cache=True)
def race_positions(st, race_pos):
    """race_pos[i] = 1 + the cars ahead of car i: more laps, or as many and a longer distance
    raced, or both equal and a lower row (numpy.lexsort of (row, -dist, -laps) for finite values)."""
    rank_rows(st, 0, st.shape[0], race_pos)


@numba.njit(cache=True, error_model="numpy")
def rank_rows(st, a, b, race_pos):
    """`race_positions` for the cars in rows a..b-1 of st alone (one race of a batch)."""
    for i in range(a, b):
        li, di = st[i, S_LAPS], st[i, S_DIST]
        rank = 1
        for j in range(a, b):
            lj, dj = st[j, S_LAPS], st[j, S_DIST]
            if lj > li or (lj == li and (dj > di or (dj == di and j < i))):
                rank += 1
        race_pos[i] = rank


@numba.njit(cache=True, error_model="numpy")
def step_world(u, nsub, st, cp, curve_w, curve_t, pt, surf, tsc, dt, fuel_on, length, info, x, y,
               yaw, piece, bp, near, snap, path, turn, wall, car, race_pos):
    """Advance the World state `st` (N, N_STATE) `nsub` sub-steps of `dt` s with controls u (N, 5)
    held, up to the first sub-step after which the broad phase (arrays `bp`) finds something
    near: returns the sub-steps done with near[0] > 0 there (the caller resolves the contact and
    goes on, `World.finish_tick`), or nsub with near[0] == 0 and race_pos (N,) updated. Returns
    NONFINITE, changing nothing, when u holds a non-finite value (info: `check_controls`).
    wall, car (N,) bool: this tick's contact flags, cleared. x, y, yaw: st's pose columns;
    piece, snap, path, turn: `advance_until_near`'s scratch. The World's own arguments come
    from `World.tick_args`."""
    check_controls(u, info)
    if info[0]:
        return NONFINITE
    n = st.shape[0]
    if n > 1:        # slipstream: from the poses at the start of the tick
        slipstream(st, cp, 0, n, length)
    for i in range(n):
        wall[i] = False
        car[i] = False
    k = advance_until_near(st, cp, curve_w, curve_t, pt, surf, tsc, u, FIRST_CAR, nsub, dt, fuel_on,
                           x, y, yaw, piece, bp, near, snap, path, turn)
    if near[0] == 0 and n > 1:
        race_positions(st, race_pos)
    return k
