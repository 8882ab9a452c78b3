"""Pit walls (track spec 6: a border of style `wall` with a side beyond it) are solid obstacles
with TORCS's pit-wall response (car spec 4.12): an elastic impulse j = -(1 + e) vn / (1/m +
(r x n)^2 / I), e = 1, half of its yaw effect, damage 0.1 x 2e-5 j^2 (x 1.5 within +-60 deg of
the nose) x skill. Every other border/side/barrier kind collides only at the barrier line.

Reference numbers are closed form, computed here; the tracks are small TORCS files written here.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from trackfiles import segment, torcs_installed, track_xml

from madsim.cars import load_car
from madsim.physics.contact import SLOP_M, ContactSolver
from madsim.physics.world import World
from madsim.tracks import load_track

DT = 0.002
HL, HW, MASS, IZZ = 2.3, 0.95, 1200.0, 2000.0
SKILL = 0.8                      # semi-pro, the solver's default
WIDTH = 10.0                     # road width of the test track, m
SEG_M = 200.0                    # length of each test segment, m
# (left border width, style, left side width) per straight segment, in order
KINDS = {
    "pit wall": (1.0, "wall", 5.0),
    "plain border": (1.0, "plan", 5.0),
    "curb border": (1.0, "curb", 5.0),
    "wall border, no side": (1.0, "wall", 0.0),
    "no border": (0.0, "plan", 5.0),
}


def _seg(name: str, border_w: float, style: str, side_w: float) -> str:
    sub = (f'<section name="Left Border"><attnum name="width" val="{border_w}"/>'
           f'<attnum name="height" val="1"/><attstr name="style" val="{style}"/></section>'
           f'<section name="Left Side"><attnum name="start width" val="{side_w}"/>'
           f'<attnum name="end width" val="{side_w}"/></section>')
    text = segment(name, "str", lg=SEG_M)
    return text[: -len("</section>")] + sub + "</section>"


@pytest.fixture(scope="module")
def kinds_track(tmp_path_factory):
    """A straight of one SEG_M segment per entry of KINDS (left side only)."""
    segs = [_seg(f"k{i}", *v) for i, v in enumerate(KINDS.values())]
    d = tmp_path_factory.mktemp("pitwalls")
    p = d / "pitwalls.xml"
    p.write_text(track_xml(segs, width=WIDTH, name="pitwalls"), encoding="utf-8")
    return load_track(p)


def s_mid(kind: str) -> float:
    return (list(KINDS).index(kind) + 0.5) * SEG_M


def test_pit_wall_geometry_covers_the_border_strip_where_a_side_is_beyond(kinds_track):
    """Only the `wall` border with a side beyond it is solid; its quads span the strip from the
    road edge to the border's outer edge (1e-9 m) over its whole segment (1e-6 m)."""
    walls = kinds_track.pit_wall_pieces()
    quads, piece, side = kinds_track.pit_wall_quads()
    assert quads.shape[0] >= 1 and np.all(side == 0) and walls[:, 1].sum() == 0
    pts = quads.reshape(-1, 2)
    s, n = kinds_track.locate(pts[:, 0], pts[:, 1])
    inner = np.r_[True, False, False, True]
    n = n.reshape(-1, 4)
    np.testing.assert_allclose(n[:, inner], WIDTH / 2, atol=1e-9)
    np.testing.assert_allclose(n[:, ~inner], WIDTH / 2 + 1.0, atol=1e-9)
    assert s.min() == pytest.approx(s_mid("pit wall") - SEG_M / 2, abs=1e-6)
    assert s.max() == pytest.approx(s_mid("pit wall") + SEG_M / 2, abs=1e-6)


def test_tracks_without_pit_walls_have_none(road):
    assert not road.pit_wall_pieces().any()
    assert road.pit_wall_quads()[0].shape == (0, 4, 2)


