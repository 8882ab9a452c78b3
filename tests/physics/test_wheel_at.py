"""`suspension.wheel_at`: a wheel's place in track coordinates on a curve (session 14), against
the exact arc geometry of a circle and against the track's own `locate`."""

import math

import numpy as np
import pytest

from madsim.physics import layout as L
from madsim.physics.suspension import wheel_at


def _exact(c, n, dx, dy):
    """(along the centre line, across) of the point dx ahead along the tangent and dy to the
    left of a point at lateral offset n on a circle of curvature c (left turn: c > 0)."""
    r = 1.0 / c - n - dy          # signed distance from the curve's centre (c's sign), before dx
    along = math.atan(dx / r) / c
    across = (1.0 / c - math.copysign(math.hypot(dx, r), c)) - n
    return along, across


@pytest.mark.parametrize("radius", [30.0, 60.0, -60.0, 200.0])
@pytest.mark.parametrize("n", [-8.0, 0.0, 8.4])
def test_wheel_at_follows_the_arc_to_second_order(radius, n):
    # first order in c dx along (its error is (dx / g) u^2 / 3 with u = c dx / g, g = 1 - c (n + dy): 4 mm
    # for an axle 1.6 m from the CG, 8.4 m inside a 30 m turn; 0.5 mm on g-track-2's curb),
    # second order across
    pt = np.zeros((1, L.N_PIECE))
    pt[0, L.P_CURV] = 1.0 / radius
    # a wheel's offsets: up to 1.6 m along (the cars' axles), 0.8 m across
    for dx, dy in ((1.3, 0.8), (1.3, -0.8), (-1.3, 0.8), (-1.3, -0.8), (1.6, 0.0)):
        da, dn = wheel_at(pt, 0, n, dx, dy)
        ea, en = _exact(1.0 / radius, n, dx, dy)
        u = dx / (radius * (1.0 - (n + dy) / radius))
        assert da == pytest.approx(ea, abs=abs(da) * u * u / 3.0 * 1.05 + 1e-9)
        assert abs(da - ea) < 5e-3
        assert dn == pytest.approx(en, abs=1e-4)
        # the old linear step was off by far more than that wherever c n is not small
        if abs(n / radius) > 0.1:
            assert abs(dx - ea) > 0.1


def test_wheel_at_is_the_identity_on_a_straight():
    pt = np.zeros((1, L.N_PIECE))
    assert wheel_at(pt, 0, 5.0, 1.3, -0.8) == (1.3, -0.8)


def test_wheel_at_matches_the_tracks_own_locate():
    # g-track-2's turn at 1515 m, a car 8.4 m left of the centre line (the curb passage)
    from madsim.cars import load_car
    from madsim.physics.world import World
    from madsim.tracks import load_track

    track = load_track("g-track-2")
    world = World(track, [load_car("car1-trb1")], np.random.default_rng(0))
    pt = world._pt
    s0, n0 = 1515.0, 8.4
    p = int(track.piece_at(np.array([s0]))[0])
    x, y, _, th = track.pose(np.array([s0]), np.array([n0]))
    for dx, dy in ((1.3, 0.8), (-1.3, -0.8)):
        c, s = math.cos(th[0]), math.sin(th[0])
        ws, wn = track.locate(x + dx * c - dy * s, y + dx * s + dy * c, s_hint=np.array([s0]))
        da, dn = wheel_at(pt, p, n0, dx, dy)
        assert da == pytest.approx(float(ws[0]) - s0, abs=2e-3)
        assert dn == pytest.approx(float(wn[0]) - n0, abs=2e-3)
