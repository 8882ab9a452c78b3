"""`madsim serve` as a real subprocess on 127.0.0.1, driven over UDP (spec/scr-protocol.md §3,
§4, §7, §14; issue 4 acceptance).

Every server gets free ports of its own, every wait is bounded, and every server process is
killed by the `serve` fixture whatever happens. Most races use `--countdown 0` and the short
bundled oval so the module stays fast.
"""

from __future__ import annotations

import csv
import math
import re
import signal
import socket
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from udp import default_sigint as _default_sigint
from udp import free_ports

from madsim.net import protocol as P
from madsim.net.client import ScrClient, simple_driver

TRACK = "madsim-oval"          # 1602.48 m, 15 m wide; the grid is on the start straight
HALF_WIDTH_M = 7.5
START_S = 180.0                # bound on a server's start-up (a cold numba cache compiles ~1 min)
WAIT_S = 30.0                  # bound on anything else a test waits for (a busy CI box)
SERVE = [sys.executable, "-m", "madsim.cli", "serve"]
# wall-clock pacing and timeouts: under pytest-xdist these run one after another in one worker
pytestmark = pytest.mark.xdist_group("timing")




class Server:
    """One `madsim serve` subprocess; reader threads collect its stdout and stderr lines."""

    def __init__(self, args: list[str], clients: int):
        self.port = free_ports(clients)
        self.proc = subprocess.Popen(SERVE + ["--port", str(self.port), "--clients", str(clients), *args],
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                     preexec_fn=_default_sigint)
        self.out: list[str] = []
        self.err: list[str] = []
        self._readers = [threading.Thread(target=self._read, args=(pipe, lines), daemon=True)
                         for pipe, lines in ((self.proc.stdout, self.out), (self.proc.stderr, self.err))]
        for t in self._readers:
            t.start()

    @staticmethod
    def _read(pipe, lines):
        for line in pipe:
            lines.append(line.rstrip("\n"))

    @property
    def output(self) -> str:
        return "\n".join(self.out + self.err)

    def wait_line(self, pattern: str, timeout: float = WAIT_S) -> re.Match:
        """The first stdout line matching the regex `pattern` (waits for it)."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            for line in list(self.out):
                if (m := re.search(pattern, line)) is not None:
                    return m
            if self.proc.poll() is not None and not any(t.is_alive() for t in self._readers):
                break
            time.sleep(0.02)
        raise AssertionError(f"no line matching {pattern!r}; output so far:\n{self.output}")

    def wait_exit(self, timeout: float = WAIT_S) -> int:
        code = self.proc.wait(timeout=timeout)
        for t in self._readers:
            t.join(5.0)
        return code

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(timeout=10)


@pytest.fixture
def serve():
    """serve(*args, clients=1): a started server whose UDP ports are open."""
    started: list[Server] = []

    def start(*args: str, clients: int = 1) -> Server:
        server = Server(list(args), clients)
        started.append(server)
        server.wait_line(r"waiting for \d+ client", timeout=START_S)
        return server

    yield start
    for server in started:
        server.kill()


def client(server: Server, car: int = 0, **kwargs) -> ScrClient:
    kwargs.setdefault("timeout_s", 2.0)
    kwargs.setdefault("identify_tries", 10)
    kwargs.setdefault("silent_tries", 15)
    return ScrClient("127.0.0.1", server.port + car, **kwargs)


class RawClient:
    """A byte-level client: what it sends and receives is exactly what is on the wire."""

    def __init__(self, port: int, timeout_s: float = WAIT_S):
        self.addr = ("127.0.0.1", port)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(timeout_s)

    def send(self, data: bytes) -> None:
        self.sock.sendto(data, self.addr)

    def recv(self) -> bytes:
        return self.sock.recv(70000)

    def identify(self, init: bytes = P.encode_init("SCR", P.SNAKEOIL_ANGLES_DEG)) -> bytes:
        self.send(init)
        return self.recv()

    def close(self) -> None:
        self.sock.close()


def stats_line(server: Server) -> dict[str, int]:
    """The counters of the server's last 'datagrams: ...' summary line."""
    m = server.wait_line(r"datagrams: (\d+) malformed, (\d+) foreign, (\d+) ignored before the start, "
                         r"(\d+) drained; (\d+) reused controls")
    return dict(zip(("malformed", "foreign", "ignored", "drained", "reused"), map(int, m.groups())))


