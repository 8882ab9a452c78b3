"""A drop-in scr_server: one UDP port per car, SCR identification, the tick loop, restart and
end-of-race messages (spec/scr-protocol.md sections 1-4, 7, 12, 14).

`ScrServer` owns the sockets and the race loop; the World (physics) and the SensorSuite
(sensor semantics) do the work, `madsim.net.protocol` does the bytes. Clock modes:
- `sync`: wait for every client's reply each tick (deterministic, as fast as the clients);
  stale datagrams are drained before each state is sent (kept only if they ask for a restart),
  so an extra reply never shifts later commands; a client silent for longer than
  `client_deadline_s` is switched to timeout behaviour with a warning, and back to waiting as
  soon as it answers again (its newest late answer is used).
- `timeout`: TORCS's behaviour: per car in turn, send, wait up to `timeout_ms`, read exactly
  one datagram (no draining), reuse the previous controls on silence.
- `realtime`: like sync, but each tick lasts 20 ms of wall time; silence reuses controls (or
  the newest late answer).

Departure from TORCS, on purpose: during a race only datagrams from the identified client's
address are read as its controls; others are counted as foreign and dropped, so stray traffic
cannot steer a car. Stock clients send from the socket they identified with, so they see no
difference.
"""

from __future__ import annotations

import csv
import gc
import math
import os
import select
import socket
import struct
import threading
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from madsim.facts import TICK_S
from madsim.net import protocol as P
from madsim.physics.schedule import make_clock
from madsim.net.server_tick import DECODE, DONE, SENSE, STEP, ServerTick
from madsim.net.sync_loop import LIMIT, PENDING, STALE, SUPPORTED, TICK, SyncLoop
from madsim.physics.sensors import SensorFrame, SensorSuite
from madsim.physics.world import World

MODES = ("sync", "timeout", "realtime")
RECV_BYTES = 65536   # receive buffer per car: any UDP datagram fits (decoding reads 1000 bytes)
STOP_POLL_S = 0.2   # longest wait for a client before a stop() request is looked at again
COUNTDOWN_TICKS = 49          # TORCS polls robots ~49 times during the start countdown (§4.3)
MAX_DAMAGE = 10000.0          # a car above this is out of the race (TORCS default)


def lap_time_limit_s(track_length_m: float) -> float:
    """TORCS's lap-time limit: a robot's car whose current lap has lasted longer is out of the
    race (84.5 s + the track's length at 10 m/s; not turned off by the SCR build's -nolaptime,
    turned off by gym_torcs' vtorcs -nolaptime)."""
    return 84.5 + float(track_length_m) / 10.0
CSV_FIELDS = ("tick", "time", "car", "x", "y", "yaw", "distFromStart", "trackPos", "angle",
              "speedX", "speedY", "rpm", "gear", "laps", "curLapTime", "lastLapTime", "damage",
              "steer", "accel", "brake", "gear_request", "clutch")


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
    drained_datagrams: int = 0    # stale or extra replies dropped (sync / realtime modes)
    timeouts: int = 0             # ticks on which a car's controls were reused
    laps: list = field(default_factory=list)   # (race, car, lap, lap time s)


@dataclass
class _RaceState:
    """What one race's loop carries from tick to tick (per-car lists: cheaper than numpy for
    the usual few cars)."""

    race: ServerTick
    laps: list                    # laps per car, as last seen
    cars: list                    # the `_Car`s still in the race
    countdown: int                # start-countdown messages still to send
    python_ticks: int = 0         # world ticks stepped by Python (the loop's PENDING ones too)
    python_tick: bool = False     # the next tick goes through the Python loop
    fast: SyncLoop | None = None  # the compiled sync loop, where it applies

    @property
    def tick(self) -> int:
        """World ticks of the race so far; right even when a signal lands in the middle of
        the bookkeeping (the compiled loop counts its own in memory)."""
        return self.python_ticks + (self.fast.ticks_run if self.fast is not None else 0)


class _Car:
    """One scr_server instance: its socket and port, client address and last controls."""

    def __init__(self, index: int, sock: socket.socket, port: int, controls: np.ndarray, inbox: np.ndarray):
        self.index = index
        self.inbox = memoryview(inbox)     # receive buffer of its answers (a row of ScrServer._inbox)
        self.sock = sock
        self.port = port
        self.addr: tuple | None = None
        self.controls = controls           # (5,) view: steer, accel, brake, gear, clutch; 0 before any answer
        self.sync = True                   # False once dropped to timeout behaviour
        self.angles = P.DEFAULT_ANGLES_DEG


