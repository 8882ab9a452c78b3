"""Contact solver: broad phase, TORCS wall and car-car response, no tunnelling at 300 km/h.

Reference numbers are closed form (spec torcs-car-format.md 4.12) computed here independently of
the solver; the solver is driven by a plain kinematic integrator (x += v dt, yaw += r dt).
Box overlap and barrier checks use this file's own separating-axis test and `Track.locate`.
"""

from __future__ import annotations

import hashlib
import math
import subprocess
import sys
from pathlib import Path

import numba
import numpy as np
import pymunk
import pytest
from trackfiles import torcs_installed

from madsim.physics.contact import ContactSolver
from madsim.tracks import load_track

DT = 0.002
HL, HW, MASS, IZZ = 2.3, 0.95, 1200.0, 2000.0
SKILL = 0.8          # TORCS semi-pro damage factor, the solver's default
V300 = 300 / 3.6     # m/s


@pytest.fixture(scope="module")
def oval():
    return load_track("madsim-oval")


@pytest.fixture(scope="module")
def street():
    return load_track("madsim-street")


@pytest.fixture(scope="module")
def speedway():
    return load_track("madsim-speedway")


# --- helpers ----------------------------------------------------------------------------------


def straight_middle(track, min_len=40.0) -> float:
    """s in the middle of the longest run of straight pieces (at least min_len long)."""
    geo = track.geo
    best, run_start, best_len = None, None, 0.0
    for i in range(geo.shape[0] + 1):
        straight = i < geo.shape[0] and geo[i, 0] == 0.0
        if straight and run_start is None:
            run_start = i
        if not straight and run_start is not None:
            length = geo[run_start:i, 2].sum()
            if length > best_len:
                best, best_len = geo[run_start, 1] + length / 2, length
            run_start = None
    assert best_len >= min_len, f"{track.name}: no straight of {min_len} m"
    return float(best)


def solver_for(track, n, **kw) -> ContactSolver:
    return ContactSolver(track, np.full(n, HL), np.full(n, HW), np.full(n, MASS), np.full(n, IZZ), **kw)


def state(track, s, n_off, yaw_rel=0.0, speed=0.0, vel_rel=None, w=0.0):
    """Arrays (x, y, yaw, vx, vy, w, piece) for cars at track (s, n), yawed by yaw_rel from the
    centre-line heading, moving at `speed` along heading + vel_rel (default: the car's yaw)."""
    s = np.atleast_1d(np.asarray(s, dtype=np.float64))
    x, y, _, h = track.pose(s, np.broadcast_to(n_off, s.shape))
    yaw = h + yaw_rel
    direction = yaw if vel_rel is None else h + vel_rel
    vx = np.broadcast_to(speed * np.cos(direction), s.shape).astype(np.float64)
    vy = np.broadcast_to(speed * np.sin(direction), s.shape).astype(np.float64)
    w = np.broadcast_to(np.asarray(w, dtype=np.float64), s.shape).copy()
    return [np.ascontiguousarray(a, dtype=np.float64) for a in (x, y, yaw, vx, vy)] + [
        w, track.piece_at(s).astype(np.int64)]


def corners(x, y, yaw):
    """(N, 4, 2) box corners: front-left, rear-left, rear-right, front-right."""
    c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
    lx = np.array([1, -1, -1, 1.0]) * HL
    ly = np.array([1, 1, -1, -1.0]) * HW
    return np.stack([x[:, None] + lx * c - ly * s, y[:, None] + lx * s + ly * c], axis=-1)


def corner_excess(track, x, y, yaw) -> float:
    """Largest distance of any corner beyond its barrier line (m, <= 0: all inside)."""
    c = corners(x, y, yaw).reshape(-1, 2)
    s, n = track.locate(c[:, 0], c[:, 1])
    left, right = track.barrier_offsets_at(s)
    return float(np.max(np.maximum(n - left, -n - right)))


def sat_gap(x, y, yaw, i, j, hl=HL, hw=HW) -> np.ndarray:
    """Largest separating-axis gap between boxes i and j (vectorised over index arrays; < 0 overlap)."""
    ci, si, cj, sj = np.cos(yaw[i]), np.sin(yaw[i]), np.cos(yaw[j]), np.sin(yaw[j])
    dx, dy = x[j] - x[i], y[j] - y[i]
    gap = np.full(np.shape(i), -np.inf)
    for ax, ay in ((ci, si), (-si, ci), (cj, sj), (-sj, cj)):
        ri = hl * np.abs(ci * ax + si * ay) + hw * np.abs(-si * ax + ci * ay)
        rj = hl * np.abs(cj * ax + sj * ay) + hw * np.abs(-sj * ax + cj * ay)
        gap = np.maximum(gap, np.abs(dx * ax + dy * ay) - ri - rj)
    return gap


def kinetic(vx, vy, w, m=MASS, izz=IZZ) -> float:
    return float(0.5 * np.sum(m * (vx ** 2 + vy ** 2) + izz * w ** 2))


