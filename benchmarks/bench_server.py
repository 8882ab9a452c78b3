"""`madsim serve` in sync mode with one minimal UDP client: ticks per second of wall time.

Run: python benchmarks/bench_server.py [--ticks 20000] [--track madsim-oval] [--case rest]
                                       [--profile FILE]
     python benchmarks/bench_server.py --tools ../shared/tools [--reps 3] [--ticks 20000]
                                       [--baseline OTHER_CHECKOUT] [--pin]
     python benchmarks/bench_server.py --stages [--track g-track-1]

With --stages: the compiled tick's stages (decode, step, sense, encode) in this process, us per
tick (component figures, see `stage_costs`).

With --tools DIR: the issue-13 acceptance procedure instead. DIR holds `scr_speed_probe.py`
(the minimal client; `--full` parses every sensor first) and `scr_echo_server.py` (a
do-nothing Python server). Each repetition runs, back to back on one port, echo then `madsim
serve` (sync, g-track-1, car1-trb1, `--countdown 0`), with the minimal client then the full
one; every figure is over the whole run from the first tick after identification (start-up
stalls included). Prints each run, then per server and client the median ticks/s (and
range), the worst longest wait, the server process's CPU time per tick over the race (user +
system from /proc, from its "waiting for" line to the probe's end: a component figure, which
moves far less than the wall rate on a shared machine), and madsim's median as a share of
echo's. `--baseline DIR`
adds a third server to each repetition: `madsim serve` of another checkout (run from its own
folder with PYTHONPATH=DIR), e.g. main before a change, so both are measured in one sitting.

The server runs as a subprocess (`python -m madsim.cli serve --countdown 0 --max-ticks N`); the
client is a plain socket in this process that sends the init once, then answers every state
message at once with one fixed C++-style control string, without parsing anything. The clock
runs over the last `--ticks` ticks, after WARMUP ticks (1,000) that absorb start-up costs (the
first ticks used to wait for numba; they are component figures), up to `***shutdown***`. Real TORCS
reaches about 10,400 ticks/s here with a minimal client (issue 4). Each case also prints the
server process's CPU time per tick over the same ticks (user + system, from /proc): on a shared
machine it moves far less than the wall rate, which depends on where server and client run. With --profile FILE the
server runs under cProfile and its 25 most expensive functions (own time) are printed.

Cases (`--case`, default all three):
- `echo`: no madsim at all, a do-nothing Python UDP server: the transport floor of a Python
  server and client on this machine at this moment (run it beside the others on a busy box);
- `rest`: the car stays on the grid (physics, sensors and codec run every tick, the contact
  solver idles);
- `wall`: straight on at half throttle: after the first bend the car scrapes the barrier and
  contact is resolved on every sub-step (the worst case).
"""

from __future__ import annotations

import argparse
import os
import pstats
import socket
import subprocess
import sys
import time

INIT = b"SCR(init -45 -19 -12 -7 -4 -2.5 -1.7 -1 -.5 0 .5 1 1.7 2.5 4 7 12 19 45)"
CONTROLS = {
    # the car stays on the grid: physics, sensors and codec run, the contact solver idles
    "rest": b"(accel 0)(brake 1)(gear 0)(steer 0)(clutch 0)(focus 0)(meta 0)\0",
    # half throttle, straight on: the car leaves the oval at the first bend and then scrapes
    # the wall, so the contact solver is consulted on every sub-step (the worst case)
    "wall": b"(accel 0.5)(brake 0)(gear 1)(steer 0)(clutch 0)(focus 0)(meta 0)\0",
    # no madsim at all: the do-nothing Python server below, answered with the "rest" string
    "echo": b"",
}


