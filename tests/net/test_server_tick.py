"""The server's compiled tick (`madsim.net.server_tick`) against the Python path of each of its
stages, and the address table that hands it its arrays."""

from __future__ import annotations

import numpy as np
import pytest

from madsim.cli import make_world_factory
from madsim.net import protocol as P
from madsim.array_table import address_table
from madsim.net.server import MAX_DAMAGE, RECV_BYTES
from madsim.net.server_tick import DECODE, DONE, EVENT, SENSE, ServerTick
from madsim.physics.layout import S_SHIFT
from madsim.physics.sensors import SensorSuite


def answers(k: int) -> list[bytes]:
    """Tick k's control datagrams of two cars: car 0 weaves with focus requests (C++ layout),
    car 1 steers into the barrier (snakeoil layout), with a malformed and a non-stock one."""
    car0 = P.encode_controls(accel=1.0, gear=1, steer=0.1 * np.sin(k / 9.0), focus=(k * 7) % 200 - 100)
    car1 = (b"(accel 0.9)(steer 0.1" if k == 40 else b"(steer 0.1) (accel 1)(gear 1)" if k == 41 else
            P.encode_controls(accel=1.0, gear=1, steer=0.0 if k < 45 else 0.45, style="snakeoil"))
    return [car0, car1]


def race(compiled: bool, noisy: bool) -> tuple[list[list[bytes]], object, int]:
    """The messages sent each tick (and whether the tick was the one compiled call), the World,
    and how many focus readings the Python path (SensorSuite.finish_frame) made after the
    countdown."""
    world = make_world_factory("madsim-oval", ["car1-trb1"], 2, fuel=True, damage=True)(3)
    suite = SensorSuite(world, noisy=noisy, rng=np.random.default_rng(1))
    inbox = np.zeros((2, RECV_BYTES), dtype=np.uint8)
    inlen = np.full(2, -1, dtype=np.int64)
    tick = ServerTick(world, suite, np.zeros((2, 5)), inbox, inlen, MAX_DAMAGE)
    tick.compiled = compiled and tick.compiled     # False: every stage in Python
    finish, python_focus = suite.finish_frame, []
    suite.finish_frame = lambda flat, cars, due: (python_focus.append(due is not None and int(np.sum(due)))
                                                  or finish(flat, cars, due))
    sent = []
    status = tick.run(SENSE, DONE, False, 0, 2)
    for k in range(240):
        sent.append([bytes(tick.message(i)) for i in range(2)] + [status == DONE])
        for i, msg in enumerate(answers(k)):
            inbox[i, :len(msg)] = np.frombuffer(msg, dtype=np.uint8)
            inlen[i] = -1 if k == 70 and i == 1 else len(msg)     # car 1 silent once
        countdown = max(1 - k, 0)
        if countdown == 0 and k == 1:
            python_focus.clear()        # the countdown's frames are Python's (no focus shown)
        status = tick.run(DECODE, DONE, k >= 2, 10, countdown)
    return sent, world, sum(python_focus)


@pytest.mark.parametrize("noisy", [False, True])
def test_the_compiled_tick_sends_the_bytes_of_the_python_path_of_every_stage(noisy):
    compiled, world, focus_in_python = race(True, noisy)
    python, world_py, _ = race(False, noisy)
    for k, (a, b) in enumerate(zip(compiled, python)):
        assert a[:2] == b[:2], f"state {k}"
    assert world._solver.stats["consults"] > 0               # the barrier was hit: contact ran
    assert np.array_equal(world.state, world_py.state)
    # the usual tick was the one compiled call, nothing left to Python; noise is drawn in Python
    whole = sum(a[2] for a in compiled)
    assert whole == 0 if noisy else whole > 100
    # car 0 asks for focus every tick: one reading per simulated second, from the compiled call
    # too (the Python path only where it adds the noise)
    assert sum(P.decode_sensors(a[0])["focus"][0] != -1.0 for a in compiled) >= 4
    assert focus_in_python >= 4 if noisy else focus_in_python == 0
    assert not any(b[2] for b in python)