def drive(solver, st, steps, check=None):
    """Kinematic integration with a resolve() after every sub-step; `check(st, report)` each step."""
    x, y, yaw, vx, vy, w, piece = st
    reports = []
    for _ in range(steps):
        x += vx * DT
        y += vy * DT
        yaw += w * DT
        rep = solver.resolve(x, y, yaw, vx, vy, w, piece, DT)
        reports.append(rep)
        if check is not None:
            check(st, rep)
    return reports


# --- broad phase ------------------------------------------------------------------------------


@pytest.mark.parametrize("n_cars", [1, 2, 10])
def test_cars_apart_on_the_road_never_reach_pymunk(oval, monkeypatch, n_cars):
    steps = []
    original = pymunk.Space.step
    monkeypatch.setattr(pymunk.Space, "step", lambda self, dt: (steps.append(dt), original(self, dt)))
    s = 20.0 + 30.0 * np.arange(n_cars)
    st = state(oval, s, np.where(np.arange(n_cars) % 2, 3.0, -3.0), speed=40.0)
    solver = solver_for(oval, n_cars)
    free = [a.copy() for a in st]
    for _ in range(200):           # the same integration without contact
        free[0] += free[3] * DT
        free[1] += free[4] * DT
        free[2] += free[5] * DT
    reports = drive(solver, st, 200)
    assert steps == [] and solver.stats["consults"] == 0 and solver.stats["calls"] == 200
    assert not any(r.wall.any() or r.car.any() or r.pairs or r.damage.any() for r in reports)
    for a, b in zip(st, free):     # nothing touched: bit-identical to the free motion
        assert np.array_equal(a, b)


def test_touching_cars_and_a_car_in_the_barrier_are_reported(oval):
    s0 = straight_middle(oval)
    left, _ = oval.barrier_offsets_at(s0)
    # car 0 touches the left barrier, cars 1 and 2 overlap nose to tail by 5 cm, car 3 is alone
    s = np.array([s0 - 20.0, s0, s0 + 2 * HL - 0.05, s0 + 20.0])
    n = np.array([left - HW + 0.01, 0.0, 0.0, 0.0])
    st = state(oval, s, n)
    solver = solver_for(oval, 4)
    rep = solver.resolve(*st, DT)
    assert rep.wall.tolist() == [True, False, False, False]
    assert rep.car.tolist() == [False, True, True, False]
    assert rep.pairs == [(1, 2)]


def test_teleported_car_is_checked_again(oval):
    """The clearance cache must not hide a car moved into a wall between calls."""
    s0 = straight_middle(oval)
    left, _ = oval.barrier_offsets_at(s0)
    st = state(oval, s0, 0.0, speed=10.0)
    solver = solver_for(oval, 1)
    drive(solver, st, 50)
    assert solver.stats["consults"] == 0
    x, y, _, _ = oval.pose(s0, left - HW + 0.2)
    st[0][:], st[1][:] = x, y
    rep = solver.resolve(*st, DT)
    assert rep.wall[0] and corner_excess(oval, st[0], st[1], st[2]) <= 0.0


def test_broad_phase_kernel_is_callable_from_compiled_code(oval):
    solver = solver_for(oval, 2)
    kernel = solver.broad_phase_kernel

    @numba.njit
    def near_count(x, y, yaw, piece, args):
        return kernel(x, y, yaw, piece, *args)

    s0 = straight_middle(oval)
    apart = state(oval, [s0, s0 + 15.0], 0.0)
    touching = state(oval, [s0, s0 + 2 * HL - 0.01], 0.0)
    assert near_count(apart[0], apart[1], apart[2], apart[6], solver.broad_phase_args) == 0
    assert near_count(touching[0], touching[1], touching[2], touching[6], solver.broad_phase_args) == 2


# --- wall response ----------------------------------------------------------------------------