def controls(steer=0.0, accel=0.0, brake=0.0, gear=1, meta=0, focus=0) -> bytes:
    return P.encode_controls(accel=accel, brake=brake, gear=gear, steer=steer, focus=focus, meta=meta)


# --- a lap, several clients, the end of a race ---------------------------------------------



def drive_in_background(server, warm_steps: int = 20):
    """Drive the server's car with simple_driver in a daemon thread; returns (thread, step
    counter [n], outcome list) once `warm_steps` states were answered (or WAIT_S passed)."""
    steps, outcome = [0], []

    def drive():
        def count(state):
            steps[0] += 1
            return simple_driver(state)
        with client(server) as c:
            outcome.append(c.run(count, max_steps=100_000))

    t = threading.Thread(target=drive, daemon=True)
    t.start()
    end = time.monotonic() + WAIT_S
    while steps[0] < warm_steps and time.monotonic() < end:
        time.sleep(0.01)
    return t, steps, outcome

def test_a_full_lap_ends_with_shutdown_after_a_state_that_carries_the_lap_time(serve):
    server = serve("--track", TRACK, "--laps", "1", "--countdown", "0")
    seen: list[dict] = []

    def driver(state):
        seen.append(state)
        return simple_driver(state)

    with client(server) as c:
        result = c.run(driver, max_steps=20_000)
    assert result.status == "shutdown" and result.steps == len(seen)
    assert server.wait_exit() == 0
    first, last = seen[0], seen[-1]
    assert first["lastLapTime"] == 0.0 and first["distRaced"] == 0.0
    # the lap time the server logs (3 decimals) is the one in the last state message (%g, float32)
    logged = float(server.wait_line(r"car 0: lap 1 in ([\d.]+) s").group(1))
    assert last["lastLapTime"] == pytest.approx(logged, abs=6e-4)
    assert 20.0 < last["lastLapTime"] < 0.02 * len(seen)
    assert last["distRaced"] > 1602.48          # a lap from the grid behind the line
    assert sum(s["lastLapTime"] > 0.0 for s in seen) == 1   # the race ends on the lap's first state
    assert re.search(r"^madsim serve: +0 +1 ", server.output, re.M)   # final table: car 0, 1 lap


def test_a_race_ends_as_torcs_ends_it_one_lap_after_the_winners_finish(serve):
    """--laps 1, car 0 driven, car 1 parked on the grid behind the line (it never crosses): TORCS
    ends the race when the winner, finished, crosses the line again (ReManage: every car is then
    finished; docs/physics.md, "The finish of a race"), not at the tick limit. The winner's lap
    count stops at its finish (1 lap in the table, one lap time logged), and its lap timer runs on
    through the lap after it."""
    server = serve("--track", TRACK, "--laps", "1", "--countdown", "0", "--max-ticks", "30000", clients=2)
    seen: list[list[dict]] = [[], []]
    results = [None, None]

    def drive(car: int, driver):
        def record(state):
            seen[car].append(state)
            return driver(state)
        with client(server, car) as c:
            results[car] = c.run(record, max_steps=40_000)

    park = lambda s: {"accel": 0.0, "brake": 1.0, "gear": 0}          # noqa: E731
    threads = [threading.Thread(target=drive, args=args, daemon=True)
               for args in ((0, simple_driver), (1, park))]
    for t in threads:
        t.start()
    for t in threads:
        t.join(4 * WAIT_S)
    assert not any(t.is_alive() for t in threads), server.output
    assert server.wait_exit() == 0
    ticks = int(server.wait_line(r"race over after (\d+) ticks").group(1))
    assert [r.status for r in results] == ["shutdown", "shutdown"] and ticks < 30000
    lap = float(server.wait_line(r"car 0: lap 1 in ([\d.]+) s").group(1))
    assert len(re.findall(r"car 0: lap \d+ in", server.output)) == 1
    last = seen[0][-1]
    assert last["lastLapTime"] == pytest.approx(lap, abs=6e-4)
    assert last["curLapTime"] > 20.0                 # the lap after the finish, untimed
    assert last["distRaced"] > 2 * 1602.48
    assert re.search(r"^madsim serve: +0 +1 ", server.output, re.M)
    assert re.search(r"^madsim serve: +1 +0 ", server.output, re.M)


