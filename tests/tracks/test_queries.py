"""Vectorised track queries: locate/pose are inverse, and agree with independent geometry."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from trackfiles import segment, torcs_installed, track_xml

from madsim.tracks import load_track

STOCK = ["g-track-1", "alpine-1", "forza", "b-speedway", "dirt-3", "e-track-5"]


@pytest.fixture(scope="module")
def stadium(tmp_path_factory):
    d = tmp_path_factory.mktemp("stadium") / "stadium"
    d.mkdir()
    segs = [segment("s1", "str", lg=200), segment("c1", "lft", radius=40, arc=180, profil_steps_length=5),
            segment("s2", "str", lg=200), segment("c2", "lft", radius=40, arc=180, profil_steps_length=5)]
    p = d / "stadium.xml"
    p.write_text(track_xml(segs, width=10))
    return load_track(p)


def test_locate_inverts_pose_on_a_stadium(stadium):
    rng = np.random.default_rng(1)
    s = rng.uniform(0, stadium.length, 5000)
    n = rng.uniform(-12, 12, 5000)
    x, y, _, _ = stadium.pose(s, n)
    s2, n2 = stadium.locate(x, y)
    ds = (s2 - s + stadium.length / 2) % stadium.length - stadium.length / 2
    assert np.abs(ds).max() < 1e-9
    assert np.abs(n2 - n).max() < 1e-9


def test_locate_matches_independent_stadium_geometry(stadium):
    # Closed form for a stadium: straight along +x from (0, 5) for 200 m, then a left half circle
    # of radius 40 centred at (200, 45). A point at (100, 8) is on the first straight 3 m left
    # of the centre; a point at (200 + 30, 45) is in the first turn, 10 m to its left (inside).
    x0, y0 = stadium.x[0], stadium.y[0]
    s, n = stadium.locate(np.array([x0 + 100, x0 + 230]), np.array([y0 + 3, y0 + 40]))
    assert s[0] == pytest.approx(100.0, abs=1e-9)
    assert n[0] == pytest.approx(3.0, abs=1e-9)
    # piece lengths are float32 as in TORCS: s agrees to float32 rounding of the 4 m pieces
    assert s[1] == pytest.approx(200 + 40 * math.pi / 2, abs=1e-4)
    assert n[1] == pytest.approx(10.0, abs=1e-9)


def test_queries_broadcast_and_keep_shapes(stadium):
    s = np.linspace(0, 100, 12).reshape(3, 4)
    x, y, z, h = stadium.pose(s, 1.0)
    assert x.shape == y.shape == z.shape == h.shape == (3, 4)
    s2, n2 = stadium.locate(x, y)
    assert s2.shape == (3, 4) and np.allclose(n2, 1.0)
    assert stadium.heading_at(s).shape == (3, 4)
    assert stadium.surface_at(s, 0.0).shape == (3, 4)


def test_heading_and_curvature_follow_the_geometry(stadium):
    # first straight heads +x; halfway round the first left turn heads +y... then -x
    assert stadium.heading_at(100.0) == pytest.approx(0.0)
    assert stadium.heading_at(200 + 40 * math.pi / 2) == pytest.approx(math.pi / 2, abs=1e-6)
    assert abs(stadium.heading_at(300 + 40 * math.pi)) == pytest.approx(math.pi, abs=1e-6)
    assert stadium.curvature_at([100.0, 250.0]) == pytest.approx([0.0, 1 / 40])


@pytest.mark.skipif(not torcs_installed(), reason="TORCS data not installed: apt-get install torcs-data")
@pytest.mark.parametrize("name", STOCK)
def test_locate_inverts_pose_on_stock_tracks(name):
    t = load_track(name)
    rng = np.random.default_rng(7)
    s = rng.uniform(0, t.length, 4000)
    left, right = t.barrier_offsets_at(s)
    n = rng.uniform(-1, 1, 4000) * np.where(rng.uniform(size=4000) < 0.5, right, left) * 0.98
    x, y, _, _ = t.pose(s, n)
    s2, n2 = t.locate(x, y)
    ds = (s2 - s + t.length / 2) % t.length - t.length / 2
    # exact inverse except where two parts of the track overlap in plan; stock tracks do not
    # overlap within the sides, except a few metres of the outside of some bends where the
    # walk from the nearest sample stops at a joint (TORCS's own behaviour, spec 10.1)
    assert np.mean(np.abs(ds) < 1e-6) > 0.995
    assert np.mean(np.abs(n2 - n) < 1e-6) > 0.995


@given(s=st.floats(0, 1), n=st.floats(-0.98, 0.98))
@settings(max_examples=200, deadline=None)
def test_locate_pose_round_trip_property(stadium, s, n):
    s_m = s * stadium.length * 0.999999
    x, y, _, _ = stadium.pose(s_m, n * 5.0)
    s2, n2 = stadium.locate(x, y)
    assert float(n2) == pytest.approx(n * 5.0, abs=1e-8)
    ds = (float(s2) - s_m + stadium.length / 2) % stadium.length - stadium.length / 2
    assert abs(ds) < 1e-8


def test_locate_agrees_with_brute_force_projection_on_the_sampled_line(need_torcs):
    # Independent check: project onto the sampled centre polyline by brute force.
    t = load_track("g-track-1")
    rng = np.random.default_rng(3)
    s = rng.uniform(0, t.length, 300)
    n = rng.uniform(-7, 7, 300)
    x, y, _, _ = t.pose(s, n)
    s2, n2 = t.locate(x, y)
    ax, ay = t.x, t.y
    bx, by = np.roll(ax, -1), np.roll(ay, -1)
    seg_len = np.hypot(bx - ax, by - ay)
    for k in range(len(x)):
        u = np.clip(((x[k] - ax) * (bx - ax) + (y[k] - ay) * (by - ay)) / seg_len ** 2, 0, 1)
        px, py = ax + u * (bx - ax), ay + u * (by - ay)
        j = int(np.argmin(np.hypot(x[k] - px, y[k] - py)))
        s_ref = (t.s[j] + u[j] * seg_len[j]) % t.length
        n_ref = math.copysign(math.hypot(x[k] - px[j], y[k] - py[j]),
                              (bx[j] - ax[j]) * (y[k] - ay[j]) - (by[j] - ay[j]) * (x[k] - ax[j]))
        # chords of <= 1 m on radii >= 20 m: sagitta < 1 cm; arc length vs chord similar
        assert abs((s2[k] - s_ref + t.length / 2) % t.length - t.length / 2) < 0.05
        assert n2[k] == pytest.approx(n_ref, abs=0.02)


def test_edges_near_returns_polylines_in_the_window(stadium):
    near = stadium.edges_near(100.0, ahead=20.0, behind=5.0)
    s, n = stadium.locate(near["edge_left"][:, 0], near["edge_left"][:, 1])
    assert s.min() >= 95.0 - 1e-9 and s.max() <= 120.0 + 1e-9
    assert np.allclose(n, 5.0)
    _, nb = stadium.locate(near["barrier_right"][:, 0], near["barrier_right"][:, 1])
    assert np.allclose(nb, -5.0)  # no side, no border: the barrier is the road edge


@pytest.mark.skipif(not torcs_installed(), reason="TORCS data not installed: apt-get install torcs-data")
def test_hinted_locate_resolves_the_wheel_2_bridge():
    # wheel-2 is a figure of eight: near s = 2385 m and s = 4946 m the road passes over itself.
    t = load_track("wheel-2")
    for s_true in (2384.0, 4946.0):
        n = np.linspace(-4, 4, 9)
        x, y, _, _ = t.pose(np.full(9, s_true), n)
        s_hint, n_hint = t.locate(x, y, s_hint=s_true - 3.0)
        assert np.allclose(s_hint, s_true, atol=1e-6) and np.allclose(n_hint, n, atol=1e-6)
    # without a hint the plan view is ambiguous there: some points land on the other level
    x, y, _, _ = t.pose(np.full(50, 2384.0), np.linspace(-4, 4, 50))
    s_plain, _ = t.locate(x, y)
    assert np.any(np.abs(s_plain - 2384.0) > 100)


def test_one_piece_table_and_walk_for_track_and_car_kernels():
    """The physics piece table starts with the track's geometry table, so the car kernel's walk
    (tracks.kernels.locate on the piece table) and the track's (on Track.geo) agree bit for bit."""
    from madsim.physics import layout as L
    from madsim.physics.tables import piece_table
    from madsim.tracks import kernels as K

    track = load_track("g-track-1")
    pt = piece_table(track)[0]
    assert L.PIECE_COLUMNS[:K.N_GEO] == K.GEO_COLUMNS
    assert np.array_equal(pt[:, :K.N_GEO], track.geo)
    a0 = track.geo[:, K.GEO_A0]
    assert np.array_equal(track.geo[:, K.GEO_CA0], np.cos(a0))
    rng = np.random.default_rng(3)
    s = rng.uniform(0, track.length, 200)
    x, y, _, _ = track.pose(s, rng.uniform(-15, 15, 200))
    for k in range(200):
        start = int(rng.integers(track.geo.shape[0]))
        on_track = K.locate_from(track.geo, start, x[k], y[k])
        on_physics = K.locate_from(pt, start, x[k], y[k])
        assert on_track == on_physics
        p, q, n, ch, sh = getattr(K.locate, "py_func", K.locate)(pt, start, x[k], y[k])
        assert (p, q, n) == on_track and abs(ch * ch + sh * sh - 1.0) < 1e-12