@pytest.mark.parametrize("friction, rebound", [(0.0, 0.5), (None, None)])
def test_flat_wall_hit_scales_the_normal_speed_and_keeps_the_tangential(oval, friction, rebound):
    """Car parallel to the left barrier, 5 cm into it, 30 m/s along and 2 m/s into the wall
    (spec 4.12, TORCS 1.3 SimCarCollideXYScene): two corners beyond the barrier line (front
    left, then rear left), each answered on its own from the corner velocities of before the
    response (-2 m/s into the wall both times), so the into-wall speed loses 2 x (k_friction +
    rebound) x 2 m/s (TORCS's barrier "friction" is an extra normal damping); tangential speed
    unchanged (1e-9 m/s); yaw rate changed only by the two friction terms -(n . r) vn
    k_friction / 10, r from the start-of-step corner to the centre as pushed in by the corners
    so far; two damages, each in whole points, the second from the velocity the first left.
    TORCS tests the box where it was at the start of the step (the pose moved back by v x DT:
    each corner e = 5 cm - 2 m/s x DT beyond the line) and pushes the centre by each corner's
    depth: 2 e in all, so the levers are n . r = -(hw + 2 e - 0.05), then -(hw + 3 e - 0.05)
    (docs/physics.md, "Where TORCS looks"). Once with TORCS's
    barrier values (friction 0, rebound 0.5: the second rebound stops the normal motion), once
    with the oval's own fence material."""
    s0 = straight_middle(oval)
    left, _ = oval.barrier_offsets_at(s0)
    srf = oval.surfaces[int(oval.surface_at(s0, left + 1.0))]
    kf = srf.friction if friction is None else friction
    kr = srf.rebound if rebound is None else rebound
    st = state(oval, s0, left - HW + 0.05)
    h = st[2][0]
    t, nu = np.array([math.cos(h), math.sin(h)]), np.array([-math.sin(h), math.cos(h)])
    v = 30.0 * t + 2.0 * nu
    st[3][:], st[4][:] = v[0], v[1]
    solver = solver_for(oval, 1, wall_friction=friction, rebound=rebound)
    rep = solver.resolve(*st, DT)
    v_after = np.array([st[3][0], st[4][0]])
    assert rep.wall[0] and not rep.car[0]
    u1 = 2.0 * (1.0 - kf - kr)                  # into-wall speed after the first corner
    assert v_after @ nu == pytest.approx(2.0 * (1.0 - 2.0 * kf - 2.0 * kr), abs=1e-9)
    assert v_after @ t == pytest.approx(30.0, abs=1e-9)
    # yaw: n = -nu, vn = -2 at both corners -> dw = -(n . r) vn kf / 10 with the levers above
    e = 0.05 - 2.0 * DT
    levers = (HW + 2.0 * e - 0.05) + (HW + 3.0 * e - 0.05)
    assert st[5][0] == pytest.approx(-levers * 2.0 * kf / 10.0, abs=1e-9)
    _, n_after = oval.locate(st[0], st[1])
    assert n_after[0] == pytest.approx(left - HW + 0.05 - 2.0 * e, abs=1e-9)
    # damage per corner: V = max(1, |v|), c = v.n / V with n = -nu, v as the corners before left
    # it; whole points each (TORCS adds int(each hit))
    expected = 0
    for un in (2.0, u1):
        speed = math.hypot(30.0, un)
        c = -un / speed
        expected += math.floor(srf.dammage * (0.5 * (c * -un) ** 2 + 0.005 * abs(1 - c) * speed) * SKILL)
    assert rep.damage[0] == expected


def test_corner_hit_with_spin_follows_the_torcs_rule(oval):
    """Car yawed 20 deg towards the left barrier, front-left corner 8 cm beyond it, spinning:
    expected values from spec 4.12 with the corner as contact point and the barrier's own
    material (friction, rebound, dammage); only that corner is beyond the line, tested (as
    TORCS) where it was at the start of the step and the centre pushed in by its depth there."""
    s0 = straight_middle(oval)
    left, _ = oval.barrier_offsets_at(s0)
    yaw_rel = math.radians(20.0)
    reach = HL * math.sin(yaw_rel) + HW * math.cos(yaw_rel)      # lateral reach of that corner
    st = state(oval, s0, left - reach + 0.08, yaw_rel=yaw_rel, speed=50.0, w=0.7)
    srf = oval.surfaces[int(oval.surface_at(s0, left + 1.0))]
    kf, kr, kd = srf.friction, srf.rebound, srf.dammage
    x, y, yaw, vx, vy, w = (a[0] for a in st[:6])
    # TORCS tests the box at the start of the step: the pose moved back by v x DT
    x0, y0, yaw0 = np.array([x - vx * DT]), np.array([y - vy * DT]), np.array([yaw - w * DT])
    corner = corners(x0, y0, yaw0)[0, 0]                          # front-left, start of step
    _, n_corner = oval.locate(corner[:1], corner[1:])
    e = float(n_corner[0] - left)                                 # its depth beyond the line
    assert 0.0 < e < 0.08 and corner_excess(oval, x0, y0, yaw0) == pytest.approx(e, abs=1e-9)
    h = yaw - yaw_rel
    n = np.array([math.sin(h), -math.cos(h)])                      # away from the left barrier
    r = corner - np.array([x0[0], y0[0]])
    v = np.array([vx, vy])
    vn = (v + w * np.array([-r[1], r[0]])) @ n
    speed = max(1.0, float(np.hypot(*v)))
    c = (v @ n) / speed
    v_exp = v - n * vn * kf - n * vn * kr
    # the friction term's lever from that corner to the centre as moved and pushed in by e
    w_exp = float(np.clip(w - (n @ (corner - np.array([x, y])) - e) * vn * kf / 10.0, -6.0, 6.0))
    dmg_exp = kd * (0.5 * (c * (v @ n)) ** 2 + 0.005 * abs(1 - c) * speed) * SKILL
    assert vn < 0.0
    solver = solver_for(oval, 1)
    rep = solver.resolve(*st, DT)
    assert rep.wall[0]
    assert st[3][0] == pytest.approx(v_exp[0], abs=1e-7)
    assert st[4][0] == pytest.approx(v_exp[1], abs=1e-7)
    assert st[5][0] == pytest.approx(w_exp, abs=1e-7)
    assert dmg_exp > 1.0 and rep.damage[0] == math.floor(dmg_exp)
    # the box rides in the wall by about the step's motion, as TORCS's (pushed by e only)
    assert corner_excess(oval, st[0], st[1], st[2]) <= 50.0 * DT + 1e-9


