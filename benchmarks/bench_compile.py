"""Where a cold start's compile time goes: numba's compile of every kernel `madsim serve`'s
warm-up needs, per dispatcher, from an empty numba cache.

Run: python benchmarks/bench_compile.py [--top 30] [--signatures]

Runs in a fresh process with NUMBA_CACHE_DIR pointing at a new temporary folder, so everything
compiles; builds the server's World (g-track-1, car1-trb1) and runs `net.server.warm_up` on it.
Prints the process CPU time of both, then per dispatcher (numba's `numba:compile` events,
CPU time) the exclusive and inclusive compile time and how many signatures it compiled, most
expensive first. A madsim kernel compiled more than once is a cold-start cost to look at (a
literal argument, a read-only view where another caller passes a writable one); `--signatures`
lists the signatures of those.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile

PROBE = r"""
import collections, sys, time
from numba.core import event

top, show = int(sys.argv[1]), sys.argv[2] == "1"
stack, own, total, count = [], collections.Counter(), collections.Counter(), collections.Counter()
signatures = collections.defaultdict(list)


class Compiles(event.Listener):
    def on_start(self, ev):
        stack.append([time.process_time(), 0.0])

    def on_end(self, ev):
        start, children = stack.pop()
        spent = time.process_time() - start
        f = ev.data["dispatcher"].py_func
        name = f"{f.__module__}.{f.__qualname__}"
        own[name] += spent - children
        total[name] += spent
        count[name] += 1
        signatures[name].append(str(ev.data["args"]))
        if stack:
            stack[-1][1] += spent


event.register("numba:compile", Compiles())
from madsim.cli import make_world_factory
from madsim.net.server import warm_up

t0 = time.process_time()
warm_up(make_world_factory("g-track-1", ["car1-trb1"], 1, fuel=True)(0))
print(f"World + warm_up: {time.process_time() - t0:.1f} s CPU; compiling {sum(own.values()):.1f} s, "
      f"{sum(count.values())} signatures of {len(count)} dispatchers")
print(" own s  incl s  signatures  dispatcher")
for name, s in own.most_common(top):
    print(f"{s:6.2f}  {total[name]:6.2f}  {count[name]:10d}  {name}")
twice = sorted(n for n, k in count.items() if k > 1 and n.startswith("madsim."))
print("madsim kernels compiled more than once:", ", ".join(twice) or "none")
if show:
    for name in twice:
        print(name)
        for sig in signatures[name]:
            print("   ", sig)
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--top", type=int, default=30, help="dispatchers to list")
    ap.add_argument("--signatures", action="store_true", help="signatures of madsim kernels "
                    "compiled more than once")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="madsim-numba-") as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        subprocess.run([sys.executable, "-c", PROBE, str(args.top), "1" if args.signatures else "0"],
                       env=env, check=True)


if __name__ == "__main__":
    main()