# The transport floor: a Python scr_server that does no work at all (identifies, then sends one
# fixed 600-byte state per answer, sync style).
ECHO_SERVER = r"""
import select, socket, sys
port, ticks = int(sys.argv[1]), int(sys.argv[2])
state = b"(angle 0)" + b"(track" + b" 123.456" * 70 + b")\0"
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.bind(("127.0.0.1", port))
data, addr = s.recvfrom(65536)
s.sendto(b"***identified***\0", addr)
for _ in range(ticks + 1):
    s.sendto(state, addr)
    select.select([s], [], [], 10.0)
    s.recvfrom(65536)
s.sendto(b"***shutdown***\0", addr)
"""


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


WARMUP = 1_000


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of process `pid` so far (s), from /proc (Linux)."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def run(ticks: int, track: str, control: bytes, profile: str | None) -> tuple[float, float]:
    """Ticks per second of wall time over `ticks` ticks after WARMUP (states counted here), and
    the server process's CPU time per tick (us) over the same ticks (to the last 1,000th tick:
    unlike the wall rate it does not depend on where the scheduler puts server and client)."""
    port = free_udp_port()
    cmd = [sys.executable]
    if control == b"":
        cmd += ["-c", ECHO_SERVER, str(port), str(ticks + WARMUP)]
        control = CONTROLS["rest"]
    else:
        if profile:
            cmd += ["-m", "cProfile", "-o", profile]
        cmd += ["-m", "madsim.cli", "serve", "--track", track, "--port", str(port), "--countdown", "0",
                "--max-ticks", str(ticks + WARMUP), "--start-timeout", "60"]
    server = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.settimeout(1.0)
        for _ in range(60):  # the port exists once the server has loaded track and car
            sock.sendto(INIT, ("127.0.0.1", port))
            try:
                if sock.recv(64).startswith(b"***identified***"):
                    break
            except (socket.timeout, ConnectionRefusedError):
                continue
        else:
            raise SystemExit(f"server did not identify: {server.stderr.read().decode()[-500:]}")
        sock.settimeout(60.0)
        addr = ("127.0.0.1", port)
        recv, send = sock.recv, sock.sendto
        data = recv(2048)
        for _ in range(WARMUP):
            send(control, addr)
            data = recv(2048)
        start = time.perf_counter()
        cpu0 = cpu_seconds(server.pid)
        cpu = (0, cpu0)
        states = 1
        while data[:3] != b"***":
            send(control, addr)
            data = recv(2048)
            states += 1
            if states % 1000 == 0:
                cpu = (states - 1, cpu_seconds(server.pid))
        elapsed = time.perf_counter() - start
        server.wait(timeout=30)
        if server.returncode != 0:
            raise SystemExit(f"server exited with {server.returncode}: {server.stderr.read().decode()[-500:]}")
        # states - 1 answered intervals = world ticks timed
        return (states - 1) / elapsed, 1e6 * (cpu[1] - cpu0) / max(cpu[0], 1)
    finally:
        sock.close()
        if server.poll() is None:
            server.kill()
            server.wait()