def test_sliding_along_a_curved_barrier_never_catches_on_its_joints(oval):
    """A box pressed 1 cm into the outer (right) barrier of the oval's first bend (R 150 m, a
    polyline with a joint every ~1 m), parallel to the track, 30 m/s along it and 0.5 m/s into
    it, put every 5 cm over 35 m: every call is a wall contact, the speed into the wall does not
    grow and the 30 m/s along the track is kept to 0.05 m/s (TORCS's barrier normal is the
    track's lateral direction: spec 4.12 pushes along it only). Before the barrier normal was
    taken from the track, pymunk's normal at a joint ran along the track and braked the box by
    up to 10.5 m/s in one step here."""
    checked = 0
    solver = solver_for(oval, 1)
    for s in np.arange(165.0, 200.0, 0.05):
        _, right = oval.barrier_offsets_at(np.array([s]))
        st = state(oval, s, -(right[0] - HW + 0.01))
        h = st[2][0]
        t, inward = np.array([math.cos(h), math.sin(h)]), np.array([-math.sin(h), math.cos(h)])
        v = 30.0 * t - 0.5 * inward             # 0.5 m/s into the right barrier
        st[3][:], st[4][:] = v[0], v[1]
        rep = solver.resolve(*st, DT)
        v_after = np.array([st[3][0], st[4][0]])
        assert rep.wall[0], s
        assert v_after @ t == pytest.approx(30.0, abs=0.05), s
        assert v_after @ inward > -0.5, s
        checked += 1
    assert checked == 700


def test_wall_damage_accumulates_per_corner(oval):
    """Nose-first into the left barrier at 300 km/h (friction 0, rebound 0.5): both front
    corners go beyond the barrier line in one step, and TORCS answers each from the corner
    velocities of before the response (-v0 into the wall both times), so the first halves the
    into-wall speed and the second stops it: that step adds kd (0.5 (c v.n)^2 + 0.005 |1 - c|
    V) x skill for v.n = -v0 and again for v.n = -v0 / 2 (V = |v.n|, c = -1), each in whole
    points (TORCS adds the int of each hit: the fraction is dropped), one step after the move
    that put them there (TORCS tests the box at the start of the step); the car then stays (no
    speed into the wall, no further damage) and calls without contact add nothing."""
    s0 = straight_middle(oval)
    left, _ = oval.barrier_offsets_at(s0)
    st = state(oval, s0, left - HL - 0.5, yaw_rel=math.pi / 2, speed=V300)
    kd = oval.surfaces[int(oval.surface_at(s0, left + 1.0))].dammage
    solver = solver_for(oval, 1, wall_friction=0.0, rebound=0.5)
    reports = drive(solver, st, 60)
    damage = np.array([r.damage[0] for r in reports])
    hit = np.flatnonzero([r.wall[0] for r in reports])
    assert np.all(damage[[k for k in range(len(reports)) if not reports[k].wall[0]]] == 0.0)
    v = np.array([V300, V300 / 2.0])
    expected = np.floor(kd * (0.5 * v ** 2 + 0.005 * 2.0 * v) * SKILL).sum()
    # the step whose move puts the corners beyond the line only flags the contact; the next one
    # (TORCS's test of the start-of-step box) takes both damages
    assert len(hit) >= 2 and damage[hit[0]] == 0.0 and damage[hit[1]] == expected
    assert np.all(damage[hit[2:]] == 0.0)
    assert math.hypot(st[3][0], st[4][0]) == pytest.approx(0.0, abs=1e-6)


# --- car-car response -------------------------------------------------------------------------


def test_head_on_equal_cars_swap_velocities(speedway):
    """Equal masses, centred head-on contact, e = 1: velocities exchange (closed form), no
    rotation (r x n = 0), |j| = m |v_rel| and damage 0.1 |j| x 1.5 (frontal) x skill each."""
    s0 = straight_middle(speedway)
    st = state(speedway, [s0, s0 + 2 * HL - 0.05], 0.0, yaw_rel=np.array([0.0, math.pi]))
    h = st[2][0]
    st[3][:] = [30.0 * math.cos(h), -25.0 * math.cos(h)]
    st[4][:] = [30.0 * math.sin(h), -25.0 * math.sin(h)]
    v0 = np.stack([st[3].copy(), st[4].copy()])
    solver = solver_for(speedway, 2)
    rep = solver.resolve(*st, DT)
    assert rep.pairs == [(0, 1)] and rep.car.all() and not rep.wall.any()
    np.testing.assert_allclose(st[3], v0[0, ::-1], atol=1e-9)
    np.testing.assert_allclose(st[4], v0[1, ::-1], atol=1e-9)
    np.testing.assert_allclose(st[5], 0.0, atol=1e-9)
    j = MASS * 55.0
    np.testing.assert_array_equal(rep.damage, math.floor(0.1 * j * 1.5 * SKILL))
    assert sat_gap(st[0], st[1], st[2], 0, 1) >= 0.0


