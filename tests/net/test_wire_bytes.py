"""The server's bytes on the wire, exactly: two cars driven over UDP by a scripted control
sequence (C++ and snakeoil layouts, focus requests, a malformed datagram, a non-stock layout,
a car scraping the barrier so the contact solver runs), with and without sensor noise and
TORCS's tick schedule. The byte stream must equal, byte for byte, what the engine's own
in-process doors give (World.step, SensorSuite.frame, protocol.encode_sensor_rows) for the
same controls, so the server's compiled tick changes no byte.

Before the compiled server tick (main 1af7f08) the two streams hashed (sha256 of every state
message of car 0 then car 1, in order) to
  plain: f41b3265202e7d687abd6e1e42e0d4b7f175d82a8ffd4967ae34b7836fa323d6
  noisy: 44d59f18eee900425cf22ed888af715cfc33ffa340cb70e0713bc69aae16f299
(`stream_hash(served_stream(**VARIANTS[name]))`), and after it to the same values. They hold
for that day's physics and car files only: a physics change moves them, while the equality
with the in-process doors, which this test asserts, stays.
"""

from __future__ import annotations

import hashlib
import math
import socket
import threading

import numpy as np
import pytest
from udp import free_ports

from madsim.cli import make_world_factory
from madsim.net import protocol as P
from madsim.net.server import ScrServer
from madsim.physics.schedule import make_clock
from madsim.physics.sensors import FOCUS_NONE, SensorSuite

TRACK = "madsim-oval"
TICKS = 240
WAIT_S = 30.0
START_S = 180.0       # the server's warm-up compiles the race kernels after an edit of one of them

VARIANTS = {
    "plain": dict(noisy=False, tick_schedule="fixed", countdown_ticks=3),
    "noisy": dict(noisy=True, tick_schedule="torcs", countdown_ticks=0),
}


def script(car: int, k: int) -> bytes:
    """Car `car`'s answer to its k-th state message."""
    if car == 0:      # the C++ client: a weave, a shift, braking, changing focus requests
        focus = 0 if k < 80 else 30 if k < 160 else None if k < 200 else -45
        return P.encode_controls(accel=1.0 if k < 160 else 0.0, brake=0.3 if 160 <= k < 200 else 0.0,
                                 gear=1 if k < 60 else 2, steer=0.05 * math.sin(k / 15.0), focus=focus)
    if k == 120:
        return b"(accel 0.7)(steer 0.1"                # malformed: applied as TORCS reads it
    if k == 121:
        return b"(steer 0.45) (accel 0.8)(gear 1)"     # well formed, not a stock layout
    if k == 122:
        return b"(accel nan)(gear 1)(steer 0.4)"
    # snakeoil: full throttle, then hard left into the barrier (the contact solver runs)
    return P.encode_controls(accel=1.0, gear=1, steer=0.0 if k < 40 else 0.45,
                             focus=[-10, 0, 10] if k % 50 < 25 else 0, style="snakeoil")


def served_stream(noisy: bool, tick_schedule: str, countdown_ticks: int, seed: int = 5) -> list[list[bytes]]:
    """Every state message each car's client received (in order) from a ScrServer on a thread."""
    port = free_ports(2)
    make = make_world_factory(TRACK, ["car1-trb1"], 2, fuel=True, damage=True)
    server = ScrServer(make, 2, port=port, seed=seed, noisy=noisy, tick_schedule=tick_schedule,
                       countdown_ticks=countdown_ticks, max_ticks=TICKS, start_timeout_s=WAIT_S)
    server.open()
    thread = threading.Thread(target=server.serve, daemon=True)
    thread.start()
    socks = []
    for car in range(2):
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.bind(("127.0.0.1", 0))
        s.settimeout(START_S)
        socks.append(s)
    try:
        for car, s in enumerate(socks):
            angles = P.SNAKEOIL_ANGLES_DEG if car else P.CPP_CLIENT_ANGLES_DEG
            s.sendto(P.encode_init("SCR", angles), ("127.0.0.1", port + car))
            assert s.recv(1000).startswith(P.IDENTIFIED)
            s.settimeout(WAIT_S)
        got: list[list[bytes]] = [[], []]
        for k in range(TICKS + countdown_ticks + 2):
            for car, s in enumerate(socks):
                data = s.recv(70000)
                if data.startswith(P.SHUTDOWN):
                    continue
                got[car].append(data)
                s.sendto(script(car, k), ("127.0.0.1", port + car))
        thread.join(WAIT_S)
        assert not thread.is_alive()
        return got
    finally:
        server.stop()
        for s in socks:
            s.close()


def in_process_stream(noisy: bool, tick_schedule: str, countdown_ticks: int, seed: int = 5):
    """The same race through World, SensorSuite and the protocol functions; also the World."""
    world = make_world_factory(TRACK, ["car1-trb1"], 2, fuel=True, damage=True)(seed)
    suite = SensorSuite(world, noisy=noisy, rng=np.random.default_rng([seed, 1]))
    for car, angles in enumerate((P.CPP_CLIENT_ANGLES_DEG, P.SNAKEOIL_ANGLES_DEG)):
        suite.set_angles(car, P.parse_init(P.encode_init("SCR", angles)).angles_deg)   # as sent
    clock = make_clock(tick_schedule)
    out: list[list[bytes]] = [[], []]
    countdown = countdown_ticks
    for k in range(TICKS + countdown_ticks + 1):
        flat = suite.frame().flat
        if countdown > 0:
            flat[:, 1] = -0.02 * countdown        # curLapTime, gear, focus during the countdown
            flat[:, 6] = 0.0
            flat[:, 74:79] = -1.0
        for car, msg in enumerate(P.encode_sensor_rows(flat)):
            out[car].append(msg)
        if k == TICKS + countdown_ticks:
            break
        ctl = [P.decode_controls(script(car, k)) for car in range(2)]
        suite.request_focus(np.arange(2), [FOCUS_NONE if c.focus is None else c.focus for c in ctl])
        if countdown > 0:
            countdown -= 1
        else:
            world.step(np.array([[c.steer, c.accel, c.brake, c.gear, c.clutch] for c in ctl]), clock.substeps())
    return out, world


def stream_hash(stream: list[list[bytes]]) -> str:
    return hashlib.sha256(b"".join(stream[0] + stream[1])).hexdigest()


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_served_bytes_equal_the_in_process_doors_for_a_scripted_race(variant):
    kw = VARIANTS[variant]
    served = served_stream(**kw)
    expected, world = in_process_stream(**kw)
    assert [len(s) for s in served] == [TICKS + kw["countdown_ticks"] + 1] * 2
    for car in range(2):
        for k, (got, want) in enumerate(zip(served[car], expected[car])):
            assert got == want, f"car {car}, state {k}: {got[:120]!r} != {want[:120]!r}"
    # the race exercised what it claims to: contact, focus readings, noise
    assert world._solver.stats["consults"] > 0
    assert any(b"(focus -1 " not in m for m in served[0])
