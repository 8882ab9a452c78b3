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
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
os.environ["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))

SERVER_TEST_FILES = ("test_traffic_udp.py", "test_bad_input.py", "test_interrupts.py", "test_backend.py",
                     "test_start_and_schedule.py", "test_server.py", "test_wire_bytes.py",
                     "test_scenarios.py", "test_commands_as_written.py", "test_docs.py", "test_standin.py")


def pytest_collection_finish(session):
    """Compile (or load) the race kernels once the session's tests are known, before the first
    test starts: outside every test's timeout, which a cold compile on a busy machine can eat."""
    if session.config.option.collectonly:
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