def stage_costs(track: str, reps: int = 40, n: int = 100) -> None:
    """The compiled tick's stages in this process (a component figure: warm, no network): one
    car (car1-trb1) driving at 0.3 throttle on `track`, `server_tick` called for each stage
    range from a compiled loop, as the sync loop calls it; prints the best of `reps` runs of
    `n` ticks per stage, us per tick, and the bytes of the last state message. The empty call
    (DONE..DONE) is the call's own cost (the address table's views it makes); `from Python`
    is one whole tick called from Python (with the argument unboxing the sync loop skips)."""
    import numba
    import numpy as np

    from madsim.cli import make_world_factory
    from madsim.net.server import MAX_DAMAGE, RECV_BYTES
    from madsim.net.server_tick import DECODE, DONE, ENCODE, SENSE, STEP, ServerTick, server_tick
    from madsim.physics.sensors import SensorSuite

    world = make_world_factory(track, ["car1-trb1"], 1)(0)
    suite = SensorSuite(world, noisy=False, rng=np.random.default_rng(0))
    inbox = np.zeros((1, RECV_BYTES), dtype=np.uint8)
    inlen = np.full(1, -1, dtype=np.int64)
    race = ServerTick(world, suite, np.zeros((1, 5)), inbox, inlen, MAX_DAMAGE)
    msg = b"(accel 0.3)(brake 0)(gear 1)(steer 0.0)(clutch 0)(focus 0)(meta 0)\0"
    inbox[0, :len(msg)] = np.frombuffer(msg, dtype=np.uint8)
    inlen[0] = len(msg)
    snap = world.state.copy()

    @numba.njit
    def ticks(count, first, stop, nsub, st, snap, table, dt, fuel_on, length, half_width, max_range,
              max_bytes, max_damage):
        for _ in range(count):   # typed as the sync loop calls it: the same compiled server_tick
            server_tick(first, stop, np.bool_(True), np.bool_(True), nsub, st, snap, table, dt, fuel_on,
                        length, half_width, max_range, max_bytes, max_damage)

    def best(first, stop, compiled=True):
        times = []
        for _ in range(reps):
            world.state[:] = snap
            for _ in range(150):          # the car rolling, off the grid
                race.run(DECODE, DONE, True, 10, 0)
            args = race.args
            t0 = time.perf_counter()
            if compiled:
                ticks(n, np.int64(first), np.int64(stop), np.int64(10), *args)
            else:
                for _ in range(n):
                    server_tick(first, stop, True, True, 10, *args)
            times.append(time.perf_counter() - t0)
        return min(times) / n * 1e6

    best(DECODE, DONE)                    # compile / load
    best(DECODE, DONE, False)
    stages = [("whole tick", DECODE, DONE), ("decode", DECODE, STEP), ("step", STEP, SENSE),
              ("sense", SENSE, ENCODE), ("encode", ENCODE, DONE), ("empty call", DONE, DONE)]
    print(f"server_tick stages, {track}, one car, warm, in process (component figures), best of "
          f"{reps} x {n} ticks, us per tick:")
    print("  " + "  ".join(f"{name} {best(a, b):.2f}" for name, a, b in stages)
          + f"  (whole tick from Python {best(DECODE, DONE, False):.2f})")
    print(f"  last message ({race.out_len[0]} B): {bytes(race.message(0))[:120]!r}...")