def _state(track, s, n, yaw_rel=0.0, v_t=0.0, v_n=0.0, w=0.0):
    x, y, _, h = track.pose(np.array([s]), np.array([n]))
    t = np.array([math.cos(h[0]), math.sin(h[0])])
    nu = np.array([-math.sin(h[0]), math.cos(h[0])])
    v = v_t * t + v_n * nu
    arrays = [np.array(x, dtype=float), np.array(y, dtype=float), h + yaw_rel,
              np.array([v[0]]), np.array([v[1]]), np.array([float(w)]),
              track.piece_at(np.array([s])).astype(np.int64)]
    return arrays, t, nu


@pytest.mark.parametrize("face", ["road side", "pit side"])
def test_flat_hit_is_elastic_with_torcs_damage(kinds_track, face):
    """Car parallel to the wall, 5 cm into one face, 30 m/s along it and 2 m/s into it: the
    normal speed reverses (e = 1: -2 m/s, 1e-9), the tangential speed and yaw rate are kept (the
    contact is the middle of the side: r x n = 0), the car is pushed out by the penetration +
    SLOP_M, damage 0.1 x 2e-5 (2 m 2)^2 x skill (side hit: no frontal factor) in whole points
    (TORCS adds the int of each hit)."""
    solver = ContactSolver(kinds_track, [HL], [HW], [MASS], [IZZ])
    if face == "road side":
        n0, into = WIDTH / 2 - HW + 0.05, 2.0
    else:
        n0, into = WIDTH / 2 + 1.0 + HW - 0.05, -2.0
    st, t, nu = _state(kinds_track, s_mid("pit wall"), n0, v_t=30.0, v_n=into)
    rep = solver.resolve(*st, DT)
    v = np.array([st[3][0], st[4][0]])
    assert rep.wall[0]
    assert v @ nu == pytest.approx(-into, abs=1e-9)
    assert v @ t == pytest.approx(30.0, abs=1e-9)
    assert st[5][0] == pytest.approx(0.0, abs=1e-9)
    _, n_after = kinds_track.locate(st[0], st[1])
    assert n_after[0] == pytest.approx(n0 - math.copysign(0.05 + SLOP_M, into), abs=1e-9)
    j = 2.0 * MASS * 2.0
    assert rep.damage[0] == math.floor(0.1 * 2e-5 * j * j * SKILL)


def test_corner_hit_with_spin_follows_the_torcs_pit_wall_rule(kinds_track):
    """Nose yawed 20 deg into the wall's road face, front-left corner 3 cm in, spinning: the
    closed-form impulse at that corner (r x n lever), half its yaw effect, frontal damage
    factor 1.5 (the corner is 22 deg off the nose), in whole points; 1e-7."""
    yaw_rel = math.radians(20.0)
    reach = HL * math.sin(yaw_rel) + HW * math.cos(yaw_rel)
    st, t, nu = _state(kinds_track, s_mid("pit wall"), WIDTH / 2 - reach + 0.03, yaw_rel=yaw_rel,
                       v_t=0.0, w=0.7)
    yaw = st[2][0]
    speed = 20.0
    st[3][:], st[4][:] = speed * math.cos(yaw), speed * math.sin(yaw)
    x, y, vx, vy, w = st[0][0], st[1][0], st[3][0], st[4][0], st[5][0]
    c, s = math.cos(yaw), math.sin(yaw)
    corner = np.array([x + HL * c - HW * s, y + HL * s + HW * c])   # front-left
    r = corner - np.array([x, y])
    n = -nu                                                          # away from the wall
    vn = (np.array([vx, vy]) + w * np.array([-r[1], r[0]])) @ n
    cr = r[0] * n[1] - r[1] * n[0]
    j = -2.0 * vn / (1.0 / MASS + cr * cr / IZZ)
    v_exp = np.array([vx, vy]) + j * n / MASS
    w_exp = float(np.clip(w + 0.5 * j * cr / IZZ, -3.0, 3.0))
    dmg_exp = 0.1 * 2e-5 * j * j * 1.5 * SKILL
    assert vn < 0.0
    solver = ContactSolver(kinds_track, [HL], [HW], [MASS], [IZZ])
    rep = solver.resolve(*st, DT)
    assert rep.wall[0]
    np.testing.assert_allclose([st[3][0], st[4][0], st[5][0]], [*v_exp, w_exp], rtol=0, atol=1e-7)
    assert dmg_exp > 1.0 and rep.damage[0] == math.floor(dmg_exp)


