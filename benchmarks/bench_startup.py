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
  warm-up of every race kernel, heap freeze): what a client waits for before identifying;
- floors, what any program pays before madsim's own work: `numpy` (`import numpy`) and `numba`
  (`import numba` and the first call of a one-line `cache=True` function from its warm cache,
  which sets up numba's typing and target context: numba's fixed cost).
Children run with Python's bytecode cache on, as an installed package runs (PYTHONDONTWRITEBYTECODE,
if set, is removed for them; `--no-bytecode` keeps it: every start then compiles madsim's sources).
Prints each run's phases and the median total per case.
"""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

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


NUMPY = r"""
import time
t0 = time.perf_counter()
import numpy
print(f"import numpy total {time.perf_counter() - t0:.3f}")
"""

NUMBA = r"""
import time
t0 = time.perf_counter()
import numba
t1 = time.perf_counter()
from bench_startup_one_kernel import plus_one
plus_one(1.0)
t2 = time.perf_counter()
print(f"import {t1 - t0:.3f} first cached call {t2 - t1:.3f} total {t2 - t0:.3f}")
"""

ONE_KERNEL = """import numba


@numba.njit(cache=True)
def plus_one(x):
    return x + 1.0
"""

CHILD_ENV = dict(os.environ)


def _python(code: str, cwd: str | None = None) -> str:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                          timeout=300, env=CHILD_ENV, cwd=cwd).stdout.strip()


def _numba_floor(folder: str) -> str:
    module = Path(folder) / "bench_startup_one_kernel.py"
    if not module.exists():
        module.write_text(ONE_KERNEL)
        _python(NUMBA, cwd=folder)       # compile once: the runs measure the warm cache
    return _python(NUMBA, cwd=folder)


def _serve() -> str:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "madsim.cli", "serve", "--track", "g-track-1",
                             "--cars", "car1-trb1", "--port", str(port)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env=CHILD_ENV)
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
    ap.add_argument("--cases", default="env,vec,world,serve,numpy,numba",
                    help="comma-separated subset")
    ap.add_argument("--no-bytecode", action="store_true",
                    help="keep PYTHONDONTWRITEBYTECODE as it is (set: sources compile every start)")
    args = ap.parse_args()
    chosen = args.cases.split(",")
    if not args.no_bytecode:
        CHILD_ENV.pop("PYTHONDONTWRITEBYTECODE", None)
    print(f"load: {os.getloadavg()[0]:.2f} (1 min); bytecode cache "
          f"{'off' if 'PYTHONDONTWRITEBYTECODE' in CHILD_ENV else 'on'}")
    floor_dir = tempfile.TemporaryDirectory(prefix="madsim-bench-startup-")
    for case, run in (("env", lambda: _python(ENV)), ("vec", lambda: _python(VEC)),
                      ("world", lambda: _python(WORLD)), ("serve", _serve),
                      ("numpy", lambda: _python(NUMPY)),
                      ("numba", lambda: _numba_floor(floor_dir.name))):
        if case not in chosen:
            continue
        totals = []
        for _ in range(args.reps):
            line = run()
            totals.append(float(line.rsplit("total ", 1)[1]))
            print(f"{case:5} {line}", flush=True)
        print(f"{case:5} median total {sorted(totals)[len(totals) // 2]:.3f} s over {args.reps} runs")
    floor_dir.cleanup()
    print(f"load: {os.getloadavg()[0]:.2f} (1 min)")


if __name__ == "__main__":
    main()
