"""No compile after start-up: every kernel a race runs comes from numba's on-disk cache
(issue 13: a server compiling its contact stepper on the first tick stalled SCR clients for
about a second, longer than their 1 s timeout)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from kernel_probe import DISPATCHERS

from madsim.net.server import warm_up

# Run in a fresh process: build a 2-car world, run the server's warm-up (every kernel a race
# calls, contact included), then list the madsim dispatchers that compiled instead of loading.
PROBE = DISPATCHERS + r"""
import json, sys
import numba
import numpy as np
from madsim.cli import make_world_factory
from madsim.net import protocol as P
from madsim.net.server import warm_up
from madsim.net.server_tick import DECODE, DONE, SENSE, ServerTick
from madsim.physics.sensors import SensorSuite

make = make_world_factory("madsim-oval", ["car1-trb1"], 2, fuel=True, damage=True)
warm_up(make(0))
hits = [name for name, d in dispatchers() if d.stats.cache_hits]
misses = [name for name, d in dispatchers() if d.stats.cache_misses]
loaded = {name: len(d.overloads) for name, d in dispatchers()}
# a race as the server runs it (its compiled tick): a countdown, focus asked, car 0 at full
# throttle and full left lock into the barrier, car 1 braking in snakeoil's layout
world = make(0)
suite = SensorSuite(world, rng=np.random.default_rng(1))
suite.set_angles(0, P.CPP_CLIENT_ANGLES_DEG)
inbox = np.zeros((2, 65536), dtype=np.uint8)
inlen = np.full(2, -1)
race = ServerTick(world, suite, np.zeros((2, 5)), inbox, inlen, 10000.0)
race.run(SENSE, DONE, stepping=False, nsub=0, countdown=3)
answers = (P.encode_controls(accel=1.0, steer=1.0), P.encode_controls(brake=1.0, gear=0, style="snakeoil"))
for tick in range(200):
    for car, msg in enumerate(answers):
        inbox[car, :len(msg)] = np.frombuffer(msg, dtype=np.uint8)
        inlen[car] = len(msg)
    race.run(DECODE, DONE, stepping=tick >= 3, nsub=10, countdown=max(2 - tick, 0))
# and the in-process doors on the same kind of race
world2 = make(0)
suite = SensorSuite(world2, rng=np.random.default_rng(1))
controls = np.array([[1.0, 1.0, 0.0, 1.0, 0.0], [0.0, 0.0, 1.0, 0.0, 0.0]])
for tick in range(200):
    suite.request_focus(np.arange(2), np.zeros(2))
    P.encode_sensor_rows(suite.frame().flat)
    P.decode_controls(b"(accel 1)(brake 0)(gear 1)(steer 1)(clutch 0)(focus 0)(meta 0)")
    world2.step(controls)
after_warm_up = [name for name, d in dispatchers() if len(d.overloads) > loaded.get(name, 0)]
print(json.dumps({"hits": hits, "misses": misses, "after_warm_up": after_warm_up,
                  "consults": world._solver.stats["consults"] + world2._solver.stats["consults"],
                  "server_consults": world._solver.stats["consults"]}))
"""


def _world(n_cars: int):
    from madsim.cli import make_world_factory

    return make_world_factory("madsim-oval", ["car1-trb1"], n_cars, fuel=True, damage=True)(0)


@pytest.mark.skipif(os.environ.get("NUMBA_DISABLE_JIT") == "1", reason="no compiled code")
def test_a_fresh_process_loads_every_race_kernel_from_the_disk_cache():
    warm_up(_world(2))   # compiles (and caches) whatever this test process has not yet
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    out = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True,
                         timeout=120, env=env, check=True).stdout
    found = json.loads(out.strip().splitlines()[-1])
    assert found["misses"] == []
    # the race touched the barrier, and nothing was loaded or compiled after the warm-up
    assert found["consults"] > 0 and found["server_consults"] > 0
    assert found["after_warm_up"] == []
    # the kernels that used to be compiled per process are among the cache hits
    assert "madsim.physics.world_tick.finish_contact" in found["hits"]   # the contact path's
    assert "madsim.net.server_tick.server_tick" in found["hits"]
    # and the narrow phase's consultation from compiled code, which most of a race's are
    assert "madsim.physics.pymunk_direct.narrow_direct" in found["hits"]


def test_warm_up_leaves_the_world_it_is_given_only():
    # the warm-up runs on a throwaway world: a race's own world is built after it, so the warm
    # world's contact and ticks never reach a client (its car 0 is put on the barrier)
    world = _world(2)
    warm_up(world)
    assert world._solver.stats["consults"] > 0          # the narrow phase ran
    fresh = _world(2)
    assert fresh.time == 0.0 and np.all(fresh.column("damage") == 0.0)
