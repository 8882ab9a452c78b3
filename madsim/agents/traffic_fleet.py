"""`TrafficFleet`: the traffic cars of a batch as arrays, driven by one compiled call per tick.

Row r of a fleet is row r of the sensor and control arrays it is given (a World's cars, a
WorldBatch's rows over all episodes, or one UDP car). `put(r, behaviour)` takes a behaviour
after its `reset` (a `madsim.agents.traffic.TrafficBehaviour`; its state moves into the
fleet's rows, its attributes read them from there); any other object with `act(row)` (the
env's `traffic_factory` hook) is driven in Python, row by row. `act(sensors, controls, rows)`
writes steer, accel, brake, gear of `rows` for the coming tick.

Cost per tick: one kernel call (~0.2 us per built-in car), plus, in Python, the random
draws taken 64 at a time per car, one info entry per recorded lane draw or halt, one
`target` call per car of a user-defined behaviour (~5-10 us) and one `act` per foreign object.
"""

from __future__ import annotations

import numpy as np

from madsim.agents import traffic_kernel as tk
from madsim.agents.sensor_row import SensorRow

__all__ = ["TrafficFleet"]

class TrafficFleet:
    """Arrays of `n` traffic rows (see the module docstring); rows without a car are skipped."""

    def __init__(self, n: int):
        self.n = n
        self.kind = np.zeros(n, dtype=np.int64)
        self.S = np.zeros((n, tk.NS))
        self.P = np.zeros((n, tk.NP))
        self.lanes = np.zeros((n, tk.MAX_LANES))
        self.rand = np.zeros((n, tk.RAND_BUF))
        self.objects: list = [None] * n
        self._random = np.zeros(n, dtype=bool)     # rows that draw while they drive
        self._n_python = 0                          # rows of K_USER or K_FOREIGN
        self._n_events = 0                          # rows that may report an event

    def clear(self, rows: slice) -> None:
        """Remove the cars of `rows`."""
        for r in range(self.n)[rows]:
            if self.objects[r] is not None:
                self._count(r, -1)
                self.objects[r] = None
        self.kind[rows] = tk.K_NONE
        self._random[rows] = False

    def put(self, r: int, obj) -> None:
        """Drive row r with `obj` (a reset TrafficBehaviour, or any object with act(row))."""
        self.clear(slice(r, r + 1))
        bind = getattr(obj, "_bind", None)
        if bind is not None:
            bind(self, r)
        else:
            self.kind[r] = tk.K_FOREIGN
        self._random[r] = self.kind[r] in (tk.K_LANE_SWITCH, tk.K_STOPPING)
        self._count(r, +1)
        self.objects[r] = obj

    def _count(self, r: int, sign: int) -> None:
        kind = self.kind[r]
        self._n_python += sign * (kind in (tk.K_USER, tk.K_FOREIGN))
        self._n_events += sign * (kind in (tk.K_USER, tk.K_LANE_SWITCH, tk.K_STOPPING))

    def compiled_only(self) -> bool:
        """True when `act` is `traffic_kernel.traffic_tick` alone: every car built-in, none
        that draws or reports (a compiled caller may then call it itself)."""
        return self._n_python == 0 and self._n_events == 0

    def act(self, sensors: np.ndarray, controls: np.ndarray, rows: np.ndarray) -> None:
        """Controls (steer, accel, brake, gear) of `rows` for the coming tick into
        controls[rows, :4], from sensors (n, 79) float64 in wire order."""
        if self._n_events:
            self._refill()
        tk.traffic_tick(sensors, controls, rows, self.kind, self.S, self.P, self.lanes, self.rand)
        if self._n_events:
            events = self.S[rows, tk.EVENT]
            if events.any():
                self._events(sensors, controls, rows[events != 0.0])
        if self._n_python:
            for r in rows[self.kind[rows] == tk.K_FOREIGN].tolist():
                steer, accel, brake, gear = self.objects[r].act(SensorRow(sensors[r]))
                controls[r, 0], controls[r, 1], controls[r, 2], controls[r, 3] = \
                    steer, accel, brake, gear

    def _refill(self) -> None:
        """Keep two draws ahead for every car that draws (the most one tick takes)."""
        at = self.S[:, tk.RAND_AT]
        for r in np.flatnonzero(self._random & (at > tk.RAND_BUF - 2)).tolist():
            i = int(at[r])
            keep = tk.RAND_BUF - i
            self.rand[r, :keep] = self.rand[r, i:].copy()
            self.rand[r, keep:] = self.objects[r]._draws(i)
            at[r] = 0.0

    def _events(self, sensors, controls, rows) -> None:
        S = self.S
        user = []
        for r in rows.tolist():
            event, t_s, obj = S[r, tk.EVENT], float(S[r, tk.T_S]), self.objects[r]
            if event == tk.EV_TARGET:
                lane, speed = obj.target(SensorRow(sensors[r]), t_s)
                S[r, tk.TARGET_LANE], S[r, tk.TARGET_SPEED] = float(lane), float(speed)
                user.append(r)
            else:
                obj._record(event, t_s, float(S[r, tk.EVENT_VALUE]))
        if user:
            tk.drive_user(sensors, controls, np.array(user, dtype=np.int64), self.S, self.P)
