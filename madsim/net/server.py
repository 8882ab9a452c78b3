"""A drop-in scr_server: one UDP port per car, SCR identification, the tick loop, restart and
end-of-race messages (spec/scr-protocol.md sections 1-4, 7, 12, 14).

`ScrServer` owns the sockets and the race loop; the World (physics) and the SensorSuite
(sensor semantics) do the work, `madsim.net.protocol` does the bytes. Clock modes:
- `sync`: wait for every client's reply each tick (deterministic, as fast as the clients);
  stale datagrams are drained before each state is sent; a client silent for longer than
  `client_deadline_s` is switched to timeout behaviour with a warning.
- `timeout`: TORCS's behaviour: per car in turn, send, wait up to `timeout_ms`, read exactly
  one datagram (no draining), reuse the previous controls on silence.
- `realtime`: like sync, but each tick lasts 20 ms of wall time; silence reuses controls.

Departure from TORCS, on purpose: during a race only datagrams from the identified client's
address are read as its controls; others are counted as foreign and dropped, so stray traffic
cannot steer a car. Stock clients send from the socket they identified with, so they see no
difference.
"""

from __future__ import annotations

import csv
import os
import select
import socket
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from madsim.net import protocol as P
from madsim.physics.sensors import FOCUS_NONE, SensorSuite

TICK_S = 0.02
MODES = ("sync", "timeout", "realtime")
COUNTDOWN_TICKS = 49          # TORCS polls robots ~49 times during the start countdown (§4.3)
MAX_DAMAGE = 10000.0          # a car above this is out of the race (TORCS default)
CSV_FIELDS = ("tick", "time", "car", "x", "y", "yaw", "distFromStart", "trackPos", "angle",
              "speedX", "speedY", "rpm", "gear", "laps", "curLapTime", "lastLapTime", "damage",
              "steer", "accel", "brake", "clutch")


class ServerError(RuntimeError):
    """The server cannot run (ports taken, clients never came)."""


@dataclass
class ServerStats:
    """Counters reported at the end: datagrams by kind, timeouts, restarts, ticks."""

    ticks: int = 0
    races: int = 0
    restarts: int = 0
    bad_datagrams: int = 0        # not well-formed control messages (still applied, as TORCS)
    foreign_datagrams: int = 0    # from an address other than the car's client: dropped
    ignored_datagrams: int = 0    # non-identification datagrams before the race: no reply
    drained_datagrams: int = 0    # extra replies dropped in sync mode
    timeouts: int = 0             # ticks on which a car's controls were reused
    laps: list = field(default_factory=list)   # (race, car, lap, lap time s)


class _Car:
    """One scr_server instance: its socket, client address and last controls."""

    def __init__(self, index: int, sock: socket.socket):
        self.index = index
        self.sock = sock
        self.addr: tuple | None = None
        self.controls = np.zeros(5)        # steer, accel, brake, gear, clutch; before any answer: 0
        self.focus: int | None = 0             # focus angle of the last control message (deg)
        self.sync = True                   # False once dropped to timeout behaviour
        self.angles = P.DEFAULT_ANGLES_DEG


