"""Rangefinder rays (SCR `track`/`focus`) against an independent brute-force reference."""

import math

import numpy as np
import pytest
from trackfiles import segment, torcs_installed, track_xml

from madsim.tracks import load_track

SCR_ANGLES = [-90, -75, -60, -45, -30, -20, -15, -10, -5, 0, 5, 10, 15, 20, 30, 45, 60, 75, 90]


def fine_edges(track, step=0.05):
    s = np.arange(0.0, track.length, step)
    return [np.stack(track.pose(s, n)[:2], axis=1) for n in (track.width / 2, -track.width / 2)]


def brute_ray(edges, px, py, heading, rmax=200.0):
    """First crossing of the ray with 5 cm chords of both edges (chord error < 0.1 mm here)."""
    best, dx, dy = rmax, math.cos(heading), math.sin(heading)
    for e in edges:
        a, b = e[:-1], e[1:]
        ex, ey = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
        den = dx * ey - dy * ex
        ok = np.abs(den) > 1e-12
        den = np.where(ok, den, 1.0)
        wx, wy = a[:, 0] - px, a[:, 1] - py
        t = (wx * ey - wy * ex) / den
        u = (wx * dy - wy * dx) / den
        hit = ok & (t > 1e-9) & (u >= 0) & (u <= 1)
        if hit.any():
            best = min(best, float(t[hit].min()))
    return best


@pytest.mark.parametrize("name", ["madsim-street", "madsim-road", "g-track-1"])
def test_rays_match_brute_force_within_a_centimetre(name):
    if name == "g-track-1" and not torcs_installed():
        pytest.skip("TORCS data not installed: apt-get install torcs-data")
    t = load_track(name)
    edges = fine_edges(t)
    rng = np.random.default_rng(11)
    s = rng.uniform(0, t.length, 25)
    n = rng.uniform(-0.95, 0.95, 25) * t.width / 2
    x, y, _, heading = t.pose(s, n)
    yaw = heading + rng.normal(0.0, 0.3, 25)
    got = t.rangefinders(x, y, yaw, SCR_ANGLES, s_hint=s)
    for k in range(25):
        for a, ang in enumerate(SCR_ANGLES):
            ref = brute_ray(edges, x[k], y[k], yaw[k] - math.radians(ang))
            assert got[k, a] == pytest.approx(ref, abs=0.01), (k, ang)


def test_closed_form_on_a_straight(write_track):
    # 400 m straight, width 10: at n = +2 heading along the track, the -90 deg ray (left) is 3 m,
    # +90 (right) is 7 m, 0 deg reaches the 200 m cap; a 45 deg ray to the right hits the right
    # edge after 7 / sin(45 deg).
    segs = [segment("s", "str", lg=400), segment("c", "lft", radius=60, arc=180),
            segment("s2", "str", lg=400), segment("c2", "lft", radius=60, arc=180)]
    t = load_track(write_track(track_xml(segs, width=10)))
    x, y, _, h = t.pose(50.0, 2.0)
    r = t.rangefinders(x, y, h, [-90, 0, 90, 45])[0]
    assert r == pytest.approx([3.0, 200.0, 7.0, 7 / math.sin(math.pi / 4)], abs=1e-9)


def test_ray_follows_a_bend_to_the_outer_edge(write_track):
    # Straight into a left circle of radius 100 (width 10); from the centre line 20 m before the
    # bend, looking straight ahead, the ray meets the outer (right) edge circle of radius 105.
    segs = [segment("s", "str", lg=300), segment("c", "lft", radius=100, arc=180),
            segment("s2", "str", lg=300), segment("c2", "lft", radius=100, arc=180)]
    t = load_track(write_track(track_xml(segs, width=10)))
    x, y, _, h = t.pose(280.0, 0.0)
    got = t.rangefinders(x, y, h, [0.0])[0, 0]
    # circle centre is 100 m to the left of the bend start; ray along +x from 20 m before it:
    # distance to the circle x^2 + (y - 100)^2 = 105^2 from the bend start is sqrt(105^2 - 100^2)
    assert got == pytest.approx(20 + math.sqrt(105 ** 2 - 100 ** 2), abs=1e-6)


@pytest.mark.skipif(not torcs_installed(), reason="TORCS data not installed: apt-get install torcs-data")
def test_rays_follow_the_road_over_the_wheel_2_bridge():
    # On the bridge level the crossing road below is not an edge: the ahead ray runs on.
    t = load_track("wheel-2")
    x, y, _, h = t.pose(2384.0, 0.0)
    ahead = t.rangefinders(x, y, h, [0.0], s_hint=2384.0)[0, 0]
    assert ahead > 2 * t.width


@pytest.mark.parametrize("name", ["madsim-road", "madsim-oval"])
def test_on_arc_filter_decides_as_the_arc_angle_does(name):
    """`_on_arc` (two cross products) decides a crossing point's place on an arc exactly as
    `_arc_q` (atan2) with its 1e-12 rad tolerance does, or defers (-1): points spread over
    every arc run and around it, and points 1e-11..1e-5 rad from either end."""
    from madsim.tracks.rays import RUN_ARC, RUN_CX, RUN_CY, RUN_KIND, RUN_R, _arc_frame, _arc_q, _on_arc

    t = load_track(name)
    runs = t.runs
    rng = np.random.default_rng(3)
    decided = deferred = 0
    for j in np.flatnonzero(runs[:, RUN_KIND] != 0.0):
        theta0, sense = _arc_frame(runs, j)
        d = runs[j, RUN_ARC]
        near_ends = np.concatenate([e + sign * 10.0 ** rng.uniform(-11, -5, 200)
                                    for e in (0.0, d) for sign in (-1.0, 1.0)])
        for alpha in np.concatenate([rng.uniform(-math.pi, math.pi, 400), near_ends]):
            radius = runs[j, RUN_R] + rng.uniform(-1.0, 1.0) * t.width / 2
            phi = theta0 + sense * alpha
            x = runs[j, RUN_CX] + radius * math.cos(phi)
            y = runs[j, RUN_CY] + radius * math.sin(phi)
            q = _arc_q(runs, j, x, y)
            on = _on_arc(runs, j, x - runs[j, RUN_CX], y - runs[j, RUN_CY], radius, sense, d)
            if on < 0:
                deferred += 1
                assert d >= 3.0 or min(abs(alpha), abs(alpha - d)) < 2e-9   # only at the very ends
            else:
                decided += 1
                assert on == (1 if -1e-12 <= q <= d + 1e-12 else 0), (j, alpha, q, d)
    assert decided > 0 and deferred > 0
