"""`world_batch_kernels.quiet`: the batch's cheap stand-in for the contact broad phase after a
whole tick. Where it answers True the broad phase itself (same state, same caches) returns 0 and
writes exactly the flags and slack `quiet` wrote, changing no cache; where it answers False
it has written nothing. Checked over random moves of a few cars from a measured state (some
small enough to keep every cached clearance, some not, some bringing cars together)."""

from __future__ import annotations

import numpy as np
import pytest

from madsim.physics import layout as L
from madsim.physics.contact import ContactSolver
from madsim.physics.contact_kernels import _broad_phase
from madsim.physics.world_batch_kernels import quiet as quiet_check
from madsim.tracks import load_track

HL, HW, MASS, IZZ = 2.3, 0.95, 1200.0, 2000.0


@pytest.mark.parametrize("n", [1, 3])
def test_quiet_agrees_with_the_broad_phase(n):
    track = load_track("madsim-oval")
    solver = ContactSolver(track, np.full(n, HL), np.full(n, HW), np.full(n, MASS), np.full(n, IZZ))
    args = solver.broad_phase_args
    s0 = 10.0 + 9.0 * np.arange(n)
    x, y, _, yaw = (np.ascontiguousarray(a, dtype=np.float64) for a in track.pose(s0, np.zeros(n)))
    assert _broad_phase(x, y, yaw, track.piece_at(s0).astype(np.int64), *args) == 0  # measured
    rng = np.random.default_rng(1)
    seen = {True: 0, False: 0}
    for _ in range(300):
        scale = rng.choice([0.05, 0.5, 3.0])
        ds, dn = rng.normal(0.0, scale, n), rng.normal(0.0, scale, n)
        if n > 1 and rng.random() < 0.2:
            ds[1] = s0[0] - s0[1] + rng.normal(0.0, 1.0)          # car 1 onto car 0
        s, tpos = s0 + ds, dn
        px, py, _, pyaw = track.pose(s, tpos)
        st = np.zeros((n + 2, L.N_STATE), order="F")           # rows 1..n: this slot
        st[1:n + 1, L.S_X], st[1:n + 1, L.S_Y] = px, py
        st[1:n + 1, L.S_YAW] = pyaw + rng.normal(0.0, 0.05 * scale, n)
        piece = np.zeros(n + 2, dtype=np.int64)
        piece[1:n + 1] = track.piece_at(s)
        mine = [a.copy() for a in args]
        theirs = [a.copy() for a in args]
        quiet = quiet_check(st, 1, n + 1, piece, mine[0].shape[0], *mine[2:])
        seen[bool(quiet)] += 1
        if not quiet:
            assert all(np.array_equal(a, b) for a, b in zip(mine, args))    # wrote nothing
            continue
        near = _broad_phase(np.ascontiguousarray(st[1:n + 1, L.S_X]),
                            np.ascontiguousarray(st[1:n + 1, L.S_Y]),
                            np.ascontiguousarray(st[1:n + 1, L.S_YAW]), piece[1:n + 1], *theirs)
        assert near == 0
        for a, b in zip(mine, theirs):                       # flags, slack and every cache
            assert np.array_equal(a, b)
    assert seen[True] > 20 and seen[False] > 20