class ScrServer:
    """Serve one World to N SCR clients over UDP on host:port+i.

    `make_world(seed)` builds a fresh World (called at start and after every restart, so a
    restarted race with the same seed is bit-identical).
    """

    def __init__(self, make_world: Callable[[int], object], n_clients: int, *, host: str = "127.0.0.1",
                 port: int = 3001, mode: str = "sync", timeout_ms: float = 10.0, noisy: bool = False,
                 identified_reply: str = "plain", seed: int = 0, laps: int | None = None,
                 max_ticks: int | None = None, countdown_ticks: int = COUNTDOWN_TICKS,
                 start_timeout_s: float | None = None, client_deadline_s: float = 5.0,
                 log: Callable[[str], None] | None = None, log_csv: str | os.PathLike | None = None,
                 pid: int | None = None):
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        if identified_reply not in ("plain", "pid"):
            raise ValueError(f"identified_reply must be 'plain' or 'pid', got {identified_reply!r}")
        if n_clients < 1:
            raise ValueError("need at least one client")
        self.make_world = make_world
        self.n = int(n_clients)
        self.host, self.port, self.mode = host, int(port), mode
        self.timeout_s = float(timeout_ms) / 1000.0
        self.noisy = bool(noisy)
        self.reply = P.identified_reply(pid if pid is not None else os.getpid()) \
            if identified_reply == "pid" else P.identified_reply(None)
        self.seed = int(seed)
        self.laps = laps
        self.max_ticks = max_ticks
        self.countdown_ticks = int(countdown_ticks)
        self.start_timeout_s = start_timeout_s
        self.client_deadline_s = float(client_deadline_s)
        self.log = log or (lambda msg: None)
        self.log_csv = log_csv
        self.stats = ServerStats()
        self._stop = False
        self.cars: list[_Car] = []
        self.world = None

    # --- sockets ----------------------------------------------------------------------------

    def open(self) -> None:
        """Bind one UDP socket per car (host:port+i)."""
        for i in range(self.n):
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            try:
                s.bind((self.host, self.port + i))
            except OSError as exc:
                s.close()
                self.close()
                raise ServerError(f"cannot bind UDP {self.host}:{self.port + i}: {exc.strerror or exc}") from None
            s.setblocking(False)
            self.cars.append(_Car(i, s))

    def close(self) -> None:
        for c in self.cars:
            c.sock.close()
        self.cars = []

    def stop(self) -> None:
        """Ask the loop to end after the current tick (thread-safe flag)."""
        self._stop = True

    def _send(self, car: _Car, data: bytes) -> None:
        if car.addr is not None:
            try:
                car.sock.sendto(data, car.addr)
            except OSError:
                pass  # client gone (ICMP unreachable); nothing to do over UDP

    def _recv(self, car: _Car):
        """One datagram from the car's socket: (data, addr) or None when nothing is queued."""
        try:
            return car.sock.recvfrom(65536)
        except (BlockingIOError, InterruptedError):
            return None
        except OSError:
            return None   # e.g. ECONNREFUSED echoed by the kernel for an earlier send

    # --- identification -----------------------------------------------------------------

    def identify_all(self) -> bool:
        """Block until every car's client has identified (§3). False if stopped / timed out."""
        for c in self.cars:
            c.addr = None
        waiting_since = last_note = time.monotonic()
        self.log(f"waiting for {self.n} client(s) on UDP ports {self.port}..{self.port + self.n - 1}")
        while any(c.addr is None for c in self.cars):
            if self._stop:
                return False
            now = time.monotonic()
            if self.start_timeout_s is not None and now - waiting_since > self.start_timeout_s:
                missing = [str(self.port + c.index) for c in self.cars if c.addr is None]
                raise ServerError(f"no client identified on port(s) {', '.join(missing)} within "
                                  f"{self.start_timeout_s:g} s")
            if now - last_note > 5.0:
                missing = [str(self.port + c.index) for c in self.cars if c.addr is None]
                self.log(f"still waiting for clients on port(s) {', '.join(missing)}")
                last_note = now
            socks = [c.sock for c in self.cars if c.addr is None]
            ready, _, _ = select.select(socks, [], [], 0.2)
            for c in self.cars:
                if c.sock not in ready:
                    continue
                while (got := self._recv(c)) is not None:
                    data, addr = got
                    init = P.parse_init(data)
                    if init is None or c.addr is not None:
                        self.stats.ignored_datagrams += 1
                        continue
                    c.addr = addr
                    c.angles = init.angles_deg
                    c.controls = np.zeros(5)
                    c.sync = True
                    c.focus = 0
                    c.sock.sendto(self.reply, addr)
                    self.log(f"client {init.client_id!r} identified on port {self.port + c.index} from {addr[0]}:{addr[1]}")
        return True

    # --- the race -----------------------------------------------------------------------

    def serve(self) -> ServerStats:
        """Run races until the end of a race, a stop request or Ctrl-C; returns the counters."""
        if not self.cars:
            self.open()
        writer = None
        csv_file = None
        if self.log_csv is not None:
            csv_file = open(self.log_csv, "w", newline="")
            writer = csv.writer(csv_file)
            writer.writerow(CSV_FIELDS)
        try:
            while not self._stop:
                if not self.identify_all():
                    break
                outcome = self._race(writer)
                if outcome != "restart":
                    break
        except KeyboardInterrupt:
            self.log("interrupted: shutting down")
            for c in self.cars:
                self._send(c, P.SHUTDOWN_MESSAGE)
        finally:
            if csv_file is not None:
                csv_file.close()
            self.close()
        return self.stats

    def _race(self, writer) -> str:
        """One race from the grid; returns 'restart', 'end' or 'stopped'."""
        self.world = world = self.make_world(self.seed)
        self.stats.races += 1
        suite = SensorSuite(world, noisy=self.noisy, rng=np.random.default_rng([self.seed, 1]))
        for c in self.cars:
            suite.set_angles(c.index, c.angles)
        active = np.ones(self.n, dtype=bool)
        last_laps = np.zeros(self.n, dtype=np.int64)
        countdown = self.countdown_ticks
        tick = 0
        while True:
            if self._stop:
                for c in self.cars:
                    self._send(c, P.SHUTDOWN_MESSAGE)
                return "stopped"
            frame = suite.frame()
            if countdown > 0:
                frame.curLapTime[:] = -TICK_S * countdown
                frame.gear[:] = 0
                frame.focus[:] = -1.0
            finished = self._race_over(world, tick, active)
            for c in self.cars:
                if active[c.index]:
                    self._send(c, self._encode(frame, c.index))
            if finished:
                for c in self.cars:
                    self._send(c, P.SHUTDOWN_MESSAGE)
                self._final_table(world)
                return "end"
            restart_by = self._collect(active)
            controls = np.array([c.controls for c in self.cars])
            focus = [c.focus for c in self.cars]
            suite.request_focus(np.arange(self.n), np.array([f if f is not None else FOCUS_NONE
                                                             for f in focus], dtype=np.float64))
            if writer is not None:
                self._write_csv(writer, tick, world, frame, controls)
            if countdown > 0:
                countdown -= 1
            else:
                world.step(controls)
                self.stats.ticks += 1
                tick += 1
                self._log_laps(world, last_laps)
                active &= world.column("damage") <= MAX_DAMAGE
            if restart_by is not None:
                self.stats.restarts += 1
                self.log(f"restart requested by the client of car {restart_by}")
                for c in self.cars:
                    self._send(c, P.RESTART_MESSAGE if c.index == restart_by else P.SHUTDOWN_MESSAGE)
                return "restart"

    def _encode(self, frame, k: int) -> bytes:
        try:
            return P.encode_sensors(frame.row(k))
        except P.ProtocolError:
            # only pathological values exceed 999 bytes; clip the noisy arrays and retry
            row = frame.row(k)
            for name in ("track", "opponents", "focus"):
                row[name] = [float(np.float32(round(v, 2))) for v in row[name]]
            return P.encode_sensors(row)

    def _race_over(self, world, tick: int, active: np.ndarray) -> bool:
        if self.max_ticks is not None and tick >= self.max_ticks:
            return True
        if not active.any():
            return True
        if self.laps is not None:
            done = world.column("laps")[active] > self.laps
            return bool(done.all())
        return False

    def _collect(self, active: np.ndarray) -> int | None:
        """Read this tick's controls per the clock mode; returns the car asking for restart."""
        cars = [c for c in self.cars if active[c.index]]
        got: dict[int, bytes] = {}
        start = time.monotonic()
        if self.mode == "timeout":
            for c in cars:   # TORCS polls in turn: exactly one datagram, no draining
                data = self._wait_one(c, time.monotonic() + self.timeout_s)
                if data is not None:
                    got[c.index] = data
        else:
            tick_end = start + TICK_S if self.mode == "realtime" else None

            def deadline(c: _Car) -> float:
                if tick_end is not None:
                    return tick_end
                return start + (self.client_deadline_s if c.sync else self.timeout_s)

            pending = {c.index: c for c in cars}
            while pending:
                wait = max(0.0, min(deadline(c) for c in pending.values()) - time.monotonic())
                ready, _, _ = select.select([c.sock for c in pending.values()], [], [], wait)
                for c in list(pending.values()):
                    if c.sock in ready and (data := self._read_from_client(c)) is not None:
                        got[c.index] = data
                        del pending[c.index]
                now = time.monotonic()
                for c in list(pending.values()):
                    if now >= deadline(c):
                        if c.sync and tick_end is None:
                            c.sync = False
                            self.log(f"warning: client of car {c.index} silent for {self.client_deadline_s:g} s "
                                     f"in sync mode; reusing its last controls, waiting {self.timeout_s * 1000:g} ms "
                                     f"per tick until it answers again")
                        del pending[c.index]
            if tick_end is not None and (rest := tick_end - time.monotonic()) > 0:
                time.sleep(rest)
        restart_by = None
        for c in cars:
            data = got.get(c.index)
            if data is None:
                self.stats.timeouts += 1
                continue
            c.sync = True  # it answered: wait for it again
            ctl = P.decode_controls(data)
            if not ctl.well_formed:
                self.stats.bad_datagrams += 1
            c.controls = np.array([ctl.steer, ctl.accel, ctl.brake, ctl.gear, ctl.clutch], dtype=np.float64)
            c.focus = ctl.focus
            if ctl.meta == 1 and restart_by is None:
                restart_by = c.index
        return restart_by

    def _read_from_client(self, c: _Car) -> bytes | None:
        """The next datagram from c's own client; foreign ones are counted and dropped. In sync
        mode extra queued replies (e.g. gym_torcs' double reply) are drained and counted."""
        first = None
        while (got := self._recv(c)) is not None:
            data, addr = got
            if addr != c.addr:
                self.stats.foreign_datagrams += 1
                continue
            if first is None:
                first = data
                if self.mode == "timeout":
                    break
            else:
                self.stats.drained_datagrams += 1
        return first

    def _wait_one(self, c: _Car, deadline: float) -> bytes | None:
        while True:
            wait = deadline - time.monotonic()
            if wait <= 0:
                return None
            ready, _, _ = select.select([c.sock], [], [], wait)
            if ready:
                data = self._read_from_client(c)
                if data is not None:
                    return data

    # --- reporting ----------------------------------------------------------------------

    def _log_laps(self, world, last_laps: np.ndarray) -> None:
        laps = world.column("laps").astype(np.int64)
        for i in np.nonzero(laps > last_laps)[0]:
            lap_time = float(world.column("last_lap_time")[i])
            if laps[i] >= 2 and lap_time > 0:
                self.stats.laps.append((self.stats.races, int(i), int(laps[i]) - 1, lap_time))
                self.log(f"car {i}: lap {int(laps[i]) - 1} in {lap_time:.3f} s, "
                         f"damage {int(world.column('damage')[i])}")
        last_laps[:] = laps

    def _final_table(self, world) -> None:
        self.log(f"race over after {self.stats.ticks} ticks")
        self.log(f"{'car':>3} {'laps':>4} {'best lap (s)':>12} {'last lap (s)':>12} {'damage':>6} {'pos':>3}")
        for i in range(self.n):
            best = world.column("best_lap_time")[i]
            last = world.column("last_lap_time")[i]
            self.log(f"{i:>3} {max(int(world.column('laps')[i]) - 1, 0):>4} "
                     f"{best:>12.3f} {last:>12.3f} {int(world.column('damage')[i]):>6} "
                     f"{int(np.asarray(world.race_pos)[i]):>3}")
        st = self.stats
        self.log(f"datagrams: {st.bad_datagrams} malformed, {st.foreign_datagrams} foreign, "
                 f"{st.ignored_datagrams} ignored before the start, {st.drained_datagrams} drained; "
                 f"{st.timeouts} reused controls")

    def _write_csv(self, writer, tick: int, world, frame, controls: np.ndarray) -> None:
        col = world.column
        t = world.time
        for i in range(self.n):
            writer.writerow([tick, f"{t:.3f}", i, f"{col('x')[i]:.4f}", f"{col('y')[i]:.4f}",
                             f"{col('yaw')[i]:.5f}", f"{frame.distFromStart[i]:.3f}",
                             f"{frame.trackPos[i]:.5f}", f"{frame.angle[i]:.5f}", f"{frame.speedX[i]:.3f}",
                             f"{frame.speedY[i]:.3f}", f"{frame.rpm[i]:.1f}", int(frame.gear[i]),
                             int(col("laps")[i]), f"{frame.curLapTime[i]:.3f}", f"{frame.lastLapTime[i]:.3f}",
                             int(frame.damage[i]), *(f"{v:.5f}" for v in controls[i])])