def test_broad_phase_flags_a_car_at_a_pit_wall_far_from_the_barriers(kinds_track):
    """A car on the road touching the pit wall is 6 m from the barrier line: the broad phase
    must still send it to pymunk; 2 m from the wall (and the barrier) it must not."""
    solver = ContactSolver(kinds_track, [HL], [HW], [MASS], [IZZ])
    kernel, args = solver.broad_phase_kernel, solver.broad_phase_args
    st, _, _ = _state(kinds_track, s_mid("pit wall"), WIDTH / 2 - HW + 0.01)
    assert kernel(st[0], st[1], st[2], st[6], *args) == 1
    solver.reset()
    st, _, _ = _state(kinds_track, s_mid("pit wall"), WIDTH / 2 - HW - 2.0)
    assert kernel(st[0], st[1], st[2], st[6], *args) == 0
    assert solver.broad_phase_args[9][0] > 1.5        # its clearance, m (slack)


@pytest.mark.parametrize("kind", list(KINDS))
def test_a_placed_car_driving_at_the_left_side_collides_where_torcs_does(kinds_track, kind):
    """World.place a sedan 1 m from the road's left edge, nose at the wall, 10 m/s, coasting
    in neutral. Pit wall: it bounces off the wall's road face elastically: the body's forward
    speed is -10 m/s just after the hit (within 5 %: the still forward-rolling tyres brake it
    in the rest of that tick), the nose never passes the face (1 cm), and it took one hit's
    damage 0.1 x 2e-5 (2 m v)^2 x 1.5 (frontal) x skill (1 %: the speed at impact). Every other
    kind: the car crosses the road edge and is stopped at the barrier line, within 0.5 m of it
    and not beyond it (1 cm), and TORCS's barrier rule sends it back: its two front corners
    are answered one after the other from the corner velocities of before the response (1.3's
    SimCarCollideXYScene), so the into-wall speed v becomes -v (1 - 2 (k_friction + rebound)):
    16 m/s back from 10 with this track's barrier material (no surface file: friction 0.8,
    rebound 0.5, the loader's defaults; TORCS's own barrier has friction 0 and stops the car),
    within 5 % (the tyres, rolling forward, brake it in the rest of that tick)."""
    car = load_car("madsim-sedan")
    world = World(kinds_track, [car], np.random.default_rng(0), contact=True)
    world.reset()
    half_len = car.body_length / 2.0            # the contact box (spec 4.12: body length)
    world.place(0, s_mid(kind), WIDTH / 2 - 1.0 - half_len, yaw_rel=math.pi / 2, speed=10.0,
                gear=0)
    controls = np.zeros((1, 5))
    ns, vs = [], []
    for _ in range(15 if kind == "pit wall" else 60):
        world.step(controls)
        ns.append(float(world.n[0]))
        vs.append(float(world.vx[0]))
    ns, vs = np.array(ns), np.array(vs)
    border_w, style, side_w = KINDS[kind]
    barrier = WIDTH / 2 + border_w + side_w
    if kind == "pit wall":
        hit = int(np.argmax(vs < 0.0))
        assert 0 < hit and np.all(vs[:hit] > 9.9)
        assert vs[hit] == pytest.approx(-10.0, rel=0.05)
        assert ns.max() + half_len < WIDTH / 2 + 0.01
        j = 2.0 * car.mass_total * 10.0
        assert world.damage[0] == pytest.approx(0.1 * 2e-5 * j * j * 1.5 * SKILL, rel=0.01)
    else:
        assert ns.max() + half_len > WIDTH / 2 + 0.5     # nothing solid at the road edge
        assert barrier - 0.5 < ns.max() + half_len < barrier + 0.01
        srf = kinds_track.surfaces[int(kinds_track.surface_at(np.array([s_mid(kind)]),
                                                              np.array([barrier + 1.0]))[0])]
        hit = int(np.argmax(vs < 0.0))
        assert 0 < hit and np.all(vs[:hit] > 0.0)
        factor = 2.0 * (srf.friction + srf.rebound) - 1.0
        assert vs[hit] == pytest.approx(-vs[hit - 1] * factor, rel=0.05)


