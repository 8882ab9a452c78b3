"""Session set-up shared by every test directory.

One copy of madsim for the whole session. numba's disk cache is per source file, so two copies
of the package (the checkout the tests import, and a non-editable install in site-packages, as
in CI's clean clone) compile every kernel twice. So PYTHONPATH is set to the repository here,
before any test starts a process: `madsim serve`, `python -m madsim.cli`, Ray's workers and
every other child import the checkout, as this process does, and load the kernels this
process (or an earlier child) compiled into its disk cache. (Packaging is tested by
tests/packaging, which builds the wheel and reads it.)

Tests that start an SCR server in another process (`madsim serve`, `ScrServer` threads, clients
with a bounded wait) assume the race kernels load from numba's disk cache in about a second.
On a fresh install (CI's clean clone) the first server compiles them instead (~25-45 s on a
2-core machine), which would eat that test's wait. So when the session holds such a test,
the kernels are compiled here once, into the disk cache the servers read, after collection
(outside any test's timeout).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))

SERVER_TEST_FILES = ("test_traffic_udp.py", "test_bad_input.py", "test_interrupts.py", "test_backend.py",
                     "test_start_and_schedule.py", "test_server.py", "test_wire_bytes.py",
                     "test_scenarios.py", "test_commands_as_written.py", "test_docs.py", "test_standin.py")


WARMED = "MADSIM_TESTS_KERNELS_WARM"   # set by the xdist controller once it compiled the kernels


def _xdist_controller(config) -> bool:
    """True in the process that starts pytest-xdist's workers (`-n N`), before it starts them."""
    return (not hasattr(config, "workerinput") and bool(getattr(config.option, "numprocesses", None))
            and getattr(config.option, "dist", "no") != "no" and not config.option.collectonly)


def pytest_sessionstart(session):
    """Under pytest-xdist: compile (or load) the kernels here, in the controller, before the
    workers start (xdist starts them in its own, later, sessionstart). Two workers otherwise each
    compile the same kernels at the same time (twice the CPU of a cold install, and the first
    tests of both wait). Two child processes compile at once, one per core, into numba's disk
    cache the workers then load from: the race kernels with the single env's (World, contact,
    sensors, server tick, codec, agents), and make_vec's batch kernels with the physics kernel
    alone."""
    if not _xdist_controller(session.config):
        return
    start = time.monotonic()
    children = [subprocess.Popen([sys.executable, "-c", code], cwd=ROOT)
                for code in (WARM_UP + WARM_UP_ENVS, WARM_UP_BATCH)]
    codes = [child.wait() for child in children]
    if any(codes):
        raise pytest.UsageError(f"the kernel warm-up failed (exit codes {codes})")
    print(f"madsim kernels compiled or loaded in {time.monotonic() - start:.0f} s", file=sys.stderr)
    os.environ[WARMED] = "1"


# The longest tests (seconds on a warm cache, 2-core AMD EPYC, session 11), started first under
# xdist so that neither worker is left with one of them at the end while the other idles.
LONGEST_FIRST = ("test_every_readme_and_docs_command_runs_as_written", "test_exp6_same_seed_and_hash_seed",
                 "test_one_training_iteration_with_two_rollout_workers",
                 "test_world_batch_equals_the_world_bit_for_bit_over_hills",
                 "test_smoke_run_writes_a_complete_result_folder", "test_threads_give_bit_identical_slots",
                 "test_mixed_traffic_on_the_narrow_street", "test_threaded_contact_stepping_is_bit_identical")


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(config, items):
    """Under xdist (in each worker; every worker sorts alike): the longest tests first, the rest
    in collection order. And with `--dist loadgroup`, each `xdist_group` test's node id gets its
    group's suffix (`...@name`), which xdist's scheduler groups by: pytest-xdist 3.8 writes it to
    `item._nodeid`, which pytest 9 no longer reads (the id is `item._id`), so without this the
    groups are silently ignored."""
    if not hasattr(config, "workerinput"):
        return
    if config.getvalue("loadgroup"):
        from _pytest.nodeid import coerce_node_id

        for item in items:
            names = sorted({str(m.args[0] if m.args else m.kwargs.get("name", "default"))
                            for m in item.iter_markers("xdist_group")})
            if names and "@" not in item.nodeid.rpartition("]")[2]:
                item._id = coerce_node_id(f"{item.nodeid}@{'_'.join(names)}")
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}

    def key(item):
        return next((rank[n] for n in LONGEST_FIRST if n in item.name), len(rank))

    items.sort(key=key)     # stable: collection order within each rank


def pytest_collection_finish(session):
    """Compile (or load) the race kernels once the session's tests are known, before the first
    test starts: outside every test's timeout, which a cold compile on a busy machine can eat."""
    if session.config.option.collectonly or os.environ.get(WARMED):
        return
    if any(item.path.name in SERVER_TEST_FILES for item in session.items):
        exec(WARM_UP, {})


WARM_UP = """
import numpy as np
from madsim.cars import load_car
from madsim.net import protocol
from madsim.net.server import warm_up
from madsim.physics import SensorSuite, World
from madsim.tracks import load_track

world = World(load_track("madsim-road"), [load_car("madsim-sedan")] * 2, rng=np.random.default_rng(0))
warm_up(world)
rows = SensorSuite(world, noisy=False, rng=np.random.default_rng(0)).frame().flat
protocol.decode_sensors(protocol.encode_sensor_rows(rows)[0])      # the clients' side
"""

WARM_UP_ENVS = """
from pathlib import Path

import madsim
from madsim.envs import MadrasEnv

for name in ("single_lap", "mixed_traffic"):
    env = MadrasEnv(Path(madsim.__file__).parent / "envs" / "configs" / f"{name}.yml")
    env.reset(seed=0)
    for _ in range(20):
        env.step(env.action_space.sample())
"""

# make_vec's batch kernels, and the physics kernel called on its own (tests/physics calls it
# from Python and from test kernels): none of these is in the other two warm-ups
WARM_UP_BATCH = """
from pathlib import Path

import numpy as np
import madsim
import madsim.physics.world as W
from madsim.cars import load_car
from madsim.tracks import load_track

for name in ("single_lap", "mixed_traffic"):
    venv = madsim.make_vec(Path(madsim.__file__).parent / "envs" / "configs" / f"{name}.yml", num_envs=2)
    venv.reset(seed=0)
    for _ in range(20):
        venv.step(venv.action_space.sample())
w = W.World(load_track("madsim-oval"), [load_car("madsim-sedan")], np.random.default_rng(0), contact=True)
w.reset(np.array([[100.0, 0.0, 20.0]]), gears=2)
W.kernel.advance_car(w.state, 0, w._cp, w._curve_w, w._curve_t, w._pt, w._surf, w._tsc,
                     np.array([[0.0, 0.8, 0.0, 3.0, 0.0]]), 1, W.DT, False)
"""
