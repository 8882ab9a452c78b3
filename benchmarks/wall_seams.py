"""Seams in the barrier lines: does a car sliding along a barrier catch on the joints?

A box (4.6 x 1.9 m, 1200 kg) is put every 0.25 m along each barrier of a track, 1 cm into it,
parallel to the track, 30 m/s along it and 0.5 m/s into it, and one `ContactSolver.resolve` is
run. The barrier rule acts along the contact normal only, so a contact on a smooth wall leaves
the speed along the track unchanged; a large change means the normal ran along the track (a
polyline joint, as barrier contacts had before they took the track's lateral direction as their
normal, and pit walls before their seams were dropped). Expected now: no placement changes it
by more than 0.5 m/s (wheel-2: 7, where its inner barrier folds over a bend's centre).

    python benchmarks/wall_seams.py [TRACK ...]     (default: madsim-oval e-track-2)

Prints, per track: placements, wall contacts, the worst change of the speed along the track
and how many placements changed it by more than 0.5 m/s.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from madsim.physics.contact import ContactSolver
from madsim.tracks import load_track

DT = 0.002
HALF_LENGTH, HALF_WIDTH, MASS, IZZ = 2.3, 0.95, 1200.0, 2000.0
STEP_M, INTO_M, V_ALONG, V_INTO = 0.25, 0.01, 30.0, 0.5


def sweep(name: str) -> tuple[int, int, float, int]:
    track = load_track(name)
    solver = ContactSolver(track, [HALF_LENGTH], [HALF_WIDTH], [MASS], [IZZ])
    count = hits = bad = 0
    worst = 0.0
    for side in (1.0, -1.0):
        for s in np.arange(0.0, track.length, STEP_M):
            left, right = track.barrier_offsets_at(np.array([s]))
            offset = float(left[0] if side > 0 else right[0])
            x, y, _, h = track.pose(np.array([s]), np.array([side * (offset - HALF_WIDTH + INTO_M)]))
            along = np.array([math.cos(h[0]), math.sin(h[0])])
            normal = np.array([-math.sin(h[0]), math.cos(h[0])])
            v = V_ALONG * along + side * V_INTO * normal
            st = [np.array(x, float), np.array(y, float), h.copy(), np.array([v[0]]),
                  np.array([v[1]]), np.array([0.0]), track.piece_at(np.array([s])).astype(np.int64)]
            rep = solver.resolve(*st, DT)
            change = abs(np.array([st[3][0], st[4][0]]) @ along - V_ALONG)
            count += 1
            hits += bool(rep.wall[0])
            worst = max(worst, change)
            bad += change > 0.5
    return count, hits, worst, bad


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("tracks", nargs="*", default=["madsim-oval", "e-track-2"])
    for name in ap.parse_args().tracks:
        count, hits, worst, bad = sweep(name)
        print(f"{name}: {count} placements, {hits} wall contacts, speed along the track changed "
              f"by at most {worst:.2f} m/s; by more than 0.5 m/s at {bad} ({100 * bad / count:.1f} %)")


if __name__ == "__main__":
    main()