def test_rear_end_damage_is_frontal_only_for_the_hitting_car(speedway):
    s0 = straight_middle(speedway)
    st = state(speedway, [s0, s0 + 2 * HL - 0.03], 0.0)
    h = st[2][0]
    st[3][:] = np.array([40.0, 30.0]) * math.cos(h)
    st[4][:] = np.array([40.0, 30.0]) * math.sin(h)
    rep = solver_for(speedway, 2).resolve(*st, DT)
    j = MASS * 10.0          # e = 1, equal masses: the cars exchange their speeds
    np.testing.assert_array_equal(rep.damage, np.floor([0.1 * j * 1.5 * SKILL, 0.1 * j * SKILL]))
    np.testing.assert_allclose(np.hypot(st[3], st[4]), [30.0, 40.0], atol=1e-9)


def random_touching_pair(track, rng, s0):
    """Two cars at random yaw whose boxes overlap by 0.5-10 cm, random velocities and spins."""
    while True:
        dn, ds = rng.uniform(-3.0, 3.0), rng.uniform(-6.0, 6.0)
        st = state(track, [s0, s0 + ds], np.array([0.0, dn]), yaw_rel=rng.uniform(-math.pi, math.pi, 2))
        gap = sat_gap(st[0], st[1], st[2], 0, 1)
        if -0.1 < gap < -0.005:
            break
    st[3][:], st[4][:] = rng.normal(0.0, 20.0, 2), rng.normal(0.0, 20.0, 2)
    st[5][:] = rng.normal(0.0, 0.5, 2)
    return st


@pytest.mark.parametrize("restitution", [1.0, 0.5])
def test_car_car_conserves_momentum_and_creates_no_energy(speedway, restitution):
    """60 random oblique contacts (random yaw, speeds, spins; masses 1200/900 kg): linear
    momentum conserved, kinetic energy (incl. rotation) not increased; for e = 1 and no yaw-rate
    cap (3 rad/s) involved it is conserved exactly."""
    rng = np.random.default_rng(7)
    s0 = straight_middle(speedway)
    mass = np.array([1200.0, 900.0])
    izz = np.array([2000.0, 1300.0])
    solver = ContactSolver(speedway, np.full(2, HL), np.full(2, HW), mass, izz, car_restitution=restitution)
    checked_equal = 0
    for _ in range(60):
        solver.reset()
        st = random_touching_pair(speedway, rng, s0)
        p0 = np.array([mass @ st[3], mass @ st[4]])
        e0 = kinetic(st[3], st[4], st[5], mass, izz)
        rep = solver.resolve(*st, DT)
        assert rep.pairs == [(0, 1)]
        np.testing.assert_allclose([mass @ st[3], mass @ st[4]], p0, rtol=0, atol=1e-9 * (1 + abs(p0).max()))
        e1 = kinetic(st[3], st[4], st[5], mass, izz)
        assert e1 <= e0 * (1 + 1e-12) + 1e-9
        if restitution == 1.0 and np.all(np.abs(st[5]) < 3.0):
            # no yaw cap involved: an elastic impulse keeps kinetic energy exactly
            assert e1 == pytest.approx(e0, rel=1e-9)
            checked_equal += 1
        assert sat_gap(st[0], st[1], st[2], 0, 1) >= 0.0
    assert restitution != 1.0 or checked_equal >= 10


# --- 300 km/h: never through a wall or another car --------------------------------------------


@pytest.mark.parametrize("track_name, angle_deg", [
    ("madsim-oval", 90.0), ("madsim-oval", 30.0), ("madsim-oval", -60.0),
    ("madsim-street", 90.0), ("madsim-street", 35.0), ("madsim-speedway", 12.0),
])
def test_300kmh_into_a_wall_never_passes_through(track_name, angle_deg):
    track = load_track(track_name)
    s0 = straight_middle(track, min_len=3.0) if track_name == "madsim-street" else straight_middle(track)
    st = state(track, s0, 0.0, yaw_rel=math.radians(angle_deg), speed=V300)
    solver = solver_for(track, 1)
    worst = []

    def check(st, rep):
        worst.append(corner_excess(track, st[0], st[1], st[2]))

    reports = drive(solver, st, 600, check)
    assert any(r.wall[0] for r in reports), "the car never reached the wall"
    # TORCS answers a corner at the step after the move that put it beyond the line: the box
    # rides in by at most one sub-step's motion
    assert max(worst) <= V300 * DT, f"a corner went {max(worst):.4f} m beyond the barrier"


@pytest.mark.parametrize("offset, yaw_a, yaw_b", [(0.0, 0.0, 0.0), (1.2, 0.05, 0.05), (-1.5, -0.02, -0.04)])
def test_300kmh_head_on_cars_never_overlap_or_pass(speedway, offset, yaw_a, yaw_b):
    """Each car at 300 km/h (600 km/h closing): after every sub-step the boxes do not overlap
    and car B is still ahead of car A along the road."""
    s0 = straight_middle(speedway)
    st = state(speedway, [s0 - 25.0, s0 + 25.0], np.array([0.0, offset]),
               yaw_rel=np.array([yaw_a, math.pi + yaw_b]), speed=V300)
    ahead = np.array([math.cos(st[2][0] - yaw_a), math.sin(st[2][0] - yaw_a)])
    solver = solver_for(speedway, 2)
    gaps, order = [], []

    def check(st, rep):
        gaps.append(float(sat_gap(st[0], st[1], st[2], 0, 1)))
        order.append((st[0][1] - st[0][0]) * ahead[0] + (st[1][1] - st[1][0]) * ahead[1])

    reports = drive(solver, st, 400, check)
    assert any(r.pairs == [(0, 1)] for r in reports)
    assert min(gaps) >= 0.0, f"boxes overlapped by {-min(gaps):.4f} m"
    assert min(order) > 0.0