def test_the_lap_time_limit_takes_a_car_out_as_torcs_does(serve):
    """--lap-time-limit: a car whose current lap has lasted longer than 84.5 s + length / (10
    m/s) is out of the race (TORCS's robot lap-time limit; madsim-oval: 244.748 s). Car 0 parked
    on the grid never crosses the line: it is out at the first tick past the limit, and with no
    car left the race is over and its client told so."""
    server = serve("--track", TRACK, "--countdown", "0", "--max-ticks", "20000", "--lap-time-limit",
                   clients=1)
    limit = 84.5 + 1602.48 / 10.0
    seen: list[dict] = []

    def park(state):
        seen.append(state)
        return {"accel": 0.0, "brake": 1.0, "gear": 0}

    with client(server, 0) as c:
        result = c.run(park, max_steps=30_000)
    assert result.status == "shutdown"
    assert server.wait_exit() == 0
    lap = float(server.wait_line(r"car 0 is out of the race at tick \d+: its lap has lasted ([\d.]+) s")
                .group(1))
    assert limit < lap <= limit + 0.02 + 1e-9           # the first tick past the limit
    ticks = int(server.wait_line(r"race over after (\d+) ticks").group(1))
    assert ticks == round(lap / 0.02) < 20000
    assert seen[-1]["curLapTime"] <= limit + 0.02 + 1e-9


def test_three_clients_each_drive_their_own_car_at_the_same_time(serve):
    server = serve("--track", TRACK, "--countdown", "0", "--max-ticks", "150", clients=3)
    states: list[list[dict]] = [[], [], []]
    results = [None, None, None]

    def drive(car: int, driver, angles):
        def record(state):
            states[car].append(state)
            return driver(state)
        with client(server, car, angles_deg=angles) as c:
            results[car] = c.run(record, max_steps=1000)

    park = lambda s: {"accel": 0.0, "brake": 1.0, "gear": 0}          # noqa: E731
    slow = lambda s: simple_driver(s, target_speed_kmh=15.0)           # noqa: E731
    threads = [threading.Thread(target=drive, args=args, daemon=True) for args in (
        (0, simple_driver, P.SNAKEOIL_ANGLES_DEG), (1, slow, P.CPP_CLIENT_ANGLES_DEG),
        (2, park, P.DEFAULT_ANGLES_DEG))]
    for t in threads:
        t.start()
    for t in threads:
        t.join(WAIT_S)
    assert not any(t.is_alive() for t in threads), server.output
    assert server.wait_exit() == 0
    assert results == [("shutdown", 151)] * 3          # states of ticks 0..150, then shutdown
    for k in range(151):
        assert sorted(states[i][k]["racePos"] for i in range(3)) == [1, 2, 3]
    # the grid on the start straight: nearest opponent as the crow flies from (s, n) of the others
    grid = [(s[0]["distFromStart"], s[0]["trackPos"] * HALF_WIDTH_M) for s in states]
    for i in range(3):
        nearest = min(math.dist(grid[i], grid[j]) for j in range(3) if j != i)
        assert min(states[i][0]["opponents"]) == pytest.approx(nearest, abs=0.01)
    # per-client rangefinder angles (§3.3): +-90 deg reach the edges, +-45 deg sqrt(2) further
    for i in range(3):
        tp, rays = states[i][0]["trackPos"], states[i][0]["track"]
        factor = math.sqrt(2.0) if i == 0 else 1.0            # client 0 asked -45 .. 45
        assert rays[0] == pytest.approx(factor * HALF_WIDTH_M * (1 - tp), abs=0.01)
        assert rays[18] == pytest.approx(factor * HALF_WIDTH_M * (1 + tp), abs=0.01)
    # each car got its own client's controls: the parked one stayed, the fast one is ahead
    raced = [s[-1]["distRaced"] for s in states]
    assert abs(raced[2]) < 0.05 and raced[0] > raced[1] > 2.0
    assert states[2][-1]["speedX"] == pytest.approx(0.0, abs=0.1)
    assert states[1][-1]["speedX"] == pytest.approx(15.0, abs=6.0)
    assert states[0][-1]["speedX"] > 30.0


