"""TORCS 1.3.7's finish of a race (its race engine's start-line rule in ReManage and the race's end
in ReSortCars; docs/physics.md, "The finish of a race"), compiled on the car table's column
C_FINISH and the state's lap columns: the one implementation World, WorldBatch and the SCR
server share.

C_FINISH per car: 0 for a race without end; > 0 the start-line crossings (S_LAPS) at which the
car has finished: the race's laps + 1 at the start, the car's next crossing once another car has
finished (`finish_rule`); FINISH_ENDED once the race is over (a finished car has crossed the line
again, and every car is finished). A finished car's crossings are not counted: its S_LAPS, last
and best lap time stay, its lap timer runs on; S_BACK goes below 0 by the crossings not counted,
so the distance raced (S_DIST) goes on without a jump.

Cars are independent within a tick (the threaded and whole-tick steppers rely on it), so the
rule that ties them, a car finishing at its first crossing after another car's finish, is
applied at each tick's start before the cross-car slipstream (`kernel.tick_start`), from the
lap times: a car that crossed the line in the previous tick after the first finisher's finish
counts as finished from this tick's start (TORCS flags it at that very crossing: up to 20 ms of
its slow pace and damage gate come late)."""

from __future__ import annotations

import numba

from madsim.physics.layout import C_FINISH, S_BACK, S_BESTLAP, S_LAPS, S_LAPSTART, S_LASTLAP, S_TIME

_JIT = {"cache": True, "error_model": "numpy"}
FINISH_ENDED = -1.0
"""C_FINISH of every car once the race is over (TORCS's RM_RACE_ENDED)."""


@numba.njit(inline="always", **_JIT)
def finished(st, cp, i):
    """True once car i has finished its race (TORCS's RM_CAR_STATE_FINISH): its crossings reached
    C_FINISH, or the race is over."""
    finish = cp[i, C_FINISH]
    return finish < 0.0 or (finish > 0.0 and st[i, S_LAPS] >= finish)


@numba.njit(inline="always", **_JIT)
def takes_damage(st, cp, i):
    """True while car i has not finished: TORCS 1.3.7's simuv2 adds no damage (walls, pit walls,
    cars, bottoming) once the car's RM_CAR_STATE_FINISH is set."""
    return not finished(st, cp, i)


@numba.njit(inline="always", **_JIT)
def cross_forward(st, cp, i):
    """Car i has just crossed the start line forward (ReManage's start-line rule): after a
    backward crossing it only takes that back; a finished car's crossing is not counted and ends
    the race (every car is then finished); else a lap more, with its lap time from the second
    crossing on (the first, from the grid, starts lap 1: its timer runs from the race start)."""
    if st[i, S_BACK] > 0.0:
        st[i, S_BACK] -= 1.0
    elif finished(st, cp, i):
        st[i, S_BACK] -= 1.0          # not counted: the distance raced goes on
        cp[i, C_FINISH] = FINISH_ENDED
    else:
        st[i, S_LAPS] += 1.0
        if st[i, S_LAPS] > 1.0:
            lap = st[i, S_TIME] - st[i, S_LAPSTART]
            st[i, S_LASTLAP] = lap
            if st[i, S_BESTLAP] == 0.0 or lap < st[i, S_BESTLAP]:
                st[i, S_BESTLAP] = lap
            st[i, S_LAPSTART] = st[i, S_TIME]


@numba.njit(inline="always", **_JIT)
def finish_rule(st, cp, a, b):
    """The finish of cars a..b-1 (one race) at a tick's start. Once any car is past FINISH_ENDED
    (a finished car crossed again) every car gets it. Else, once a car has finished, each car not
    yet finished gets C_FINISH = its next crossing, or its crossings now if its last one came at
    or after the first finisher's (both from their lap start times; a car on its first lap has
    none, and its grid crossing counts as earlier)."""
    ended = False
    t_first = 1e300
    for i in range(a, b):
        finish = cp[i, C_FINISH]
        if finish < 0.0:
            ended = True
        elif finish > 0.0 and st[i, S_LAPS] >= finish:
            t_first = min(t_first, st[i, S_LAPSTART])
    if ended:
        for i in range(a, b):
            cp[i, C_FINISH] = FINISH_ENDED
    elif t_first < 1e300:
        for i in range(a, b):
            laps = st[i, S_LAPS]
            if cp[i, C_FINISH] > laps:
                late = laps > 1.0 and st[i, S_LAPSTART] >= t_first
                cp[i, C_FINISH] = laps if late else laps + 1.0
