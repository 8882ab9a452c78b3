"""Session set-up shared by every test directory.

Tests that start an SCR server in another process (`madsim serve`, `ScrServer` threads, clients
with a bounded wait) assume the race kernels load from numba's disk cache in about a second.
On a fresh install (CI's clean clone) the first server compiles them instead (~25-45 s on a
2-core machine), which would eat that test's wait. So when the session holds such a test,
the kernels are compiled here once, into the disk cache the servers read: in this process (for
servers in threads) and, at the same time, in a child process started outside the repository
(for servers in subprocesses: with a non-editable install, as in CI, they import the installed
copy of madsim, whose cache entries are not this process's).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile

import pytest

SERVER_TEST_FILES = ("test_traffic_udp.py", "test_bad_input.py", "test_interrupts.py", "test_backend.py",
                     "test_start_and_schedule.py", "test_server.py", "test_wire_bytes.py",
                     "test_scenarios.py", "test_commands_as_written.py", "test_docs.py", "test_standin.py")


@pytest.fixture(scope="session", autouse=True)
def _race_kernels_compiled(request):
    if not any(item.path.name in SERVER_TEST_FILES for item in request.session.items):
        return
    child = subprocess.Popen([sys.executable, "-c", WARM_UP], cwd=tempfile.gettempdir())
    try:
        exec(WARM_UP, {})
    finally:
        assert child.wait(timeout=600) == 0, "compiling the race kernels in a child process failed"


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