def test_max_ticks_ends_the_race_after_countdown_and_final_state_with_pid_reply(serve):
    server = serve("--track", TRACK, "--countdown", "5", "--max-ticks", "40", "--identified-reply", "pid")
    seen: list[dict] = []
    with client(server) as c:
        pid = c.identify()
        assert pid == server.proc.pid          # MADRaS kills this pid to reset (§12.1)
        result = c.run(lambda s: seen.append(s) or simple_driver(s), max_steps=1000)
    assert result == ("shutdown", 46)          # 5 countdown states, ticks 0..40
    assert server.wait_exit() == 0
    # §4.3: countdown states are frozen, curLapTime negative, gear neutral, no focus
    assert [s["curLapTime"] for s in seen[:5]] == pytest.approx([-0.1, -0.08, -0.06, -0.04, -0.02])
    assert all(s["gear"] == 0 and s["focus"] == [-1.0] * 5 and s["speedX"] == 0.0 for s in seen[:5])
    assert seen[5]["curLapTime"] == 0.0 and seen[5]["distFromStart"] == seen[0]["distFromStart"]
    assert seen[-1]["curLapTime"] == pytest.approx(40 * 0.02, abs=1e-5)
    server.wait_line(r"race over after 40 ticks")


# --- restart -------------------------------------------------------------------------------


def _race_two_raw_clients(raw: list[RawClient], ticks: int, restart_at: int) -> list[list[bytes]]:
    """Identify both, answer `ticks` states with a fixed control sequence per car; client 0
    asks for a restart in its answer to state `restart_at`. Returns the states received."""
    got: list[list[bytes]] = [[], []]
    for r in raw:
        assert r.identify() == b"***identified***\0"
    for k in range(ticks):
        for i, r in enumerate(raw):
            got[i].append(r.recv())
        raw[0].send(controls(steer=0.2 * math.sin(k / 7.0), accel=1.0, meta=int(k == restart_at)))
        raw[1].send(controls(steer=-0.05, accel=0.6 + 0.004 * k, gear=1 + (k > 40)))
    return got


def test_restart_tells_requester_restart_others_shutdown_and_replays_bit_identically(serve):
    server = serve("--track", TRACK, "--countdown", "3", clients=2)
    raw = [RawClient(server.port), RawClient(server.port + 1)]
    try:
        first = _race_two_raw_clients(raw, 61, restart_at=60)
        assert raw[0].recv() == P.RESTART_MESSAGE and raw[1].recv() == P.SHUTDOWN_MESSAGE
        server.wait_line(r"restart requested by the client of car 0")
        second = _race_two_raw_clients(raw, 61, restart_at=-1)   # both must identify again
    finally:
        for r in raw:
            r.close()
    assert first == second                       # same seed, same controls: same bytes
    begin = P.decode_sensors(second[0][0])
    assert begin["curLapTime"] == pytest.approx(-0.06) and begin["distRaced"] == 0.0   # from the grid
    end = P.decode_sensors(first[0][-1])
    assert end["speedX"] > 15.0 and end["distRaced"] > 1.0   # the race had really moved on


# --- robustness ------------------------------------------------------------------------------


