"""Compiled traffic driving: one call computes the controls of every traffic car of a batch.

What `madsim.agents.traffic` documents (the T-S PID towards a lane and speed, collision
avoidance from the opponents sensor, the off-track guard, curvature observer and feed-forward,
and the targets of the six built-in behaviours) is computed here, car by car, over arrays with
the car axis first:

- `sens` (n, 79): SCR sensor rows in wire order (madsim.physics.sensors), `ctrl` (n, >= 4):
  steer, accel, brake, gear written for the processed rows; `rows` (m,) the rows to process;
- `kind` (n,): what drives each row (K_* below; K_NONE and K_FOREIGN rows are skipped);
- `S` (n, NS) per-car state, `P` (n, NP) per-car parameters, `lanes` (n, MAX_LANES) the lanes
  of RandomLaneSwitch, `rand` (n, RAND_BUF) draws taken from each car's generator in advance
  (RandomStopping: uniform doubles; RandomLaneSwitch: lane indices), consumed at `S[:, RAND_AT]`.

A boolean state such as "not seen yet" is a 0/1 float column. `S[:, EVENT]` tells the caller
what to record for the episode info after the call (EV_LANE: a lane draw, EV_STOP: a halt
began, value in `S[:, EVENT_VALUE]`, time in `S[:, T_S]`); EV_TARGET marks a K_USER car
whose target the caller computes in Python before `drive_user` finishes it.
The arithmetic follows the Python it replaced operation for operation (min/max as Python's).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from madsim.agents.pid import (
    CTRL_PARAMS,
    CTRL_STATE,
    SPEED_GEAR_KMH,
    observe,
    pid_controls,
    py_max,
    py_min,
)
from madsim.physics.kernel import NO_REFCOUNT
from madsim.physics.sensors import O_ANGLE, O_CURLAP, O_DFS, O_DRACED, O_OPP, O_SX, O_TPOS, O_TRACK

# kinds
K_NONE, K_CONST_VEL, K_SINUSOIDAL, K_LANE_SWITCH, K_STOPPING, K_PARK, K_PARKED, K_USER, \
    K_FOREIGN = range(9)

# state columns
(TICKS, STEER, KAPPA, ANGLE_PREV, HAS_ANGLE_PREV, LANE_CMD, HAS_LANE_CMD, DIST0, HAS_DIST0, DFS0,
 DFS_PREV, TRAVELLED, HALF_WIDTH, TRACK_LENGTH) = range(14)
S_PID = 14                   # the controller's state block (madsim.agents.pid, CTRL_STATE values)
(LANE, HAS_LANE, WANTED, DRAWS, STAND_S, STANDING, PARKED, TO_GO, HAS_TO_GO, RAND_AT, EVENT,
 EVENT_VALUE, T_S, TARGET_LANE, TARGET_SPEED) = range(S_PID + CTRL_STATE, S_PID + CTRL_STATE + 15)
NS = S_PID + CTRL_STATE + 15
EV_NONE, EV_LANE, EV_STOP, EV_TARGET = 0.0, 1.0, 2.0, 3.0

# parameter columns
(WINDOW_S, MIN_SAFE, LENGTH, WIDTH, WHEELBASE, REAR_AXLE, STEER_LOCK, TICK) = range(8)
P_PID = 8                    # the controller's parameter block (CTRL_PARAMS values)
(SPEED, LANE_P, MEAN, AMPLITUDE, PERIOD, INTERVAL, N_LANES, STOP_P, MAX_STOP, PARK_LANE,
 PARK_DISTANCE) = range(P_PID + CTRL_PARAMS, P_PID + CTRL_PARAMS + 11)
NP = P_PID + CTRL_PARAMS + 11
MAX_LANES = 16
RAND_BUF = 64

RAYS_READ = np.array([0, 7, 8, 9, 10, 11, 18], dtype=np.int64)
"""The rangefinder rays (indices into `track`) the built-in behaviours read (`_observe`: 0 and
18; `_gaps_ahead`: 9; `_drive`: 7-11): a door may cast only these for its compiled traffic cars
(`SensorSuite.cast_only`, `WorldBatch.cast_only`)."""
COMPILED_KINDS = (K_CONST_VEL, K_SINUSOIDAL, K_LANE_SWITCH, K_STOPPING, K_PARK, K_PARKED)
"""The kinds driven by compiled code alone (K_USER's target and K_FOREIGN read every ray)."""

KMH = 3.6
NO_CAR_M = 200.0
FRONT_SIDE_SECTORS = 9       # FRONT_CONE_DEG = 90: sectors 9..26
LATERAL_MARGIN_M = 0.4
PLAN_DECEL = 3.0
LAT_ACCEL = 4.0
LANE_SPEED = 1.0
CURVATURE_TAU_S = 0.25
HOLD_SPEED = 0.3
GUARD_HORIZON_S = 0.5
GUARD_SPEED = 3.0
CREEP_SPEED = 1.0
CREEP_GAP_M = 0.3
STOP_TOLERANCE_M = 0.25

# (cos, sin) of five bearings spanning each opponents sector j, [(j - 18) * 10, (j - 17) * 10] deg
SUB_BEARINGS = np.array([[[math.cos(math.radians((j - 18) * 10.0 + 2.5 * k)),
                           math.sin(math.radians((j - 18) * 10.0 + 2.5 * k))] for k in range(5)]
                         for j in range(36)])


@njit(cache=True, inline="always")
def _wrap(a):
    return (a + math.pi) % (2.0 * math.pi) - math.pi


@njit(cache=True)
def _observe(sens, S, P, r):
    """Road half width (if not known), odometry and the curvature observer."""
    tpos, angle = sens[r, O_TPOS], sens[r, O_ANGLE]
    if S[r, HALF_WIDTH] == 0.0 and abs(tpos) < 1.0 and sens[r, O_TRACK] > 0 \
            and sens[r, O_TRACK + 18] > 0:
        S[r, HALF_WIDTH] = 0.5 * (sens[r, O_TRACK] + sens[r, O_TRACK + 18]) * abs(math.cos(angle))
    dist, dfs = sens[r, O_DRACED], sens[r, O_DFS]
    if S[r, HAS_DIST0] == 0.0:
        S[r, DIST0], S[r, DFS0], S[r, HAS_DIST0] = dist, dfs, 1.0
    elif S[r, TRACK_LENGTH] == 0.0 and dfs < S[r, DFS_PREV] - 50.0:      # crossed the line
        S[r, TRACK_LENGTH] = S[r, DFS0] + (dist - S[r, DIST0]) - dfs
    S[r, DFS_PREV] = dfs
    S[r, TRAVELLED] = dist - S[r, DIST0]
    v = sens[r, O_SX] / KMH
    tick = P[r, TICK]
    if S[r, HAS_ANGLE_PREV] != 0.0 and v > 2.0:
        # d(angle)/dt = kappa_road * v - yaw rate, yaw rate = v * tan(wheel angle) / wheelbase
        kappa_car = math.tan(S[r, STEER] * P[r, STEER_LOCK]) / P[r, WHEELBASE]
        raw = kappa_car + _wrap(angle - S[r, ANGLE_PREV]) / (v * tick)
        S[r, KAPPA] += py_min(1.0, tick / CURVATURE_TAU_S) * (raw - S[r, KAPPA])
    S[r, ANGLE_PREV], S[r, HAS_ANGLE_PREV] = angle, 1.0


@njit(cache=True)
def _side_clear(sens, P, r, to_left):
    """No car within two car lengths beside, 170 deg behind to 10 deg ahead, on that side."""
    reach = 2.0 * P[r, LENGTH]
    first = 1 if to_left else 19
    for j in range(first, first + 16):
        if not sens[r, O_OPP + j] >= reach:
            return False
    return True


@njit(cache=True)
def _target(sens, S, P, lanes, rand, kind, r, t_s):
    """(lane in trackPos units, speed m/s; <= 0: stop) of a built-in behaviour."""
    if kind == K_CONST_VEL:
        return P[r, LANE_P], P[r, SPEED]
    if kind == K_SINUSOIDAL:
        return P[r, LANE_P], P[r, MEAN] + P[r, AMPLITUDE] * math.sin(
            2.0 * math.pi * t_s / P[r, PERIOD])
    if kind == K_LANE_SWITCH:
        if t_s >= S[r, DRAWS] * P[r, INTERVAL] - 1e-9:
            i = int(S[r, RAND_AT])
            S[r, RAND_AT] = i + 1
            S[r, WANTED] = lanes[r, int(rand[r, i])]
            S[r, DRAWS] += 1.0
            S[r, EVENT], S[r, EVENT_VALUE] = EV_LANE, S[r, WANTED]
        if S[r, HAS_LANE] == 0.0:
            S[r, LANE], S[r, HAS_LANE] = sens[r, O_TPOS], 1.0
        wanted = S[r, WANTED]
        if wanted != S[r, LANE] and _side_clear(sens, P, r, wanted > S[r, LANE]):
            S[r, LANE] = wanted
        return S[r, LANE], P[r, SPEED]
    if kind == K_STOPPING:
        if S[r, STANDING] == 0.0:
            i = int(S[r, RAND_AT])
            if rand[r, i] < P[r, STOP_P]:
                S[r, STAND_S] = P[r, MAX_STOP] * (1.0 - rand[r, i + 1])    # (0, max]
                S[r, STANDING] = 1.0
                S[r, RAND_AT] = i + 2
                S[r, EVENT], S[r, EVENT_VALUE] = EV_STOP, S[r, STAND_S]
            else:
                S[r, RAND_AT] = i + 1
        if S[r, STANDING] != 0.0:
            if sens[r, O_SX] / KMH < HOLD_SPEED:
                S[r, STAND_S] -= P[r, TICK]
                if S[r, STAND_S] <= 0.0:
                    S[r, STANDING] = 0.0
            if S[r, STANDING] != 0.0:
                return P[r, LANE_P], 0.0
        return P[r, LANE_P], P[r, SPEED]
    if kind == K_PARK:
        rem = math.inf
        if S[r, HAS_TO_GO] == 0.0:
            d = P[r, PARK_DISTANCE] - S[r, DFS0]
            length = S[r, TRACK_LENGTH]
            if not (d < 0.0 and length == 0.0):
                S[r, TO_GO] = d % length if length != 0.0 else d
                S[r, HAS_TO_GO] = 1.0
        if S[r, HAS_TO_GO] != 0.0:
            rem = S[r, TO_GO] - S[r, TRAVELLED]
        if S[r, PARKED] == 0.0 and (rem <= STOP_TOLERANCE_M or (
                rem < 1.0 and sens[r, O_SX] / KMH < HOLD_SPEED)):
            S[r, PARKED] = 1.0
        if S[r, PARKED] != 0.0:
            return P[r, PARK_LANE], 0.0
        speed = py_min(P[r, SPEED], math.sqrt(2.0 * PLAN_DECEL * py_max(rem, 0.0)))
        return P[r, PARK_LANE], py_max(speed, 0.5)
    return sens[r, O_TPOS], 0.0           # K_PARKED


@njit(cache=True)
def _gaps_ahead(sens, S, P, r, lane_a, lane_b, max_range_m):
    """Bumper gaps (m) to the nearest car ahead surely / possibly in the own path (see
    TrafficBehaviour.gaps_ahead)."""
    tpos, heading = sens[r, O_TPOS], sens[r, O_ANGLE]
    hw, kappa = S[r, HALF_WIDTH], S[r, KAPPA]
    length = P[r, LENGTH]
    reach = P[r, WIDTH] + LATERAL_MARGIN_M
    lo_s = hi_s = 0.0
    if hw != 0.0:
        sa, sb = (lane_a - tpos) * hw, (lane_b - tpos) * hw
        lo_s = py_min(py_min(lo_s, sa), sb)
        hi_s = py_max(py_max(hi_s, sa), sb)
    lo_edge, hi_edge = lo_s - reach, hi_s + reach
    # road curvatures to allow for: 0 .. estimate, cut to what the free ray ahead allows
    k_lo, k_hi = py_min(0.0, kappa), py_max(0.0, kappa)
    ahead = sens[r, O_TRACK + 9]
    if ahead > 0.0 and hw != 0.0:
        y0 = tpos * hw - heading * ahead
        ray_lo, ray_hi = 2.0 * (y0 - hw) / ahead ** 2, 2.0 * (y0 + hw) / ahead ** 2
        k_lo, k_hi = py_max(k_lo, ray_lo), py_min(k_hi, ray_hi)
        if k_lo > k_hi:
            k_lo = k_hi = py_min(py_max(kappa, ray_lo), ray_hi)
    cos_h, sin_h = math.cos(heading), math.sin(heading)
    max_range_m = py_min(max_range_m, NO_CAR_M)
    sure = possible = math.inf
    for j in range(18 - FRONT_SIDE_SECTORS, 18 + FRONT_SIDE_SECTORS):
        d = sens[r, O_OPP + j]
        if d >= max_range_m or d <= 0.0:
            continue
        for step in range(5):                                   # across the sector
            cos_b, sin_b = SUB_BEARINGS[j, step, 0], SUB_BEARINGS[j, step, 1]
            x = d * (cos_b * cos_h - sin_b * sin_h)             # along the road
            y = -d * (sin_b * cos_h + cos_b * sin_h)            # to the left
            if x <= 0.0:
                continue
            e_hi, e_lo = y - k_lo * 0.5 * x * x, y - k_hi * 0.5 * x * x
            if e_lo <= hi_edge and e_hi >= lo_edge:
                possible = py_min(possible, x - length)
                if step == 2 and lo_edge <= e_lo and e_hi <= hi_edge:
                    sure = py_min(sure, x - length)
    return sure, possible


@njit(cache=True)
def _drive(sens, S, P, ctrl, r, lane, speed):
    """Controls towards (lane, speed): collision avoidance, guard, bends, the T-S PID."""
    v = sens[r, O_SX] / KMH
    tpos, angle = sens[r, O_TPOS], sens[r, O_ANGLE]
    hw, kappa = S[r, HALF_WIDTH], S[r, KAPPA]
    min_safe, window = P[r, MIN_SAFE], P[r, WINDOW_S]
    if S[r, HAS_LANE_CMD] == 0.0:
        S[r, LANE_CMD], S[r, HAS_LANE_CMD] = py_max(-1.0, py_min(1.0, tpos)), 1.0
    step = LANE_SPEED * P[r, TICK] / (hw if hw != 0.0 else 5.0)
    S[r, LANE_CMD] += py_max(-step, py_min(step, lane - S[r, LANE_CMD]))
    lane_des = S[r, LANE_CMD]
    stopping = speed <= 0.0
    relevant = P[r, LENGTH] + min_safe + window * py_max(speed, v) + 5.0
    sure, possible = _gaps_ahead(sens, S, P, r, lane, lane_des, relevant)
    creep = CREEP_SPEED if possible > CREEP_GAP_M else 0.0
    # speed the road allows: stop before the edge ahead, limit the corner acceleration
    ahead = sens[r, O_TRACK + 7]
    for i in range(8, 12):
        ahead = py_max(ahead, sens[r, O_TRACK + i])
    cap = math.inf
    if ahead > 0.0:
        cap = math.sqrt(2.0 * PLAN_DECEL * py_max(ahead - min_safe, 0.0))
    if abs(kappa) > 1e-6:
        cap = py_min(cap, math.sqrt(LAT_ACCEL / abs(kappa)))
    cap = py_max(cap, GUARD_SPEED)
    v_des = py_min(py_min(py_min(py_max(speed, 0.0), cap), py_max(0.0, (sure - min_safe) / window)),
                 py_max(creep, (possible - min_safe) / window))
    blocked = sure < min_safe or possible < CREEP_GAP_M
    # off-track guard: steer back towards the road, not towards the nearer edge
    cut = False
    if abs(tpos) >= 1.0:
        lane_des = 0.0
        v_des = py_min(v_des, GUARD_SPEED)
    else:
        side = 1.0 if tpos > 0.0 else -1.0
        edge_m = (1.0 - abs(tpos)) * (hw if hw != 0.0 else 1.0)
        outward = -side * v * math.sin(angle)             # m/s towards the near edge
        inside = abs(tpos) - 0.3
        if edge_m < outward * GUARD_HORIZON_S:
            lane_des = side * (py_max(lane_des * side, inside) if lane_des * side < abs(tpos)
                               else inside)
            cut = True
        elif edge_m < min_safe and lane_des * side < abs(tpos) - 0.05:
            lane_des = side * py_max(lane_des * side, inside)
    # the PID sees the angle of the motion (kinematic sideslip atan(b kappa) in a bend)
    slip = math.atan(P[r, REAR_AXLE] * kappa)
    s, p = S[r], P[r]
    observe(s, S_PID, tpos, angle - slip, sens[r, O_SX])
    steer, accel, brake = pid_controls(s, S_PID, p, P_PID, lane_des, v_des * KMH)
    steer += math.atan(P[r, WHEELBASE] * kappa) / P[r, STEER_LOCK]
    steer = py_max(-1.0, py_min(1.0, steer))
    if stopping or cut:
        accel = 0.0
    if (stopping and v < HOLD_SPEED) or blocked:
        accel, brake = 0.0, 1.0
    if stopping and v < HOLD_SPEED:
        steer = 0.0
    S[r, STEER] = steer
    gear = 1.0
    for threshold in SPEED_GEAR_KMH:
        if sens[r, O_SX] > threshold:
            gear += 1.0
    ctrl[r, 0], ctrl[r, 1], ctrl[r, 2], ctrl[r, 3] = steer, accel, brake, gear


@njit(cache=True, **NO_REFCOUNT)
def traffic_tick(sens, ctrl, rows, kind, S, P, lanes, rand):
    """Controls of the coming tick for `rows` from their latest sensors; K_USER rows stop
    after the observer with EV_TARGET set (finish them with `drive_user`)."""
    for r in rows:
        k = kind[r]
        if k == K_NONE or k == K_FOREIGN:
            continue
        S[r, EVENT] = EV_NONE
        if sens[r, O_CURLAP] < 0.0:        # TORCS countdown: wait, the clock has not started
            ctrl[r, 0], ctrl[r, 1], ctrl[r, 2], ctrl[r, 3] = 0.0, 0.0, 1.0, 1.0
            continue
        t_s = S[r, TICKS] * P[r, TICK]
        S[r, TICKS] += 1.0
        S[r, T_S] = t_s
        _observe(sens, S, P, r)
        if k == K_USER:
            S[r, EVENT] = EV_TARGET
            continue
        lane, speed = _target(sens, S, P, lanes, rand, k, r, t_s)
        _drive(sens, S, P, ctrl, r, lane, speed)


@njit(cache=True, **NO_REFCOUNT)
def drive_user(sens, ctrl, rows, S, P):
    """Finish the K_USER rows of `traffic_tick` from the targets in S[:, TARGET_LANE/SPEED]."""
    for r in rows:
        _drive(sens, S, P, ctrl, r, S[r, TARGET_LANE], S[r, TARGET_SPEED])
