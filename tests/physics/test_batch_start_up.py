"""make_vec's batch loops come from numba's on-disk cache (issue 13:
they were per-process closures and typed.List methods, compiled again in every new process:
about 1.5 s in the first reset and 2 s in the first step)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from kernel_probe import DISPATCHERS

# A fresh process: a two-episode vector env (default scenario: contact on), reset, one step;
# then the madsim dispatchers that loaded from the cache and those that compiled.
PROBE = DISPATCHERS + r"""
import json, sys
import numba
import madsim

env = madsim.make_vec(num_envs=2)
env.reset(seed=0)
env.step(env.action_space.sample())

print(json.dumps({"hits": [n for n, d in dispatchers() if d.stats.cache_hits],
                  "misses": [n for n, d in dispatchers() if d.stats.cache_misses]}))
"""


@pytest.mark.skipif(os.environ.get("NUMBA_DISABLE_JIT") == "1", reason="no compiled code")
def test_a_fresh_process_loads_make_vecs_batch_loops_from_the_disk_cache():
    import madsim

    env = madsim.make_vec(num_envs=2)      # compiles (and caches) what this process has not yet
    env.reset(seed=0)
    env.step(env.action_space.sample())
    env.close()
    pyenv = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    out = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True,
                         timeout=120, env=pyenv, check=True).stdout
    found = json.loads(out.strip().splitlines()[-1])
    assert found["misses"] == []
    for name in ("advance_slots", "sense_slots", "race_positions"):
        assert f"madsim.physics.world_batch_kernels.{name}" in found["hits"]