def test_a_silent_client_in_sync_mode_is_warned_about_and_the_race_goes_on(serve):
    server = serve("--track", TRACK, "--countdown", "0", "--max-ticks", "80", "--client-deadline", "0.5",
                   "--timeout-ms", "5", clients=2)
    silent = RawClient(server.port + 1)
    received = [0]
    try:
        assert silent.identify() == b"***identified***\0"

        def quiet_then_answer():   # reads every state; answers only from the 30th on
            while silent.recv() != P.SHUTDOWN_MESSAGE:
                received[0] += 1
                if received[0] >= 30:
                    silent.send(controls(brake=1.0, gear=0))

        t = threading.Thread(target=quiet_then_answer, daemon=True)
        t.start()
        started = time.monotonic()
        with client(server, 0) as c:
            result = c.run(simple_driver, max_steps=1000)
        t.join(WAIT_S)
    finally:
        silent.close()
    assert result == ("shutdown", 81) and received[0] == 81
    assert server.wait_exit() == 0
    server.wait_line(r"warning: client of car 1 silent for 0.5 s in sync mode")
    server.wait_line(r"client of car 1 answers again")
    reused = stats_line(server)["reused"]
    assert 29 <= reused < 60        # the 29 unanswered states, and a few while it caught up
    assert time.monotonic() - started < 0.5 + 81 * 0.25      # never a hang


def test_ten_thousand_random_datagrams_neither_crash_nor_steer_nor_stop_the_race(serve):
    server = serve("--track", TRACK, "--countdown", "0", "--client-deadline", "1")
    t, steps, outcome = drive_in_background(server)
    rng = np.random.default_rng(20261121)
    fuzzers = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(2)]
    try:
        for k in range(10_000):
            size = int(min(65507, math.exp(rng.uniform(0.0, math.log(65508.0))) - 1.0))
            data = rng.bytes(size)
            kind = k % 4
            if kind == 1:
                data = b"SCR" + data                     # looks like an identification
            elif kind == 2:                               # a valid restart request, wrong sender
                data = controls(accel=1.0, steer=1.0, meta=1)
            fuzzers[k % 7 == 0].sendto(data, ("127.0.0.1", server.port))
            if k % 50 == 49:
                time.sleep(0.002)                         # let the server keep up
    finally:
        for f in fuzzers:
            f.close()
    after = steps[0]
    end = time.monotonic() + WAIT_S
    while steps[0] < after + 300 and time.monotonic() < end:
        time.sleep(0.01)
    assert steps[0] >= after + 300, server.output      # the race still runs
    server.proc.send_signal(signal.SIGTERM)
    t.join(WAIT_S)
    assert outcome == [("shutdown", steps[0])]          # never a restart from foreign datagrams
    assert server.wait_exit() == 0
    assert "restart requested" not in server.output and "Traceback" not in server.output
    counts = stats_line(server)
    # most of them were read and rejected (the rest the kernel dropped while the buffer was full)
    assert 1_000 <= counts["foreign"] <= 10_000 and counts["malformed"] == 0


def test_non_scr_datagrams_before_the_start_get_no_reply_and_scr_alone_identifies(serve):
    server = serve("--track", TRACK, "--countdown", "0", "--max-ticks", "3")
    raw = RawClient(server.port, timeout_s=0.5)
    junk = [b"", b"S", b"SC", b"scr(init 0)", b"(init -90 0 90)", b"XSCR", b"\0SCR(init 0)",
            b"(accel 1)(meta 1)", bytes(range(256)) * 4]
    try:
        for data in junk:
            raw.send(data)
        with pytest.raises(socket.timeout):
            raw.recv()
        raw.sock.settimeout(WAIT_S)
        assert raw.identify(b"SCR") == b"***identified***\0"    # no (init ...): default angles
        states = []
        while (data := raw.recv()) != P.SHUTDOWN_MESSAGE:
            states.append(P.decode_sensors(data))
            raw.send(controls())
    finally:
        raw.close()
    assert len(states) == 4
    # default angles -90 .. 90 step 10: the first and last rays are the distances to the edges
    tp = states[0]["trackPos"]
    assert states[0]["track"][0] == pytest.approx(HALF_WIDTH_M * (1 - tp), abs=0.01)
    assert states[0]["track"][18] == pytest.approx(HALF_WIDTH_M * (1 + tp), abs=0.01)
    assert server.wait_exit() == 0
    assert stats_line(server)["ignored"] == len(junk)


