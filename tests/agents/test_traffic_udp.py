"""Traffic behaviours as UDP clients (`madsim traffic`) against a real `madsim serve` subprocess:
the same seed gives the same trajectory as in-process (issue 6 acceptance).

Every server gets free ports of its own, every wait is bounded and every process started here
is killed in `finally`.
"""

from __future__ import annotations

import csv
import subprocess
import sys

import numpy as np
import pytest
from udp import default_sigint as _default_sigint
from udp import free_ports

from madsim.agents.traffic_client import (
    behaviour_rng,
    build_behaviour,
    parse_params,
)
from madsim.cli import main, make_world_factory
from madsim.physics.sensors import SensorSuite

TRACK = "madsim-oval"
TICKS = 400
SERVE = [sys.executable, "-m", "madsim.cli", "serve"]
TRAFFIC = [sys.executable, "-m", "madsim", "traffic"]
WAIT_S = 90.0           # bound on a whole race (start-up, numba cache, 400 ticks in lock-step)




def read_trace(path, n_cars: int):
    """(T, N, 2) x, y of every car at every tick of a `madsim serve --log-csv` trace."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    ticks = max(int(r["tick"]) for r in rows) + 1
    xy = np.full((ticks, n_cars, 2), np.nan)
    for r in rows:
        xy[int(r["tick"]), int(r["car"])] = float(r["x"]), float(r["y"])
    return xy


BEHAVIOUR, PARAMS = "RandomStopping", ["target_speed=12", "lane=0.3", "stop_probability=0.01",
                                       "max_stop_duration=1.0"]


def test_udp_traffic_follows_the_in_process_trajectory(tmp_path):
    """Two RandomStopping cars (random halts: the seed matters) on the server's grid, 400 ticks;
    the server's trace and an in-process World driven by the same behaviour code agree within
    1 cm (measured: 0.07 mm; the wire rounds sensors and controls)."""
    seed, server_seed, n = 4, 3, 2
    port = free_ports(n)
    trace = tmp_path / "trace.csv"
    procs = []
    try:
        server = subprocess.Popen(SERVE + ["--track", TRACK, "--clients", str(n), "--port", str(port),
                                           "--countdown", "0", "--max-ticks", str(TICKS),
                                           "--seed", str(server_seed), "--log-csv", str(trace),
                                           "--start-timeout", str(WAIT_S)],
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                  preexec_fn=_default_sigint)
        procs.append(server)
        client = subprocess.Popen(TRAFFIC + ["--port", str(port), "--count", str(n), "--seed", str(seed),
                                             "--behaviour", BEHAVIOUR,
                                             *[a for p in PARAMS for a in ("--param", p)]],
                                  stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                  preexec_fn=_default_sigint)
        procs.append(client)
        out, _ = client.communicate(timeout=WAIT_S)
        assert client.returncode == 0, out
        assert out.count("shutdown after") == n, out
        server_out, _ = server.communicate(timeout=WAIT_S)
        assert server.returncode == 0, server_out
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
            p.wait(timeout=10)
    remote = read_trace(trace, n)

    world = make_world_factory(TRACK, ["madsim-sedan"], n, fuel=True, damage=True)(server_seed)
    suite = SensorSuite(world)
    behaviours = [build_behaviour(BEHAVIOUR, parse_params(PARAMS)) for _ in range(n)]
    for k, b in enumerate(behaviours):
        b.reset(behaviour_rng(seed, k), {"index": k, "port": port + k, "tick_s": 0.02})
    local = np.zeros_like(remote)
    u = np.zeros((n, 5))
    for t in range(remote.shape[0]):
        local[t] = np.stack([world.x, world.y], axis=1)
        frame = suite.frame()
        for k, b in enumerate(behaviours):
            u[k, :4] = b.act(frame.row(k))
        world.step(u)
    assert remote.shape[0] == TICKS
    assert np.abs(local - remote).max() < 0.01
    # the run exercised what it claims: the cars drove and halted at their drawn times
    assert all(len(b.info["stops"]) >= 1 for b in behaviours)
    assert np.linalg.norm(remote[-1] - remote[0], axis=1).min() > 30.0


@pytest.mark.parametrize("args, message", [
    (["--behaviour", "ConstVell"], "did you mean 'ConstVel'"),
    (["--behaviour", "ConstVel", "--param", "target_sped=3"], "did you mean 'target_speed'"),
    (["--behaviour", "ConstVel", "--param", "lane"], "expected NAME=VALUE"),
    (["--behaviour", "RandomLaneSwitch", "--param", "lane_change_interval=0"], "must be > 0"),
    (["--behaviour", "ConstVel", "--count", "0"], "--count must be >= 1"),
])
def test_cli_errors_are_one_line_and_exit_2(args, message, capsys):
    assert main(["traffic", "--port", "9", *args]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_cli_reports_a_server_that_never_answers(capsys):
    port = free_ports(1)
    from madsim.agents import traffic_client
    with pytest.raises(RuntimeError, match=rf"traffic car 0 \(port {port}\): .*did not answer"):
        traffic_client.run_traffic("ConstVel", port=port, timeout_s=0.05, identify_tries=3)


def test_parse_params_reads_numbers_and_lists():
    assert parse_params(["target_speed=12.5", "lanes=[-0.6, 0.6]"]) == {"target_speed": 12.5,
                                                                        "lanes": [-0.6, 0.6]}