def test_a_restart_request_and_a_new_lap_are_events_for_the_loop():
    world = make_world_factory("madsim-oval", ["car1-trb1"], 1, fuel=True, damage=True)(0)
    suite = SensorSuite(world, rng=np.random.default_rng(1))
    inbox = np.zeros((1, RECV_BYTES), dtype=np.uint8)
    inlen = np.zeros(1, dtype=np.int64)
    tick = ServerTick(world, suite, np.zeros((1, 5)), inbox, inlen, MAX_DAMAGE)
    tick.run(SENSE, DONE, False, 0, 0)
    msg = P.encode_controls(accel=0.0, brake=1.0, gear=0, focus=None)
    inbox[0, :len(msg)] = np.frombuffer(msg, dtype=np.uint8)
    inlen[0] = len(msg)
    assert tick.run(DECODE, DONE, True, 10, 0) == DONE
    msg = P.encode_controls(accel=0.0, brake=1.0, gear=0, focus=None, meta=1)
    inbox[0, :len(msg)] = np.frombuffer(msg, dtype=np.uint8)
    inlen[0] = len(msg)
    assert tick.run(DECODE, DONE, True, 10, 0) == DONE | EVENT and tick.meta[0] == 1
    tick.laps_seen[0] -= 1                   # as if the car had just completed a lap
    inlen[0] = -1
    assert tick.run(DECODE, DONE, True, 10, 0) == DONE | EVENT and tick.meta[0] == 0


def test_address_table_refuses_an_array_of_another_kind():
    spec = [("x", "f8", 1, "C"), ("grid", "f8", 2, "F")]
    table = address_table([np.zeros(3), np.zeros((2, 4), order="F")], spec)
    assert table.shape == (2, 3) and list(table[1, 1:]) == [2, 4]
    with pytest.raises(ValueError, match="grid must be a F-contiguous 2-d f8 array"):
        address_table([np.zeros(3), np.zeros((2, 4))], spec)
    with pytest.raises(ValueError, match="x must be a C-contiguous 1-d f8 array, got int64"):
        address_table([np.zeros(3, dtype=np.int64), np.zeros((2, 4), order="F")], spec)


@pytest.mark.parametrize("compiled", [True, False])
def test_a_silent_client_keeps_its_own_throttle_after_a_shift_capped_it(compiled):
    """A shift caps the throttle at 0.1 for the rest of that tick (TORCS writes the cap into
    ctrl->accelCmd, which the robot rewrites at its next call). The server runs the tick on its
    own copy of the controls: a client that then goes silent keeps the accel it sent (1.0), as
    TORCS's scr_server reuses its last action, and the car moves as a World stepped with it."""
    def world():
        return make_world_factory("madsim-oval", ["car1-trb1"], 1, fuel=True, damage=True)(0)
    served, ref = world(), world()
    suite = SensorSuite(served, rng=np.random.default_rng(1))
    inbox = np.zeros((1, RECV_BYTES), dtype=np.uint8)
    inlen = np.full(1, -1, dtype=np.int64)
    controls = np.zeros((1, 5))
    tick = ServerTick(served, suite, controls, inbox, inlen, MAX_DAMAGE)
    tick.compiled = compiled and tick.compiled
    tick.run(SENSE, DONE, False, 0, 0)
    capped = 0
    for k in range(120):
        gear = 1 if k < 60 else 2                       # the 1-2 shift at tick 60, then silence
        if k <= 60:
            msg = P.encode_controls(accel=1.0, gear=gear, focus=None)
            inbox[0, :len(msg)] = np.frombuffer(msg, dtype=np.uint8)
            inlen[0] = len(msg)
        else:
            inlen[0] = -1
        tick.run(DECODE, DONE, True, 10, 0)
        u = np.array([[0.0, 1.0, 0.0, gear, 0.0]])
        ref.step(u)
        assert controls[0, 1] == 1.0, f"tick {k}: the client's accel was overwritten"
        assert np.array_equal(served.state, ref.state), f"tick {k}"
        capped += served.state[0, S_SHIFT] > 0.0
    assert capped > 0                                   # the shift (and its cap) did happen