def _csv_column(path, name: str, car: int = 0) -> list[float]:
    with open(path, newline="") as f:
        rows = [r for r in csv.DictReader(f) if int(r["car"]) == car]
    assert [int(r["tick"]) for r in rows] == list(range(len(rows)))
    return [float(r[name]) for r in rows]


def test_sync_mode_drops_an_extra_reply_so_later_commands_stay_on_their_tick(serve, tmp_path):
    trace = tmp_path / "trace.csv"
    server = serve("--track", TRACK, "--countdown", "0", "--max-ticks", "6", "--log-csv", str(trace), clients=2)
    raw = [RawClient(server.port), RawClient(server.port + 1)]
    try:
        for r in raw:
            assert r.identify() == b"***identified***\0"
        for k in range(6):
            for r in raw:
                r.recv()
            raw[0].send(controls(steer=0.1 * (k + 1)))
            if k == 2:   # a second answer to the same state (gym_torcs does this at episode end)
                raw[0].send(controls(steer=0.9))
                time.sleep(0.05)   # the server is still waiting for car 1: the extra is queued
            raw[1].send(controls(steer=-0.5))
        assert [raw[i].recv()[:1] for i in (0, 1)] == [b"(", b"("]          # the final state
        assert [raw[i].recv() for i in (0, 1)] == [P.SHUTDOWN_MESSAGE] * 2
    finally:
        for r in raw:
            r.close()
    assert server.wait_exit() == 0
    assert _csv_column(trace, "steer") == pytest.approx([0.1, 0.2, 0.3, 0.4, 0.5, 0.6], abs=1e-6)
    assert _csv_column(trace, "steer", car=1) == pytest.approx([-0.5] * 6)
    assert stats_line(server)["drained"] == 1


def _two_clients_with_upsets(server: Server, ticks: int, upsets: bool) -> list[bytes]:
    """Car 0's states over a sync race of two raw clients answering a fixed control sequence;
    with `upsets`: car 0 sends an extra answer at tick 3 (queued while car 1 is waited for),
    car 1 answers tick 5 only after 0.3 s (longer than one receive timeout, shorter than the
    client deadline) and a stranger writes to car 1's port at tick 7."""
    raw = [RawClient(server.port), RawClient(server.port + 1)]
    stranger = RawClient(server.port + 1)
    got = []
    try:
        for r in raw:
            assert r.identify() == b"***identified***\0"
        for k in range(ticks):
            got.append(raw[0].recv())
            raw[1].recv()
            raw[0].send(controls(steer=0.03 * k, accel=1.0))
            if upsets and k == 3:
                raw[0].send(controls(steer=-0.9, accel=1.0))
                time.sleep(0.05)
            if upsets and k == 5:
                time.sleep(0.3)
            if upsets and k == 7:
                stranger.send(controls(steer=0.9))
                time.sleep(0.05)
            raw[1].send(controls(steer=-0.02, accel=0.5))
        got.append(raw[0].recv())
        assert raw[0].recv() == P.SHUTDOWN_MESSAGE
    finally:
        for r in raw + [stranger]:
            r.close()
    assert server.wait_exit() == 0
    return got


def test_sync_ticks_of_the_compiled_loop_hand_extras_pauses_and_strangers_to_python_unchanged(serve):
    """The usual sync ticks run in the compiled loop (`sync_loop`, no --log-csv); a stale
    datagram, a client slower than one receive timeout and a foreign datagram make it hand
    the tick to the Python loop, and the race's bytes are those of an undisturbed race."""
    args = ("--track", TRACK, "--countdown", "0", "--max-ticks", "12", "--client-deadline", "2")
    calm = _two_clients_with_upsets(serve(*args, clients=2), 12, upsets=False)
    server = serve(*args, clients=2)
    upset = _two_clients_with_upsets(server, 12, upsets=True)
    assert upset == calm and len(calm) == 13
    assert len(set(calm)) == 13 and P.decode_sensors(calm[-1])["speedX"] > 0.0   # the car moved
    assert stats_line(server) == {"malformed": 0, "foreign": 1, "ignored": 0, "drained": 1, "reused": 0}