# --- many cars ----------------------------------------------------------------------------------


def test_thousand_cars_only_planted_contacts(speedway):
    """1,000 cars over 4.2 km: 3 planted overlapping pairs and 2 cars planted in the barrier are
    the only contacts; afterwards nothing overlaps and every corner is inside (brute force)."""
    n_cars = 1000
    rng = np.random.default_rng(3)
    s = np.arange(n_cars) * speedway.length / n_cars + rng.uniform(0, 0.3, n_cars)
    n_off = np.array([-6.0, -2.0, 2.0, 6.0])[np.arange(n_cars) % 4]
    yaw_rel = rng.uniform(-0.05, 0.05, n_cars)
    planted = [(100, 104), (500, 504), (900, 904)]        # same lane, 4 slots apart: put nose to tail
    for i, j in planted:
        s[j] = s[i] + 2 * HL - 0.2        # 0.2 m: still overlapping on the outer lane of a bend
        yaw_rel[i] = yaw_rel[j] = 0.0
    left, right = speedway.barrier_offsets_at(s[[300, 700]])
    n_off[300], n_off[700] = left[0] - HW + 0.03, -(right[1] - HW + 0.03)
    yaw_rel[[300, 700]] = 0.0
    st = state(speedway, s, n_off, yaw_rel=yaw_rel, speed=50.0)
    solver = solver_for(speedway, n_cars)
    rep = solver.resolve(*st, DT)
    assert rep.pairs == planted
    assert np.flatnonzero(rep.wall).tolist() == [300, 700]
    assert sorted(np.flatnonzero(rep.car).tolist()) == sorted(k for p in planted for k in p)
    i, j = np.triu_indices(n_cars, 1)
    close = np.hypot(st[0][j] - st[0][i], st[1][j] - st[1][i]) < 2 * math.hypot(HL, HW)
    assert np.all(sat_gap(st[0], st[1], st[2], i[close], j[close]) >= 0.0)
    assert corner_excess(speedway, st[0], st[1], st[2]) <= 0.0
    # and the next 100 sub-steps (cars driving straight on) stay consistent
    drive(solver, st, 100)
    assert corner_excess(speedway, st[0], st[1], st[2]) <= 0.0


# --- determinism, reset, errors -----------------------------------------------------------------


def crash_scenario(track):
    s0 = straight_middle(track)
    left, _ = track.barrier_offsets_at(s0)
    st = state(track, [s0, s0 + 12.0, s0 + 30.0], np.array([0.0, 0.5, left - 4.0]),
               yaw_rel=np.array([0.0, math.pi - 0.2, 0.4]), speed=V300)
    st[5][:] = [0.3, -0.2, 0.1]
    return st


def run_scenario(solver, track, steps=300):
    st = crash_scenario(track)
    reports = drive(solver, st, steps)
    return st, reports


def test_same_inputs_same_outputs(oval):
    a_state, a_reps = run_scenario(solver_for(oval, 3), oval)
    b_state, b_reps = run_scenario(solver_for(oval, 3), oval)
    assert any(r.pairs for r in a_reps) and any(r.wall.any() for r in a_reps)
    for a, b in zip(a_state, b_state):
        assert np.array_equal(a, b)
    for ra, rb in zip(a_reps, b_reps):
        assert ra.pairs == rb.pairs and np.array_equal(ra.damage, rb.damage)
        assert np.array_equal(ra.wall, rb.wall) and np.array_equal(ra.car, rb.car)


def scenario_digest(track_name: str, extra_solvers: int) -> str:
    """sha256 of the final state and every call's damage of `run_scenario`, after creating
    `extra_solvers` unrelated solvers (they shift pymunk's object ids and hash ids)."""
    track = load_track(track_name)
    junk = [solver_for(track, 4) for _ in range(extra_solvers)]
    st, reports = run_scenario(solver_for(track, 3), track)
    del junk
    return hashlib.sha256(b"".join(a.tobytes() for a in st)
                          + b"".join(r.damage.tobytes() for r in reports)).hexdigest()


def test_same_outputs_in_another_process():
    code = ("import sys; sys.path[:0] = sys.argv[1:3]; import test_contact as t; "
            "print(t.scenario_digest('madsim-street', 2))")
    here = Path(__file__).parent
    out = subprocess.run([sys.executable, "-c", code, str(here), str(here.parent / "support")],
                         capture_output=True, text=True, timeout=300, check=True)
    assert out.stdout.strip() == scenario_digest("madsim-street", 0)


def test_reset_makes_a_used_solver_behave_like_a_new_one(oval):
    solver = solver_for(oval, 3)
    run_scenario(solver, oval, steps=150)
    solver.reset()
    a_state, a_reps = run_scenario(solver, oval)
    b_state, b_reps = run_scenario(solver_for(oval, 3), oval)
    for a, b in zip(a_state, b_state):
        assert np.array_equal(a, b)
    assert [r.pairs for r in a_reps] == [r.pairs for r in b_reps]


