"""Track engine speed: load from XML and from the compiled form, locate and pose (one line each).

Run: python benchmarks/bench_tracks.py [TRACK]   (default: spring, 22 km, the longest TORCS track)
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from madsim.tracks import load_track
from madsim.tracks.compiled import save_compiled


def best_of(fn, repeat: int = 7) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    name = sys.argv[1] if len(sys.argv) > 1 else "spring"
    track = load_track(name)  # also compiles/loads the numba kernels
    print(f"track: {track.name} length {track.length:.2f} m, {track.n_pieces} pieces, {len(track.s)} samples")
    print(f"load from XML: {best_of(lambda: load_track(name)) * 1e3:.1f} ms")
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / f"{name}.mtrack"
        save_compiled(track, p)
        print(f"load compiled (.mtrack, {p.stat().st_size / 1024:.0f} KiB): {best_of(lambda: load_track(str(p))) * 1e3:.1f} ms")
    rng = np.random.default_rng(0)
    s = rng.uniform(0, track.length, 10_000)
    n = rng.uniform(-track.width / 2, track.width / 2, 10_000)
    x, y, _, _ = track.pose(s, n)
    track.locate(x[:10], y[:10])
    print(f"locate 10,000 points (global): {best_of(lambda: track.locate(x, y)) * 1e3:.2f} ms")
    print(f"locate 10,000 points (with s hint): {best_of(lambda: track.locate(x, y, s_hint=s)) * 1e3:.2f} ms")
    print(f"pose 10,000 points: {best_of(lambda: track.pose(s, n)) * 1e3:.2f} ms")
    print(f"surface_at 10,000 points: {best_of(lambda: track.surface_at(s, n)) * 1e3:.2f} ms")


if __name__ == "__main__":
    main()