def test_sync_mode_honours_a_restart_request_sent_as_an_extra_datagram(serve):
    server = serve("--track", TRACK, "--countdown", "0", "--max-ticks", "3")
    raw = RawClient(server.port)
    try:
        assert raw.identify() == b"***identified***\0"
        raw.recv()
        raw.send(controls(accel=1.0))
        raw.send(b"(meta 1)")                 # C++/pyScrcClient style restart request, unasked
        assert raw.recv()[:1] == b"("          # state 1 goes out, nobody waits for its answer
        assert raw.recv() == P.RESTART_MESSAGE
        assert raw.identify() == b"***identified***\0"
        for _ in range(4):
            assert raw.recv()[:1] == b"("
            raw.send(controls())
        assert raw.recv() == P.SHUTDOWN_MESSAGE
    finally:
        raw.close()
    assert server.wait_exit() == 0
    server.wait_line(r"restart requested by the client of car 0")


def test_timeout_mode_reuses_controls_on_silence_and_reads_one_datagram_per_tick(serve, tmp_path):
    trace = tmp_path / "trace.csv"
    server = serve("--track", TRACK, "--mode", "timeout", "--timeout-ms", "500", "--countdown", "0",
                   "--max-ticks", "8", "--log-csv", str(trace))
    # answers per state: None = silence; two items = two datagrams for one state (§4.2)
    plan = [None, [0.1], None, [0.3, 0.4], [0.5], [0.6], [0.7], [0.8], [0.9]]
    raw = RawClient(server.port)
    try:
        assert raw.identify() == b"***identified***\0"
        for answers in plan:
            assert raw.recv()[:1] == b"("
            for steer in answers or ():
                raw.send(controls(steer=steer, accel=0.2, gear=2))
        assert raw.recv() == P.SHUTDOWN_MESSAGE
    finally:
        raw.close()
    assert server.wait_exit() == 0
    # tick 0: nothing received yet -> all zeros (gear 0); tick 2 reuses tick 1's command; the
    # second datagram of state 3 is read at tick 4 and every later answer stays one tick late
    assert _csv_column(trace, "steer") == pytest.approx([0.0, 0.1, 0.1, 0.3, 0.4, 0.5, 0.6, 0.7], abs=1e-6)
    assert _csv_column(trace, "gear_request") == [0, 2, 2, 2, 2, 2, 2, 2]
    counts = stats_line(server)
    assert counts["reused"] == 2 and counts["drained"] == 0


def test_realtime_mode_paces_ticks_at_20_ms_of_wall_time(serve):
    server = serve("--track", TRACK, "--mode", "realtime", "--countdown", "0", "--max-ticks", "25")
    arrivals: list[float] = []
    with client(server) as c:
        result = c.run(lambda s: arrivals.append(time.monotonic()) or simple_driver(s), max_steps=100)
    assert result == ("shutdown", 26)
    assert arrivals[-1] - arrivals[0] >= 25 * 0.02 * 0.96   # sync mode would take ~10 ms


@pytest.mark.parametrize("when", ["waiting for clients", "racing"])
def test_ctrl_c_stops_the_server_cleanly(serve, when):
    server = serve("--track", TRACK, "--countdown", "0")
    outcome = []
    if when == "racing":
        t, steps, outcome = drive_in_background(server)
        assert steps[0] >= 20, server.output
    server.proc.send_signal(signal.SIGINT)
    assert server.wait_exit() == 0
    assert "interrupted: shutting down" in server.output
    assert "Traceback" not in server.output
    if when == "racing":
        t.join(WAIT_S)
        assert outcome and outcome[0].status == "shutdown"     # the client is told
        ticks = int(server.wait_line(r"race stopped after (\d+) ticks").group(1))
        assert ticks >= 19


# --- the same numbers in-process and over UDP ----------------------------------------------