@pytest.mark.skipif(not torcs_installed(), reason="TORCS data not installed")
@pytest.mark.parametrize("name, left, right", [("e-track-2", 52, 0), ("e-track-3", 0, 56),
                                               ("wheel-1", 0, 52), ("michigan", 25, 0)])
def test_torcs_tracks_pit_walls_per_side(name, left, right):
    """Pieces with a pit wall per side on Debian torcs-data tracks (count checked by hand
    against the XML: each pit lane's `wall` border with a side beyond)."""
    walls = load_track(name).pit_wall_pieces()
    assert (int(walls[:, 0].sum()), int(walls[:, 1].sum())) == (left, right)


def test_world_batch_hits_the_pit_wall_exactly_as_the_world(kinds_track):
    """A car steering left into the pit wall at 15 m/s: WorldBatch's slot (its lone-car fast
    path and whole ticks) equals a World bit for bit every tick, and the car does hit the wall
    (wall contact, damage) and its centre never passes the road face."""
    from madsim.physics.world_batch import WorldBatch

    car = load_car("madsim-sedan")
    where = np.array([[s_mid("pit wall") - 60.0, 1.0, 15.0]])
    world = World(kinds_track, [car], np.random.default_rng(0))
    world.reset(where)
    batch = WorldBatch(1, 1)
    batch.start(0, ("pitwalls", (car.name,)), kinds_track, [car], where)
    u = np.array([[0.6, 0.3, 0.0, 1.0, 0.0]])
    mask = np.ones(1, dtype=bool)
    hit = False
    for _ in range(150):
        batch.controls[batch.rows(0)] = u
        world.step(u)
        batch.step(mask)
        assert np.array_equal(batch.state[batch.rows(0)], world.state)
        hit |= bool(world.contact_wall[0])
        assert world.n[0] < WIDTH / 2
    assert hit and world.damage[0] > 0.0


@pytest.mark.skipif(not torcs_installed(), reason="TORCS data not installed")
def test_sliding_along_a_pit_wall_never_catches_on_its_seams():
    """e-track-2's pit wall is 52 pieces (float32 starts: joints up to 0.2 mm apart). A box
    pressed 1 cm into its road face, 30 m/s along it and 0.5 m/s into it, put every 6 cm along
    the whole wall: every call is a wall contact that slows the box's speed into the wall
    (fully reversed on a flat face; less where one corner touches first, the impulse then also
    turning the box) and keeps the 30 m/s along it to 0.5 m/s (where the wall curves, its normal
    at the contact point is not the one at the box's centre): no contact at a seam between the
    wall's pieces pushes it along the track (that error was 39 m/s). Near the two end caps (within a box length) the test stays out."""
    track = load_track("e-track-2")
    walls = track.pit_wall_pieces()[:, 0]
    ends = np.flatnonzero(walls != np.roll(walls, 1))            # first piece after a change
    s_ends = track.geo[ends, 1]                                   # their start, m
    solver = ContactSolver(track, [HL], [HW], [MASS], [IZZ])
    checked = 0
    for s in np.arange(0.0, track.length, 0.06):
        to_end = np.abs((s - s_ends + track.length / 2) % track.length - track.length / 2)
        if not walls[track.piece_at(s)] or to_end.min() < 2 * HL:
            continue
        st, t, nu = _state(track, s, track.width / 2 - HW + 0.01, v_t=30.0, v_n=0.5)
        rep = solver.resolve(*st, DT)
        v = np.array([st[3][0], st[4][0]])
        assert rep.wall[0], s
        assert v @ t == pytest.approx(30.0, abs=0.5), s
        assert v @ nu < 0.5, s
        checked += 1
    assert checked > 3000


