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

from madsim.net.server import warm_up

# Run in a fresh process: build a 2-car world, run the server's warm-up (every kernel a race
# calls, contact included), then list the madsim dispatchers that compiled instead of loading.
PROBE = r"""
import json, sys
import numba
from madsim.cli import make_world_factory
from madsim.net.server import warm_up
warm_up(make_world_factory("madsim-oval", ["car1-trb1"], 2, fuel=True, damage=True)(0))
hits, misses = [], []
for name, mod in list(sys.modules.items()):
    if not name.startswith("madsim."):
        continue
    for attr, obj in vars(mod).items():
        if isinstance(obj, numba.core.dispatcher.Dispatcher) and obj.__module__ == name:
            stats = obj.stats
            if stats.cache_misses:
                misses.append(f"{name}.{attr}")
            elif stats.cache_hits:
                hits.append(f"{name}.{attr}")
print(json.dumps({"hits": hits, "misses": misses}))
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
    # the kernels that used to be compiled per process are among the cache hits
    assert "madsim.physics.contact_kernels.advance_until_near" in found["hits"]
    assert "madsim.physics.contact_kernels._respond" in found["hits"]


def test_warm_up_leaves_the_world_it_is_given_only():
    # the warm-up runs on a throwaway world: a race's own world is built after it, so the warm
    # world's contact and ticks never reach a client (its car 0 is put on the barrier)
    world = _world(2)
    warm_up(world)
    assert world._solver.stats["consults"] > 0          # the narrow phase ran
    fresh = _world(2)
    assert fresh.time == 0.0 and np.all(fresh.column("damage") == 0.0)
