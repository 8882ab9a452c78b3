"""Start-up as users pay it: fresh processes, compile or cache load included.

Run: python benchmarks/bench_startup.py [--reps 5]

Cases, each in a new Python process (numba's on-disk cache as the previous runs left it; the
first repetition after a source change compiles):
- `env`: `from madsim.envs import MadrasEnv`, `MadrasEnv()`, `reset(seed=0)`, one `step`
  (issue 13's aim: at most 1.0 s in total);
- `world`: import `World`, load g-track-1 and car1-trb1, build the World and a SensorSuite, one
  tick (physics + sensors + encoder);
- `vec`: `import madsim`, `make_vec(num_envs=64)` (default scenario), `reset(seed=0)`, one
  `step` of 64 actions (the batch loops of `physics/world_batch.py` are cached kernels too);
- `serve`: `madsim serve` from the process start to "waiting for" clients (imports, world,
  warm-up of every race kernel, heap freeze): what a client waits for before identifying.
Prints each run's phases and the median total per case.
"""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import time

def _first_step(imports: str, make: str) -> str:
    """A script timing `imports`, `make` (which binds `env`), `reset(seed=0)` and one step."""
    return f"""
import time
t0 = time.perf_counter()
{imports}
t1 = time.perf_counter()
{make}
t2 = time.perf_counter()
env.reset(seed=0)
t3 = time.perf_counter()
env.step(env.action_space.sample())
t4 = time.perf_counter()
print(f"import {{t1 - t0:.3f}} make {{t2 - t1:.3f}} reset {{t3 - t2:.3f}} "
      f"first step {{t4 - t3:.3f}} total {{t4 - t0:.3f}}")
"""


ENV = _first_step("from madsim.envs import MadrasEnv", "env = MadrasEnv()")
VEC = _first_step("import madsim", "env = madsim.make_vec(num_envs=64)")

WORLD = r"""
import time
t0 = time.perf_counter()
import numpy as np
from madsim.cars import load_car
from madsim.net import protocol as P
from madsim.physics.sensors import SensorSuite
from madsim.physics.world import World
from madsim.tracks import load_track
t1 = time.perf_counter()
world = World(load_track("g-track-1"), [load_car("car1-trb1")], np.random.default_rng(0))
suite = SensorSuite(world)
t2 = time.perf_counter()
P.encode_sensor_rows(suite.frame().flat.astype(np.float32))
world.step(np.array([[0.0, 1.0, 0.0, 1.0, 0.0]]))
t3 = time.perf_counter()
print(f"import {t1 - t0:.3f} make {t2 - t1:.3f} first tick {t3 - t2:.3f} total {t3 - t0:.3f}")
"""


def _python(code: str) -> str:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                          timeout=300).stdout.strip()


def _serve() -> str:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "madsim.cli", "serve", "--track", "g-track-1",
                             "--cars", "car1-trb1", "--port", str(port)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        for line in proc.stdout:
            if "waiting for" in line:
                return f"ready for clients after {time.perf_counter() - t0:.3f} total {time.perf_counter() - t0:.3f}"
        raise SystemExit("madsim serve ended before waiting for clients")
    finally:
        proc.kill()
        proc.wait()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--cases", default="env,vec,world,serve", help="comma-separated subset")
    args = ap.parse_args()
    chosen = args.cases.split(",")
    print(f"load: {os.getloadavg()[0]:.2f} (1 min)")
    for case, run in (("env", lambda: _python(ENV)), ("vec", lambda: _python(VEC)),
                      ("world", lambda: _python(WORLD)), ("serve", _serve)):
        if case not in chosen:
            continue
        totals = []
        for _ in range(args.reps):
            line = run()
            totals.append(float(line.rsplit("total ", 1)[1]))
            print(f"{case:5} {line}", flush=True)
        print(f"{case:5} median total {sorted(totals)[len(totals) // 2]:.3f} s over {args.reps} runs")
    print(f"load: {os.getloadavg()[0]:.2f} (1 min)")


if __name__ == "__main__":
    main()