def test_track_maps_draw_the_pit_walls(kinds_track):
    """draw_track adds the pit-wall quads, corner for corner, as one polygon collection."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    from madsim.render.trackmap import draw_track

    fig, ax = plt.subplots()
    draw_track(ax, kinds_track, marks_every_m=0)
    drawn = [c for c in ax.collections if isinstance(c, PolyCollection)]
    plt.close(fig)
    quads = kinds_track.pit_wall_quads()[0]
    assert len(drawn) == 1
    paths = drawn[0].get_paths()
    assert len(paths) == quads.shape[0]
    np.testing.assert_allclose(paths[0].vertices[:4], quads[0], atol=1e-9)


@pytest.mark.parametrize("side", ["left", "right"])
def test_barrier_normal_is_tilted_where_the_side_narrows(tmp_path, side):
    """TORCS's barrier normal is normal to the side's outer edge over the segment (track4.cpp),
    so where a side narrows from 10 m to 2 m over 20 m the normal leans back against the
    direction of travel: (slope, -/+1) / sqrt(1 + slope^2) in the track's (along, left) frame,
    slope = -0.4 (aalborg's run-off at 196-216 m narrows from 15 to 2 m over 20 m: TORCS's car
    hits it at 83 km/h and leaves at 48). The excess is measured across the track (TORCS's
    toLeft / toRight). Straight track along +x: along = +x, left = +y."""
    from madsim.physics.contact import _barrier_table
    from madsim.physics.contact_kernels import _point_excess

    def seg(name, w0, w1, length):
        sub = (f'<section name="{side.title()} Side"><attnum name="start width" val="{w0}"/>'
               f'<attnum name="end width" val="{w1}"/></section>')
        return segment(name, "str", lg=length)[: -len("</section>")] + sub + "</section>"

    p = tmp_path / "narrow.xml"
    p.write_text(track_xml([seg("wide", 10, 10, 100), seg("narrow", 10, 2, 20), seg("tight", 2, 2, 100)],
                           width=WIDTH, name="narrow"), encoding="utf-8")
    track = load_track(p)
    geo, bar = np.ascontiguousarray(track.geo, dtype=np.float64), _barrier_table(track)
    slope, sign = -0.4, (1.0 if side == "left" else -1.0)
    b = WIDTH / 2 + 10.0 + slope * 10.0                    # barrier offset 10 m into the narrowing
    x, y, _, a = (float(v) for v in track.pose(110.0, sign * (b + 0.05)))
    hint = int(track.piece_at(110.0))
    excess, nx, ny = _point_excess(geo, bar, hint, x, y)
    k = 1.0 / math.hypot(1.0, slope)
    along, left = slope * k, -sign * k                     # the inward normal in the track frame
    assert excess == pytest.approx(0.05, abs=1e-6)
    assert nx == pytest.approx(along * math.cos(a) - left * math.sin(a), abs=1e-9)
    assert ny == pytest.approx(along * math.sin(a) + left * math.cos(a), abs=1e-9)
    # where the side keeps its width the normal is the lateral direction, as before
    x, y, _, a = (float(v) for v in track.pose(50.0, sign * (WIDTH / 2 + 10.0 + 0.05)))
    excess, nx, ny = _point_excess(geo, bar, 0, x, y)
    assert excess == pytest.approx(0.05, abs=1e-6)
    assert (nx, ny) == pytest.approx((sign * math.sin(a), -sign * math.cos(a)), abs=1e-12)