def probe_runs(tools: str, reps: int, ticks: int, baseline: str | None = None, pin: bool = False) -> None:
    """The acceptance procedure of issue 13 (see the module docstring): prints one line per run
    and a summary (median and range). `baseline`: another checkout whose `madsim serve` runs
    back to back with this one's (e.g. main before a change). `pin`: the client on CPU 0 and
    every server on CPU 1 (`taskset`), so each round trip crosses cores, whatever the
    scheduler would have done."""
    server_cpu, client_cpu = (["taskset", "-c", "1"], ["taskset", "-c", "0"]) if pin else ([], [])
    probe, echo = os.path.join(tools, "scr_speed_probe.py"), os.path.join(tools, "scr_echo_server.py")
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    serve = [sys.executable, "-m", "madsim.cli", "serve", "--track", "g-track-1", "--cars", "car1-trb1",
             "--countdown", "0", "--max-ticks", str(ticks + 10), "--port"]
    servers = [("echo", None), ("madsim", here)] + ([("baseline", baseline)] if baseline else [])
    results: dict[tuple[str, str], list[tuple[float, float]]] = {}
    for _ in range(reps):
        for client in ("minimal", "full"):
            for server_name, checkout in servers:
                port = free_udp_port()
                if checkout is None:
                    cmd, env, cwd = server_cpu + [sys.executable, echo, str(port)], None, None
                else:    # that checkout's madsim, from its own folder
                    cmd, env, cwd = server_cpu + serve + [str(port)], dict(os.environ, PYTHONPATH=checkout), checkout
                server = subprocess.Popen(cmd, stdout=subprocess.PIPE if checkout else subprocess.DEVNULL,
                                          stderr=subprocess.DEVNULL, env=env, cwd=cwd, text=True)
                try:
                    # the server's CPU over the race alone: from its "waiting for" line (start-up
                    # and kernel loading done) to the end of the probe
                    if checkout:
                        for line in server.stdout:
                            if "waiting for" in line:
                                break
                    else:
                        time.sleep(0.5)
                    cpu0 = cpu_seconds(server.pid)
                    out = subprocess.run(client_cpu + [sys.executable, probe, str(ticks), str(port)]
                                         + (["--full"] if client == "full" else []),
                                         capture_output=True, text=True, timeout=600).stdout
                    cpu_us = 1e6 * (cpu_seconds(server.pid) - cpu0) / ticks
                finally:
                    server.kill()
                    server.wait()
                rate = float(out.split("ticks/s=")[1].split()[0])
                wait = float(out.split("longest_wait=")[1].split()[0])
                results.setdefault((server_name, client), []).append((rate, wait, cpu_us))
                print(f"{server_name:8} {client:7} {out.strip()} server_cpu={cpu_us:.1f}us/tick", flush=True)
    for client in ("minimal", "full"):
        med = {}
        for server_name, _ in servers:
            runs = results[(server_name, client)]
            rates = sorted(r for r, _, _ in runs)
            cpus = sorted(c for _, _, c in runs)
            med[server_name] = rates[len(rates) // 2]
            print(f"{server_name:8} {client:7} median {med[server_name]:,.0f} ticks/s (range "
                  f"{rates[0]:,.0f}-{rates[-1]:,.0f}), longest wait "
                  f"{max(w for _, w, _ in runs) * 1000:.0f} ms over {len(rates)} runs; server CPU "
                  f"{cpus[len(cpus) // 2]:.1f} us per tick (range {cpus[0]:.1f}-{cpus[-1]:.1f})")
        for server_name, _ in servers[1:]:
            print(f"{server_name} / echo, {client} client: {med[server_name] / med['echo']:.0%}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tools", default=None, help="folder of scr_speed_probe.py and "
                    "scr_echo_server.py: run the acceptance procedure (see the docstring)")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--baseline", default=None, help="with --tools: another checkout whose "
                    "`madsim serve` runs back to back with this one's")
    ap.add_argument("--pin", action="store_true", help="with --tools: client on CPU 0, servers on "
                    "CPU 1 (taskset): every round trip crosses cores")
    ap.add_argument("--ticks", type=int, default=20_000)
    ap.add_argument("--track", default="madsim-oval")
    ap.add_argument("--case", choices=sorted(CONTROLS), action="append",
                    help="control string(s) to time (default: all)")
    ap.add_argument("--stages", action="store_true", help="the compiled tick's stages in this "
                    "process, us per tick (component figures; see stage_costs)")
    ap.add_argument("--profile", default=None, help="write the server's cProfile output here "
                    "(one case only)")
    args = ap.parse_args()
    if args.stages:
        stage_costs("g-track-1" if args.track == "madsim-oval" else args.track)
        return
    if args.tools:
        probe_runs(args.tools, args.reps, args.ticks, args.baseline, args.pin)
        return
    cases = args.case or ["echo", "rest", "wall"]
    if args.profile and len(cases) != 1:
        ap.error("--profile needs exactly one --case")
    for case in cases:
        rate, cpu_us = run(args.ticks, args.track, CONTROLS[case], args.profile)
        what = ("do-nothing Python UDP server (transport floor)" if case == "echo" else
                f"madsim serve, sync mode, {args.track}, car {case}")
        print(f"{what}, one minimal client, {args.ticks} ticks: {rate:,.0f} ticks/s of wall time "
              f"({1e6 / rate:.1f} us per tick; real TORCS ~10,400); server CPU {cpu_us:.1f} us "
              "per tick", flush=True)
    if args.profile and os.path.exists(args.profile):
        pstats.Stats(args.profile).sort_stats("tottime").print_stats(25)


if __name__ == "__main__":
    main()