def _plan(k: int) -> dict:
    """A fixed control sequence: start, shift, a gentle weave, braking, changing focus."""
    focus = 0 if k < 100 else 30 if k < 200 else None if k < 250 else -45
    return {"accel": 1.0 if k < 200 else 0.0, "brake": 0.3 if 200 <= k < 250 else 0.0,
            "gear": 1 if k < 60 else 2, "steer": 0.05 * math.sin(k / 15.0), "clutch": 0.0, "focus": focus}


@pytest.mark.parametrize("noisy", [False, True])
def test_udp_states_equal_in_process_sensors_for_the_same_seed_and_controls(serve, noisy):
    from madsim.cli import make_world_factory
    from madsim.physics.sensors import FOCUS_NONE, SensorSuite

    seed, ticks = 7, 300
    server = serve("--track", TRACK, "--countdown", "0", "--max-ticks", str(ticks), "--seed", str(seed),
                   *(["--noisy"] if noisy else []))
    received = []
    with client(server) as c:                         # snakeoil's 19 angles
        c.identify()
        for k in range(ticks + 1):
            received.append(c.receive())
            if k < ticks:
                c.send(_plan(k))
        assert c.receive() is None and c.event == "shutdown"
    assert server.wait_exit() == 0

    # in-process: the World `madsim serve` builds (fuel on, damage on), the server's noise seed
    world = make_world_factory(TRACK, ["madsim-sedan"], 1, fuel=True, damage=True)(seed)
    suite = SensorSuite(world, noisy=noisy, rng=np.random.default_rng([seed, 1]))
    suite.set_angles(0, P.parse_init(P.encode_init("SCR", P.SNAKEOIL_ANGLES_DEG)).angles_deg)
    for k in range(ticks + 1):
        expected = P.decode_sensors(P.encode_sensors_flat(suite.frame().flat[0]))
        assert received[k] == expected, f"tick {k}"
        if k < ticks:
            ctl = P.decode_controls(P.encode_controls(**_plan(k)))   # the float32 values sent
            suite.request_focus([0], [FOCUS_NONE if ctl.focus is None else ctl.focus])
            world.step(np.array([[ctl.steer, ctl.accel, ctl.brake, ctl.gear, ctl.clutch]]))
    # the run exercised what it claims to: focus readings, speed, rangefinders on the road
    assert sum(s["focus"][2] > 0 for s in received) >= 4
    assert max(s["speedX"] for s in received) > 50.0
    assert received[-1]["track"][9] > 0


def test_torcs_tick_schedule_and_race_grid_replay_a_torcs_race_start(serve):
    """`--tick-schedule torcs`: states 20 or 22 ms apart exactly as TORCS's driver calls (the 22 ms
    gaps after racing messages 11 and 23, as in the real-TORCS traces); `--grid`: the traces'
    start, 100 m before the line on the centre line (one row)."""
    from madsim.physics.schedule import TorcsClock
    from madsim.tracks import load_track

    server = serve("--track", TRACK, "--countdown", "0", "--max-ticks", "30", "--tick-schedule", "torcs",
                   "--grid", "rows=1,distance_to_start=100")
    seen: list[dict] = []
    with client(server) as c:
        c.run(lambda s: seen.append(s) or simple_driver(s), max_steps=100)
    clock = TorcsClock()
    expected = [0.0]
    for _ in range(30):
        clock.substeps()
        expected.append(clock.time - 0.018)
    assert [s["curLapTime"] for s in seen] == pytest.approx(expected, abs=2e-5)
    gaps = np.round(np.diff([s["curLapTime"] for s in seen]), 3)
    assert list(np.nonzero(gaps == 0.022)[0]) == [11, 23]
    assert seen[0]["distFromStart"] == pytest.approx(load_track(TRACK).length - 100.0, abs=1e-3)
    assert seen[0]["trackPos"] == pytest.approx(0.0, abs=1e-6)


def test_bad_grid_is_one_line_error(tmp_path):
    r = subprocess.run(SERVE + ["--track", TRACK, "--grid", "rows=0"], capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and "grid: 'rows' must be >= 1" in r.stderr
    r = subprocess.run(SERVE + ["--track", TRACK, "--grid", "lanes=2"], capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and "grid: unknown value 'lanes'" in r.stderr