def test_bad_arrays_are_rejected_with_their_name(oval):
    solver = solver_for(oval, 2)
    st = state(oval, [10.0, 40.0], 0.0)
    bad = list(st)
    bad[4] = st[4][:1].copy()
    with pytest.raises(ValueError, match="vy must be a numpy float64 array of shape \\(2,\\)"):
        solver.resolve(*bad, DT)
    bad = list(st)
    bad[6] = st[6].astype(np.int32)
    with pytest.raises(ValueError, match="piece must be a numpy int64"):
        solver.resolve(*bad, DT)
    bad = list(st)
    bad[0] = [1.0, 2.0]
    with pytest.raises(ValueError, match="x must be"):
        solver.resolve(*bad, DT)


@pytest.mark.parametrize("change, match", [
    ({"mass": [MASS, -1.0]}, "mass must be finite and > 0"),
    ({"half_width": [HW]}, "half_width has 1 entries"),
    ({"car_restitution": 1.5}, "car_restitution must be in"),
    ({"rebound": float("nan")}, "rebound must be in"),
])
def test_bad_construction_is_rejected(oval, change, match):
    kwargs = {"half_length": [HL, HL], "half_width": [HW, HW], "mass": [MASS, MASS], "izz": [IZZ, IZZ]}
    kwargs.update(change)
    with pytest.raises(ValueError, match=match):
        ContactSolver(oval, **kwargs)


# --- what TORCS's corner test misses -------------------------------------------------------------


def test_side_of_the_box_against_a_convex_wall_is_a_contact(street):
    """Car tangent to the inner barrier of a 12 m bend (barrier radius 7.8 m), the middle of its
    side 5 cm beyond the barrier and all four corners inside: TORCS's corners-only test misses
    this, the pymunk box-vs-segments test finds it and pushes the side out (to within the
    polyline's chord error, 1 cm)."""
    geo = street.geo
    bends = np.flatnonzero((geo[:, 0] == 1.0) & (geo[:, 3] == 12.0))
    s_mid = geo[bends[0], 1] + 2.5 * geo[bends[0], 2]
    left, _ = street.barrier_offsets_at(s_mid)
    st = state(street, s_mid, left - HW + 0.05)
    assert corner_excess(street, st[0], st[1], st[2]) < -0.2
    rep = solver_for(street, 1).resolve(*st, DT)
    assert rep.wall[0]
    u = np.linspace(-1.0, 1.0, 41)
    c, s = math.cos(st[2][0]), math.sin(st[2][0])
    side_x = st[0][0] + u * HL * c - HW * s
    side_y = st[1][0] + u * HL * s + HW * c
    s_side, n_side = street.locate(side_x, side_y)
    assert np.max(n_side - street.barrier_offsets_at(s_side)[0]) < 0.01


def test_torcs_track_at_300kmh():
    if not torcs_installed():
        pytest.skip("TORCS data not installed: apt-get install torcs-data")
    track = load_track("g-track-1")
    st = state(track, 300.0, 0.0, yaw_rel=math.radians(40.0), speed=V300)
    worst = []
    reports = drive(solver_for(track, 1), st, 500,
                    lambda st, rep: worst.append(corner_excess(track, st[0], st[1], st[2])))
    assert any(r.wall[0] for r in reports) and max(worst) <= V300 * DT


def test_cars_on_a_bridge_do_not_touch_the_road_below():
    """wheel-2 crosses itself: a car parked on the bridge and a car driving along the road
    below, through the same place in plan, touch neither each other nor the other level's
    barriers (pymunk is 2-D; contacts are checked against each car's own track position)."""
    if not torcs_installed():
        pytest.skip("TORCS data not installed: apt-get install torcs-data")
    track = load_track("wheel-2")
    pts = np.stack([track.x, track.y], axis=1)[::4]
    s = track.s[::4]
    d = np.hypot(*(pts[:, None, :] - pts[None, :, :]).transpose(2, 0, 1))
    ds = np.abs(s[:, None] - s[None, :])
    d[np.minimum(ds, track.length - ds) < 100.0] = np.inf
    a, b = np.unravel_index(np.argmin(d), d.shape)
    lower, upper = sorted((s[a], s[b]), key=lambda v: track.elevation(v, 0.0))
    x, y, _, _ = track.pose(lower, 0.0)
    s_up, n_up = track.locate(np.array([x]), np.array([y]), s_hint=np.array([upper]))
    assert abs(float(track.elevation(upper, 0.0) - track.elevation(lower, 0.0))) > 3.0
    solver = solver_for(track, 2)
    for k in range(150):
        s_low = lower - 6.0 + 0.08 * k
        st = state(track, np.array([s_low, s_up[0]]), np.array([0.0, n_up[0]]))
        rep = solver.resolve(*st, DT)
        assert not rep.wall.any() and not rep.car.any() and rep.pairs == []


def test_bad_piece_and_dt_are_rejected(oval):
    solver = solver_for(oval, 2)
    st = state(oval, [10.0, 40.0], 0.0)
    st[6][1] = oval.n_pieces
    with pytest.raises(ValueError, match=rf"piece\[1\] = {oval.n_pieces} is not a piece index"):
        solver.resolve(*st, DT)
    st[6][1] = 0
    with pytest.raises(ValueError, match="dt must be a number > 0"):
        solver.resolve(*st, 0.0)


