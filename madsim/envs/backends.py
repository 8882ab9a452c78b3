"""Where an env's cars drive: a World in this process, or a simulator behind the SCR protocol.

A backend runs one episode at a time for the env; cars are addressed by row (traffic first,
then learners, see `madsim.envs.episode`). The contract:

    frame = backend.start(key, track, cars, placements, noisy=..., rng=...,
                          tick_schedule=...)                        # first sensors
    frame = backend.step(controls)      # controls (N, 5): steer, accel, brake, gear, clutch
    hits = backend.collisions()         # (N,) bool: contact during the last tick (a buffer
                                        # the next call overwrites), or None

Frames are `madsim.physics.sensors.SensorFrame`s (SCR units, one row per car); `step`
returns None when the simulator ended the race on its own. `check(cfg)` refuses, at env
construction, a scenario the backend cannot run. `tick_schedule` (server.tick_schedule) says
how far one `step` advances: "fixed" 0.02 s, "torcs" TORCS's 0.02-or-0.022 s driver calls
counted from `start` (`madsim.physics.schedule`).

Rangefinders point at MADRaS's angles (its snakeoil client's list, +-45 degrees, dense around
the heading): `RANGEFINDER_ANGLES_DEG`.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

from madsim.envs.config import ConfigError, ScenarioConfig
from madsim.facts import SNAKEOIL_ANGLES_DEG
from madsim.physics.schedule import make_clock
from madsim.physics.sensors import (
    N_VALUES,
    SENSOR_OFFSETS,
    SensorFrame,
    SensorSuite,
    apply_noise,
)

__all__ = ["RANGEFINDER_ANGLES_DEG", "LocalBackend", "ScrBackend"]

RANGEFINDER_ANGLES_DEG = SNAKEOIL_ANGLES_DEG


class LocalBackend:
    """The default: a `madsim.physics.world.World` in this process.

    Worlds are kept per (track entry, car names in row order), at most `max_worlds` (the
    least recently used is dropped): a reset with the same track and cars only resets the
    World (well under a millisecond); a new combination builds one (10-150 ms, most of it the
    contact solver's barrier segments). `World.reset` clears all state, so a reused World
    drives exactly like a fresh one. contact, fuel, damage: the World's options.
    """

    name = "local"

    def __init__(self, *, contact: bool = True, fuel: bool = False, damage: bool = True,
                 max_worlds: int = 16):
        if max_worlds < 1:
            raise ValueError(f"max_worlds must be >= 1, got {max_worlds}")
        self.contact, self.fuel, self.damage = bool(contact), bool(fuel), bool(damage)
        self.max_worlds = int(max_worlds)
        self._worlds: OrderedDict = OrderedDict()
        self.world = None
        self.suite = None
        self.clock = None          # None: fixed 0.02 s ticks; else the episode's TorcsClock
        self.worlds_built = 0

    def check(self, cfg: ScenarioConfig) -> None:
        """Everything a config can ask for runs locally."""

    def start(self, key, track, cars, placements, *, noisy: bool,
              rng: np.random.Generator, tick_schedule: str = "fixed") -> SensorFrame:
        from madsim.physics.world import World

        pair = self._worlds.pop(key, None)
        if pair is None:
            world = World(track, list(cars), np.random.default_rng(0), fuel=self.fuel,
                          damage=self.damage, contact=self.contact)
            suite = SensorSuite(world)
            for i in range(world.n_cars):
                suite.set_angles(i, RANGEFINDER_ANGLES_DEG)
            pair = (world, suite)
            self.worlds_built += 1
        self._worlds[key] = pair
        while len(self._worlds) > self.max_worlds:
            self._worlds.popitem(last=False)
        self.world, self.suite = pair
        self._hits = np.zeros(self.world.n_cars, dtype=bool)
        self.world.reset(placements)
        self.suite.reset()
        self.suite.noisy = bool(noisy)
        self.suite.rng = rng
        self.clock = None if tick_schedule == "fixed" else make_clock(tick_schedule)
        return self.suite.frame()

    def step(self, controls: np.ndarray) -> SensorFrame:
        if self.clock is None:
            self.world.step(controls)
        else:
            self.world.step(controls, self.clock.substeps())
        return self.suite.frame()

    def collisions(self) -> np.ndarray:
        w = self.world
        return np.logical_or(w.contact_wall, w.contact_car, out=self._hits)

    def close(self) -> None:
        self._worlds.clear()
        self.world = self.suite = None


class ScrBackend:
    """Cars of a running SCR server (`madsim serve`, or TORCS with scr_server robots) over UDP.

    One `madsim.net.client.ScrClient` per car, car row i on port `port + i` (MADRaS's slot
    order: traffic first, then learners), all answered in lock-step, so the server should run
    in sync mode (`madsim serve --mode sync`, TORCS `-t` large). What it supports, and what it
    cannot do because the server owns the race:
    - the server chooses track, cars and their number, and places them on its grid: the
      config must name one track (the one the server runs; the env uses it for the track
      length), one car per agent, a fixed traffic count and no initial_distance /
      initial_trackpos ranges; `check` refuses anything else;
    - countdown states (curLapTime < 0) are answered with the brakes on and skipped;
    - every reset after the first asks for a restart (meta 1); a server that cannot restart
      (MADRaS's TORCS fork) must be relaunched by the user;
    - observation noise is applied here, from the env's rng (leave the server's `--noisy` off);
    - contact flags do not travel over SCR: collisions are seen through `damage` only.
    host, port: the server's first car port; timeout_s, tries: per-wait timeout and how many
    silent waits before giving up (ScrTimeout).
    """

    name = "scr"

    def __init__(self, host: str = "127.0.0.1", port: int = 3001, *, timeout_s: float = 1.0,
                 tries: int = 30, client_id: str = "SCR"):
        self.host, self.port = host, int(port)
        self.timeout_s, self.tries, self.client_id = float(timeout_s), int(tries), client_id
        self.clients: list = []
        self._noisy = False
        self._rng = None

    def check(self, cfg: ScenarioConfig) -> None:
        s = cfg.server
        if len(s.tracks) != 1:
            raise ConfigError("ScrBackend cannot choose the track: name exactly the one the "
                              "server runs", key="server.tracks", value=list(s.tracks))
        count = s.traffic_count
        if count is not None and count[0] != count[1]:
            raise ConfigError("ScrBackend needs a fixed number of cars (the server's)",
                              key="server.traffic_count", value=list(count))
        if any(a.car is None for a in cfg.agents) and len(s.cars) != 1:
            raise ConfigError("ScrBackend cannot choose cars: give one car", key="server.cars",
                              value=list(s.cars))
        for where, entries in (("agents", cfg.agents), ("traffic", cfg.traffic)):
            for i, e in enumerate(entries):
                for name in ("initial_distance", "initial_trackpos"):
                    if getattr(e, name) is not None:
                        raise ConfigError("ScrBackend cannot place cars (the server uses "
                                          "its grid)", key=f"{where}[{i}].{name}",
                                          value=list(getattr(e, name)))
        if s.grid is not None:
            raise ConfigError("ScrBackend cannot place cars: give the grid to the server "
                              "(madsim serve --grid)", key="server.grid")
        if s.tick_schedule != "fixed":
            raise ConfigError("ScrBackend runs on the server's clock: start the server with "
                              "--tick-schedule instead", key="server.tick_schedule",
                              value=s.tick_schedule)

    def start(self, key, track, cars, placements, *, noisy: bool,
              rng: np.random.Generator, tick_schedule: str = "fixed") -> SensorFrame:
        from madsim.net.client import ScrClient

        n = len(cars)
        if self.clients and len(self.clients) == n and all(c.identified for c in self.clients):
            self._restart()
        else:
            self.close()
            self.clients = [ScrClient(self.host, self.port + i, client_id=self.client_id,
                                      angles_deg=RANGEFINDER_ANGLES_DEG,
                                      timeout_s=self.timeout_s, identify_tries=self.tries,
                                      silent_tries=self.tries) for i in range(n)]
        for c in self.clients:
            c.identify()
        self._noisy, self._rng = bool(noisy), rng
        states = self._receive()
        while states is not None and any(s.get("curLapTime", 0.0) < 0.0 for s in states):
            self._send_all(np.tile([0.0, 0.0, 1.0, 0.0, 0.0], (n, 1)))
            states = self._receive()
        if states is None:
            raise ConnectionError(f"the SCR server on {self.host}:{self.port} ended the race "
                                  "before it started")
        return self._frame(states)

    def step(self, controls: np.ndarray) -> SensorFrame | None:
        self._send_all(controls)
        states = self._receive()
        return None if states is None else self._frame(states)

    def collisions(self) -> None:
        return None

    def close(self) -> None:
        for c in self.clients:
            c.close()
        self.clients = []

    # --- internals -------------------------------------------------------------------------

    def _send_all(self, controls: np.ndarray, meta_car: int | None = None) -> None:
        for i, c in enumerate(self.clients):
            u = controls[i]
            c.send({"steer": float(u[0]), "accel": float(u[1]), "brake": float(u[2]),
                    "gear": round(float(u[3])), "clutch": float(u[4]), "focus": 0,
                    "meta": 1 if i == meta_car else 0})

    def _receive(self) -> list[dict] | None:
        states = [c.receive() for c in self.clients]
        return None if any(s is None for s in states) else states

    def _restart(self) -> None:
        """Ask for a new race (meta 1 from car 0) and wait for every client's end message."""
        brake = np.tile([0.0, 0.0, 1.0, 0.0, 0.0], (len(self.clients), 1))
        self._send_all(brake, meta_car=0)
        for c in self.clients:
            while c.identified:
                if c.receive() is None:
                    break

    def _frame(self, states: list[dict]) -> SensorFrame:
        flat = np.zeros((len(states), N_VALUES))
        for k, state in enumerate(states):
            for name, (o, w) in SENSOR_OFFSETS.items():
                value = state.get(name)
                if value is not None:
                    flat[k, o:o + w] = value
        frame = SensorFrame(flat, np.arange(len(states)))
        if self._noisy:
            apply_noise(frame, self._rng)
        return frame