class ScrServer:
    """Serve one World to N SCR clients over UDP on host:port+i.

    `make_world(seed)` builds a fresh World (called before the clients identify, at start and
    after every restart, so a restarted race with the same seed is bit-identical). `ports`
    (optional, one per car) replaces the default port+i, e.g. for a TORCS race file whose
    scr_server indices have gaps. `tick_schedule`: "fixed" (every tick 0.02 s, the default) or
    "torcs" (TORCS's own driver calls, 0.02 or 0.022 s apart, `madsim.physics.schedule`).
    Sensor noise (`noisy`) draws from default_rng([seed, 1]). `lap_time_limit`: TORCS's removal
    of a car whose current lap has lasted longer than 84.5 s + track length / (10 m/s)
    (`lap_time_limit_s`; default off, as `torcs -nolaptime`). `compiled_loop` (default True):
    run the usual sync ticks in `madsim.net.sync_loop` (False: every tick through Python, the
    same bytes; for tests and comparisons).
    """

    def __init__(self, make_world: Callable[[int], object], n_clients: int, *, host: str = "127.0.0.1",
                 port: int = 3001, mode: str = "sync", timeout_ms: float = 10.0, noisy: bool = False,
                 identified_reply: str = "plain", seed: int = 0, laps: int | None = None,
                 max_ticks: int | None = None, countdown_ticks: int = COUNTDOWN_TICKS,
                 start_timeout_s: float | None = None, client_deadline_s: float = 5.0,
                 log: Callable[[str], None] | None = None, log_csv: str | os.PathLike | None = None,
                 pid: int | None = None, ports: list[int] | None = None, tick_schedule: str = "fixed",
                 compiled_loop: bool = True, lap_time_limit: bool = False):
        if mode not in MODES:
            raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
        if identified_reply not in ("plain", "pid"):
            raise ValueError(f"identified_reply must be 'plain' or 'pid', got {identified_reply!r}")
        if n_clients < 1:
            raise ValueError("need at least one client")
        self.make_world = make_world
        self.n = int(n_clients)
        self.host, self.port, self.mode = host, int(port), mode
        self.ports = [self.port + i for i in range(self.n)] if ports is None else [int(p) for p in ports]
        if len(self.ports) != self.n or len(set(self.ports)) != self.n:
            raise ValueError(f"ports must be {self.n} distinct numbers, got {ports}")
        self.timeout_s = float(timeout_ms) / 1000.0
        self.noisy = bool(noisy)
        self.reply = P.identified_reply(pid if pid is not None else os.getpid()) \
            if identified_reply == "pid" else P.identified_reply(None)
        self.seed = int(seed)
        self.laps = laps
        self.max_ticks = max_ticks
        self.countdown_ticks = int(countdown_ticks)
        self.clock = make_clock(tick_schedule)   # "fixed" 20 ms ticks or TORCS's 20/22 ms calls
        self.start_timeout_s = start_timeout_s
        self.client_deadline_s = float(client_deadline_s)
        self._rcvtimeo_s = min(self.client_deadline_s, STOP_POLL_S)   # one blocking read's longest wait
        self.compiled_loop = bool(compiled_loop)
        self.lap_time_limit = bool(lap_time_limit)
        self.log = log or (lambda msg: None)
        self.log_csv = log_csv
        self.stats = ServerStats()
        self._stop = False
        self.cars: list[_Car] = []
        self.world = None
        self._race_state = None       # the current race's _RaceState
        self._warm = False            # kernels loaded (warm_up ran) in this process
        self._poll = select.poll()    # the sockets, to see at once whether any datagram is queued
        self._behind = 0              # cars dropped to timeout behaviour (sync mode)

    # --- sockets ----------------------------------------------------------------------------

    def open(self) -> None:
        """Bind one UDP socket per car (host:port+i, or host:ports[i])."""
        self._controls = np.zeros((self.n, 5))
        self._inbox = np.zeros((self.n, RECV_BYTES), dtype=np.uint8)   # car i's answer: inbox[i, :inlen[i]]
        self._inlen = np.full(self.n, -1, dtype=np.int64)
        for i, port in enumerate(self.ports):
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            try:
                s.bind((self.host, port))
            except (OSError, OverflowError) as exc:
                s.close()
                self.close()
                raise ServerError(f"cannot bind UDP {self.host}:{port}: "
                                  f"{getattr(exc, 'strerror', None) or exc}") from None
            # blocking reads are ended by the kernel (one recvfrom per answer, no select) after
            # STOP_POLL_S at most, so a stop() is seen in time; every other read passes MSG_DONTWAIT
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVTIMEO, _timeval(self._rcvtimeo_s))
            self.cars.append(_Car(i, s, port, self._controls[i], self._inbox[i]))
            self._poll.register(s, select.POLLIN)

    def close(self) -> None:
        for c in self.cars:
            self._poll.unregister(c.sock)
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
            return car.sock.recvfrom(65536, socket.MSG_DONTWAIT)
        except (BlockingIOError, InterruptedError):
            return None
        except OSError:
            return None   # e.g. ECONNREFUSED echoed by the kernel for an earlier send

    # --- identification -----------------------------------------------------------------

    def identify_all(self) -> bool:
        """Block until every car's client has identified (§3). False if stopped / timed out."""
        for c in self.cars:
            c.addr = None
            c.sync = True
        self._behind = 0
        waiting_since = last_note = time.monotonic()
        self.log(f"waiting for {self.n} client(s) on UDP port(s) {_port_list(self.ports)}")
        while any(c.addr is None for c in self.cars):
            if self._stop:
                return False
            now = time.monotonic()
            if self.start_timeout_s is not None and now - waiting_since > self.start_timeout_s:
                missing = [str(c.port) for c in self.cars if c.addr is None]
                raise ServerError(f"no client identified on port(s) {', '.join(missing)} within "
                                  f"{self.start_timeout_s:g} s")
            if now - last_note > 5.0:
                missing = [str(c.port) for c in self.cars if c.addr is None]
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
                    c.controls[:] = 0.0
                    self._send(c, self.reply)
                    self.log(f"client {init.client_id!r} identified on port {c.port} from {addr[0]}:{addr[1]}")
        return True

    # --- the race -----------------------------------------------------------------------

    def serve(self) -> ServerStats:
        """Run races until the end of a race, a stop request or Ctrl-C; returns the counters.

        On a stop request or Ctrl-C every identified client gets `***shutdown***` and the
        summary of the race so far is logged; Ctrl-C does not propagate. Before the clients
        identify, the compiled kernels are loaded (`warm_up`) and the objects alive in this
        process are moved out of the garbage collector's reach (`gc.freeze`)."""
        if not self.cars:
            self.open()
        writer = None
        csv_file = None
        stopped = False
        try:
            if self.log_csv is not None:
                csv_file = open(self.log_csv, "w", newline="")
                writer = csv.writer(csv_file)
                writer.writerow(CSV_FIELDS)
            while not self._stop:
                if not self._warm:     # say what a long wait is (a compile), if there is one
                    notice = threading.Timer(3.0, self.log, ["compiling the race kernels (the first run "
                                             "after an install or a kernel edit: up to a minute; cached "
                                             "for later runs) ..."])
                    notice.daemon = True
                    notice.start()
                    try:
                        warm_up(self.make_world(self.seed), self.noisy)
                    finally:
                        notice.cancel()
                    self._warm = True
                world = self.make_world(self.seed)   # before the clients, as TORCS loads first
                # a full collection of the ~150k objects of numba, pymunk and the World takes
                # 0.1-0.15 s: do it now and exempt them from later ones (a race allocates only
                # short-lived objects), so no tick waits for the collector
                gc.collect()
                gc.freeze()
                if not self.identify_all():
                    break
                outcome = self._race(writer, world)
                if outcome != "restart":
                    stopped = outcome == "stopped"
                    break
        except KeyboardInterrupt:
            self.log("interrupted: shutting down")
            for c in self.cars:
                self._send(c, P.SHUTDOWN_MESSAGE)
            stopped = True
        finally:
            if csv_file is not None:
                csv_file.close()
            self.close()
        if stopped and self.world is not None:
            self._final_table(self.world, self._race_state.tick if self._race_state else 0, "race stopped")
        return self.stats

    def _race(self, writer, world) -> str:
        """One race of a fresh World from the grid; returns 'restart', 'end' or 'stopped'."""
        self.world = world
        self.stats.races += 1
        suite = SensorSuite(world, noisy=self.noisy, rng=np.random.default_rng([self.seed, 1]))
        for c in self.cars:
            suite.set_angles(c.index, c.angles)
        max_lap_s = lap_time_limit_s(world.track.length) if self.lap_time_limit else math.inf
        race = ServerTick(world, suite, self._controls, self._inbox, self._inlen, MAX_DAMAGE, max_lap_s)
        self.clock.reset()
        r = self._race_state = _RaceState(race, world.column("laps").tolist(), list(self.cars),
                                          self.countdown_ticks)
        race.run(SENSE, DONE, False, 0, r.countdown)
        # the usual sync ticks without Python in between (`sync_loop`): its hand-backs are
        # finished here exactly as the Python tick would do them
        if self.compiled_loop and SUPPORTED and self.mode == "sync" and writer is None and race.compiled \
                and not self.noisy and self.clock.name == "fixed":
            r.fast = SyncLoop([c.sock.fileno() for c in self.cars], [c.addr for c in self.cars], race,
                              self.clock.substeps())
        while True:
            if self._stop:
                for c in self.cars:
                    self._send(c, P.SHUTDOWN_MESSAGE)
                return "stopped"
            finished = self._race_over(r.tick, world, r.cars)
            if r.fast is not None and r.countdown == 0 and not finished and not self._behind \
                    and not r.python_tick:
                status = self._compiled_ticks(r)
                if status is None:
                    continue
            else:
                r.python_tick = False
                if finished:
                    for c in r.cars:
                        self._send(c, race.message(c.index))
                    for c in self.cars:
                        self._send(c, P.SHUTDOWN_MESSAGE)
                    self._final_table(world, r.tick, "race over")
                    return "end"
                status = self._python_tick(r, writer, world)
            if status != DONE and self._bookkeeping(r, world):
                return "restart"

    def _compiled_ticks(self, r: "_RaceState"):
        """Ticks in `SyncLoop` until it hands back; finishes the tick it handed back in the
        middle of. Returns the race's status after that tick, or None when there is none to
        look at (a tick limit, or a stale datagram: the next tick goes through Python)."""
        limit = self.max_ticks - r.tick if self.max_ticks is not None else 1 << 62
        ticks, why, arg, foreign, waited_s = r.fast.run(limit)
        status = None
        if why == PENDING:      # the states went out, cars[:arg] answered
            self.stats.foreign_datagrams += foreign
            self._collect_sync(r.cars[arg:], waited_s)
            status = r.race.run(DECODE, DONE, True, r.fast.nsub, 0)
            r.python_ticks += 1
            ticks += 1
        elif why == TICK:
            status = r.race.resume(arg, DONE, True, r.fast.nsub, 0) if arg < DONE else arg
        self.stats.ticks += ticks
        if why in (LIMIT, STALE):
            r.python_tick = why == STALE
            return None
        return status

    def _python_tick(self, r: "_RaceState", writer, world) -> int:
        """One tick (or countdown message) in Python: states out, answers in, the step."""
        race, cars = r.race, r.cars
        # stale datagrams (sync, realtime): one poll says whether any socket holds one
        drain = self.mode != "timeout"      # TORCS's timeout mode reads one datagram per tick
        late = self._take_late(cars) if drain and self._poll.poll(0) else {}
        for c in cars:
            self._send(c, race.message(c.index))
        self._collect(cars, late)
        stepping = r.countdown == 0
        label = r.tick if stepping else -r.countdown
        if not stepping:
            r.countdown -= 1
        nsub = self.clock.substeps() if stepping else 0
        if writer is None:
            status = race.run(DECODE, DONE, stepping, nsub, r.countdown)
        else:      # the row of the state sent and the controls applied, before the step
            race.run(DECODE, STEP, stepping, nsub, r.countdown)
            self._write_csv(writer, label, world, SensorFrame(race.flat, race.cars), self._controls)
            status = race.run(STEP, DONE, stepping, nsub, r.countdown)
        if stepping:
            self.stats.ticks += 1
            r.python_ticks += 1
        return status

    def _bookkeeping(self, r: "_RaceState", world) -> bool:
        """The race's events after a tick: malformed answers, laps, cars out, a restart request.
        True when a client asked for a restart (every client has been told)."""
        race = r.race
        self.stats.bad_datagrams += race.bad_datagrams
        race.bad_datagrams = 0
        now_laps = world.column("laps").tolist()
        if now_laps != r.laps:
            self._log_laps(world, now_laps, r.laps)
            r.laps = now_laps
            race.laps_seen[:] = now_laps
        damage = world.column("damage").tolist()
        lap_s = world.column("cur_lap_time").tolist()
        out = [c for c in r.cars if damage[c.index] > MAX_DAMAGE or lap_s[c.index] > race.max_lap_s]
        if out:
            for c in out:
                why = (f"damage {damage[c.index]:.0f} > {MAX_DAMAGE:.0f}" if damage[c.index] > MAX_DAMAGE
                       else f"its lap has lasted {lap_s[c.index]:.2f} s > {race.max_lap_s:.2f} s "
                            "(TORCS's lap-time limit)")
                self.log(f"car {c.index} is out of the race at tick {r.tick}: {why}")
                self._inlen[c.index] = -1     # out of the race: no answer read again
            r.cars = [c for c in r.cars if c not in out]
            if r.fast is not None:
                r.fast.set_cars(c.index for c in r.cars)
        restart_by = next((c.index for c in r.cars if race.meta[c.index] == 1), None)
        if restart_by is None:
            return False
        self.stats.restarts += 1
        self.log(f"restart requested by the client of car {restart_by}")
        for c in self.cars:
            self._send(c, P.RESTART_MESSAGE if c.index == restart_by else P.SHUTDOWN_MESSAGE)
        return True

    def _race_over(self, tick: int, world, cars: list[_Car]) -> bool:
        """Max ticks reached, every car out, or TORCS's end of the race (`physics.finish`): every
        car still in the race has finished (done its laps, or crossed the line once after
        another car's finish), or a finished car has crossed the line again."""
        if self.max_ticks is not None and tick >= self.max_ticks:
            return True
        if not cars:
            return True
        if self.laps is not None:
            finished = world.finished
            return world.race_over or all(finished[c.index] for c in cars)
        return False

    def _take_late(self, cars: list[_Car]) -> dict[int, bytes]:
        """Sync and realtime modes, just before the states go out: empty every car's queue.

        What a client we wait for (sync) sent since its last answer is stale: dropped and
        counted, unless it asks for a restart. For a client on timeout behaviour (sync, after
        its deadline) and in realtime mode the newest datagram is a late answer: it is used if
        no fresh answer comes this tick (and in sync mode the client is waited for again)."""
        late: dict[int, bytes] = {}
        for c in cars:          # non-blocking reads: an empty queue is one failed recv
            keep_newest = self.mode == "realtime" or not c.sync
            while (got := self._recv(c)) is not None:
                data, addr = got
                if addr != c.addr:
                    self.stats.foreign_datagrams += 1
                elif keep_newest or P.decode_controls(data).meta == 1:
                    if c.index in late:
                        self.stats.drained_datagrams += 1   # superseded by a newer one
                    late[c.index] = data
                else:
                    self.stats.drained_datagrams += 1
        return late

    def _collect(self, cars: list[_Car], late: dict[int, bytes]) -> None:
        """Read this tick's answers per the clock mode into the cars' inbox rows (`_inlen`)."""
        if not late and self.mode == "sync" and not self._behind:
            self._collect_sync(cars)
            return
        got: dict[int, bytes] = dict(late)   # fresh answers replace late ones
        start = time.monotonic()
        if self.mode == "timeout":
            for c in cars:   # TORCS polls in turn: exactly one datagram, no draining
                data = self._wait_one(c, time.monotonic() + self.timeout_s)
                if data is not None:
                    got[c.index] = data
        else:
            tick_end = start + TICK_S if self.mode == "realtime" else None
            # a late answer that asks for a restart is final: nothing more to wait for
            final = {i for i, data in late.items() if P.decode_controls(data).meta == 1} if late else ()
            pending = {c.sock: c for c in cars if c.index not in final}
            deadline = {c.index: tick_end if tick_end is not None else
                        start + (self.client_deadline_s if c.sync else self.timeout_s) for c in pending.values()}
            while pending and not self._stop:
                wait = min(deadline[c.index] for c in pending.values()) - time.monotonic()
                ready, _, _ = select.select(list(pending), [], [], max(0.0, min(wait, STOP_POLL_S)))
                for sock in ready:
                    c = pending[sock]
                    if (data := self._read_from_client(c)) is not None:
                        got[c.index] = data
                        del pending[sock]
                if not pending or ready and wait > 0:
                    continue
                now = time.monotonic()
                for sock, c in list(pending.items()):
                    if now >= deadline[c.index]:
                        if c.sync and tick_end is None:
                            self._to_timeout_behaviour(c)
                        del pending[sock]
            if tick_end is not None and (rest := tick_end - time.monotonic()) > 0:
                time.sleep(rest)
        self._apply(cars, got)

    def _collect_sync(self, cars: list[_Car], waited_s: float = 0.0) -> None:
        """Sync mode, every client answering in time so far (the usual tick): one blocking
        read per car into its inbox row, which the kernel ends after `client_deadline_s`
        (SO_RCVTIMEO); a car silent that long goes to timeout behaviour. `waited_s`: how long
        the first car has been waited for already (by the compiled loop)."""
        inlen = self._inlen
        for c in cars:
            n = inlen[c.index] = -1 if self._stop else self._wait_for_client(c, waited_s)
            waited_s = 0.0
            if n < 0:
                self.stats.timeouts += 1
                if not self._stop:
                    self._to_timeout_behaviour(c)

    def _to_timeout_behaviour(self, c: _Car) -> None:
        c.sync = False
        self._behind += 1
        self.log(f"warning: client of car {c.index} silent for {self.client_deadline_s:g} s "
                 f"in sync mode; reusing its last controls, waiting {self.timeout_s * 1000:g} ms "
                 f"per tick until it answers again")

    def _wait_for_client(self, c: _Car, waited_s: float = 0.0) -> int:
        """Receive c's client's next datagram into c.inbox, waiting up to `client_deadline_s`
        (less `waited_s`, the time it was waited for already);
        returns its length, or -1 on silence or a stop request (the socket's receive timeout is
        at most STOP_POLL_S so stop() is seen in time); foreign datagrams are counted and dropped
        without extending the wait."""
        end = time.monotonic() + self.client_deadline_s - waited_s
        if waited_s >= self.client_deadline_s:
            return -1
        while not self._stop:
            try:
                n, addr = c.sock.recvfrom_into(c.inbox)
            except OSError:     # EAGAIN: one receive timeout (<= STOP_POLL_S) passed, or the socket failed
                if time.monotonic() >= end:
                    return -1
                continue
            if addr == c.addr:
                return n
            self.stats.foreign_datagrams += 1
            if time.monotonic() >= end:
                return -1
        return -1

    def _apply(self, cars: list[_Car], got: dict[int, bytes]) -> None:
        """This tick's answers into the cars' inbox rows (silent cars: length -1, they keep
        their controls); a car back from timeout behaviour is waited for again."""
        for c in cars:
            data = got.get(c.index)
            if data is None:
                self.stats.timeouts += 1
                self._inlen[c.index] = -1
                continue
            if not c.sync:   # it answered (late or fresh): wait for it again
                c.sync = True
                self._behind -= 1
                self.log(f"client of car {c.index} answers again: waiting for it every tick")
            self._inbox[c.index, :len(data)] = np.frombuffer(data, dtype=np.uint8)
            self._inlen[c.index] = len(data)

    def _read_from_client(self, c: _Car) -> bytes | None:
        """The next datagram from c's own client; foreign ones are counted and dropped. Only
        one is read: in timeout mode the rest waits for the next ticks (TORCS), in the other
        modes `_take_late` empties the queue before the next state is sent."""
        while (got := self._recv(c)) is not None:
            data, addr = got
            if addr == c.addr:
                return data
            self.stats.foreign_datagrams += 1
        return None

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

    def _log_laps(self, world, laps: list, before: list) -> None:
        """One line per completed lap (the first line crossing from the grid starts lap 1)."""
        for i, (now, was) in enumerate(zip(laps, before)):
            lap_time = float(world.column("last_lap_time")[i])
            if now > was and now >= 2 and lap_time > 0:
                self.stats.laps.append((self.stats.races, i, int(now) - 1, lap_time))
                self.log(f"car {i}: lap {int(now) - 1} in {lap_time:.3f} s, "
                         f"damage {int(world.column('damage')[i])}")

    def _final_table(self, world, ticks: int, how: str) -> None:
        self.log(f"{how} after {ticks} ticks")
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
        """One row per car: the state sent at this tick and the controls applied for it
        (countdown ticks are numbered -countdown .. -1, the race from 0)."""
        col = world.column
        t = world.time
        for i in range(self.n):
            writer.writerow([tick, f"{t:.3f}", i, f"{col('x')[i]:.4f}", f"{col('y')[i]:.4f}",
                             f"{col('yaw')[i]:.5f}", f"{frame.distFromStart[i]:.3f}",
                             f"{frame.trackPos[i]:.5f}", f"{frame.angle[i]:.5f}", f"{frame.speedX[i]:.3f}",
                             f"{frame.speedY[i]:.3f}", f"{frame.rpm[i]:.1f}", int(frame.gear[i]),
                             int(col("laps")[i]), f"{frame.curLapTime[i]:.3f}", f"{frame.lastLapTime[i]:.3f}",
                             int(frame.damage[i]), f"{controls[i, 0]:.5f}", f"{controls[i, 1]:.5f}",
                             f"{controls[i, 2]:.5f}", int(controls[i, 3]), f"{controls[i, 4]:.5f}"])