def test_a_car_with_a_nan_pose_touches_nothing(oval):
    """A NaN car (a blown-up state) is ignored, also when it already sits in the pymunk space;
    the others still collide normally."""
    s0 = straight_middle(oval)
    solver = solver_for(oval, 3)
    st = state(oval, [s0, s0 + 20.0, s0 + 20.0 + 2 * HL - 0.05], 0.0)
    assert solver.resolve(*st, DT).pairs == [(1, 2)]          # car 2 enters the pymunk space
    st = state(oval, [s0, s0 + 2 * HL - 0.05, s0 + 20.0], 0.0)
    st[0][2] = np.nan
    rep = solver.resolve(*st, DT)
    assert rep.pairs == [(0, 1)] and not rep.wall.any() and not rep.car[2]
    assert np.isnan(st[0][2]) and np.all(np.isfinite(st[0][:2]))


def test_ten_car_pile_up_never_overlaps(speedway):
    """Ten cars in one lane, 8 m apart, 20-83 m/s, slightly yawed: a chain of rear-end hits.
    After every sub-step no two boxes overlap and every corner is inside the barriers;
    momentum is conserved while no car touches a wall."""
    rng = np.random.default_rng(11)
    s0 = straight_middle(speedway) - 60.0
    st = state(speedway, s0 + 8.0 * np.arange(10), 0.0, yaw_rel=rng.uniform(-0.05, 0.05, 10),
               speed=0.0)
    speed = np.linspace(V300, 20.0, 10)
    st[3][:], st[4][:] = speed * np.cos(st[2]), speed * np.sin(st[2])
    solver = solver_for(speedway, 10)
    i, j = np.triu_indices(10, 1)
    p0 = np.array([st[3].sum(), st[4].sum()]) * MASS
    worst_gap, worst_wall, touched, walls = [], [], set(), 0

    def check(st, rep):
        nonlocal walls
        worst_gap.append(float(sat_gap(st[0], st[1], st[2], i, j).min()))
        worst_wall.append(corner_excess(speedway, st[0], st[1], st[2]))
        touched.update(rep.pairs)
        walls += int(rep.wall.any())

    drive(solver, st, 300, check)
    assert len(touched) >= 5
    assert min(worst_gap) >= 0.0 and max(worst_wall) <= 0.0
    if walls == 0:
        np.testing.assert_allclose(np.array([st[3].sum(), st[4].sum()]) * MASS, p0, rtol=1e-12, atol=1e-6)


@pytest.mark.parametrize("track_name", ["madsim-road", "madsim-street", "madsim-oval"])
def test_wall_segments_follow_the_barrier_polylines(track_name):
    """Every barrier polyline sample lies on a wall segment (1e-9 m): merging the samples of a
    straight piece must keep the steps where side widths change between pieces."""
    track = load_track(track_name)
    seg = solver_for(track, 1).wall_segments()
    a, ab = seg[:, :2], seg[:, 2:] - seg[:, :2]
    for side in ("left", "right"):
        for p in np.array_split(track.barrier_polyline(side), 40):       # (k, 2) chunks
            rel = p[:, None, :] - a[None, :, :]
            t = np.clip((rel * ab).sum(axis=2) / (ab ** 2).sum(axis=1), 0.0, 1.0)
            dist = np.hypot(*(rel - t[..., None] * ab).transpose(2, 0, 1)).min(axis=1)
            assert dist.max() < 1e-9


def test_a_car_resting_against_a_barrier_gains_no_damage(oval):
    """TORCS adds each barrier hit's damage as a whole number, the fraction dropped. A car
    pressed against a barrier at rest hits it every step at a few cm/s, a hit worth kd x 0.005
    x |1 - c| x 1 x skill = 0.04 points (V = max(1, |v|)): TORCS's car gains nothing (the
    traces: dirt-2's car sits at the side from message 1240 to its removal with its damage at
    276 throughout). Here a car nosed 60 deg into the left barrier, full throttle in first gear,
    steering away (the reference controller's commands there), for 3 s: in contact most of the
    time, no damage (it gained 0.04 per contact step before)."""
    from madsim.cars import load_car
    from madsim.physics.world import World

    car = load_car("car1-trb1")
    world = World(oval, [car], np.random.default_rng(0), damage=True)
    world.reset()
    s0 = straight_middle(oval)
    left, _ = oval.barrier_offsets_at(s0)
    yaw_rel = math.radians(60.0)
    reach = car.body_length / 2 * math.sin(yaw_rel) + car.overall_width / 2 * math.cos(yaw_rel)
    world.place(0, s0, float(left) - reach - 0.02, yaw_rel=yaw_rel, speed=0.0, gear=1)
    u = np.array([[-1.0, 1.0, 0.0, 1.0, 0.0]])
    touching = 0
    for _ in range(150):
        world.step(u)
        touching += bool(world.contact_wall[0])
    assert touching > 100
    assert abs(float(world.speed[0])) < 2.0
    assert world.damage[0] == 0.0