def _timeval(seconds: float) -> bytes:
    """struct timeval for SO_RCVTIMEO (all zero, "wait forever", for an infinite deadline)."""
    if not seconds < 1e7:
        return struct.pack("ll", 0, 0)
    usec = max(1, round(max(seconds, 0.0) * 1e6))
    return struct.pack("ll", usec // 1_000_000, usec % 1_000_000)


def warm_up(world, noisy: bool = False) -> None:
    """Run, once, every compiled kernel a race calls, on a throwaway `world` (N cars): the
    server's compiled tick and each stage's Python path (focus reading, noise, countdown, a
    datagram in no stock layout), the World's own step, the contact solver's narrow phase and
    response (car 0 is put on its barrier; then two cars press against each other, so that a
    consultation runs from compiled code as most of a race's do), the codec. Numba loads them from its disk cache (or
    compiles them) now, before any client identifies, so no tick of the race waits for them (a
    first contact would otherwise stall the race for a cache load, or a compile on a fresh
    install)."""
    n = world.n_cars
    suite = SensorSuite(world, noisy=noisy, rng=np.random.default_rng(0))
    inbox = np.zeros((n, RECV_BYTES), dtype=np.uint8)
    inlen = np.full(n, -1, dtype=np.int64)
    race = ServerTick(world, suite, np.zeros((n, 5)), inbox, inlen, MAX_DAMAGE)
    race.run(SENSE, DONE, stepping=False, nsub=0, countdown=1)
    placements = np.zeros((n, 3))
    placements[:, 0] = 10.0 * np.arange(n)      # the other cars in line behind, clear of car 0
    placements[0] = (world.track.length / 2, float(world.track.barrier_left[0]), 10.0)
    answers = [P.encode_controls(1.0, 0.0, 1, 0.0, style=style) for style in ("cpp", "snakeoil")]
    answers.append(b"(accel 1) (gear 1)")          # in no stock layout: the Python decoder
    for tick, msg in enumerate(answers * 2):
        if tick == len(answers):
            world.reset(placements)
            race.refresh()
        inbox[:, :len(msg)] = np.frombuffer(msg, dtype=np.uint8)
        inlen[:] = len(msg)
        race.run(DECODE, DONE, stepping=True, nsub=10, countdown=0)
    if SUPPORTED:
        SyncLoop([-1] * n, [("127.0.0.1", 0)] * n, race, 10).run(0)   # the sync loop, loaded only
    world.step(race.u)          # and the in-process doors' own path, a focus reading due
    # two cars side by side steering into each other for three ticks: a consultation of pymunk
    # with the body set unchanged since the last one runs from compiled code
    # (`pymunk_direct.narrow_direct`)
    pair = World(world.track, [world.cars[0]] * 2, np.random.default_rng(0))
    middle = world.track.length / 2
    pair.reset(np.array([[middle, 0.9, 10.0], [middle, -0.9, 10.0]]))
    for _ in range(3):
        pair.step(np.array([[-1.0, 0.5, 0.0, 1.0, 0.0], [1.0, 0.5, 0.0, 1.0, 0.0]]))
    P.encode_sensor_rows(SensorSuite(world, noisy=noisy, rng=np.random.default_rng(0)).frame().flat)
    P.decode_controls_into(answers[0], np.zeros(8))


def _port_list(ports: list[int]) -> str:
    """'3001..3003' for consecutive ports, else '3001, 3003'."""
    if ports == list(range(ports[0], ports[0] + len(ports))):
        return f"{ports[0]}..{ports[-1]}" if len(ports) > 1 else str(ports[0])
    return ", ".join(map(str, ports))

