"""Per-wheel spin and TORCS's axle differentials (spec 4.10): the kernel's one-axle step against
closed forms, then whole cars turning (free wheels roll at their own contact speed, a spool
turns both wheels together, a limited slip holds their speed ratio)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from madsim.physics import kernel
from madsim.physics import layout as L

DT = 0.002


def diff_table(kind, slip=0.03, lock=3000.0, lockb=990.0, dmin=0.05, dmax=0.8, visc=1.0):
    """A one-car constant table with axle 0's differential set (the rest is never read)."""
    cp = np.zeros((1, L.N_CAR))
    cp[0, L.C_DKIND] = L.DIFF_KINDS.index(kind)
    cp[0, L.C_DSLIP], cp[0, L.C_DLOCK], cp[0, L.C_DLOCKB] = slip, lock, lockb
    cp[0, L.C_DMIN], cp[0, L.C_DSPAN], cp[0, L.C_DVISC] = dmin, dmax - dmin, visc
    return cp


def axle(cp, drive, w0, w1, t0=0.0, t1=0.0, s0=0.0, s1=0.0, i0=2.0, i1=2.0, b0=0.0, b1=0.0, fb=0.0):
    return kernel._axle_spin(cp, 0, 0, drive, fb, w0, w1, t0, t1, s0, s1, i0, i1, b0, b1, DT)


def test_free_differential_splits_the_drive_and_passes_the_spider_torque():
    # TORCS 1.3.7: d0 = (D + t1 - t0) / 2, d1 = (D - t1 + t0) / 2; each wheel then w += dt (d - t) / I
    cp = diff_table("FREE")
    D, t0, t1, i0, i1 = 800.0, 300.0, 100.0, 2.0, 3.0
    w0, w1 = axle(cp, D, 50.0, 52.0, t0, t1, i0=i0, i1=i1)
    assert w0 == pytest.approx(50.0 + DT * ((D + t1 - t0) / 2 - t0) / i0, rel=1e-14)
    assert w1 == pytest.approx(52.0 + DT * ((D - t1 + t0) / 2 - t1) / i1, rel=1e-14)
    # at rest (no common speed) each wheel gets half, without the spider
    w0, w1 = axle(cp, D, 0.0, 0.0, t0, t1)
    assert (w0, w1) == pytest.approx((DT * (D / 2 - t0) / 2.0, DT * (D / 2 - t1) / 2.0), rel=1e-14)


def test_free_differential_step_is_implicit_in_both_tyre_torques():
    # the linearised tyre torques t_k + s_k dw_k satisfy the step's equations exactly
    cp = diff_table("FREE")
    D, t0, t1, s0, s1, i0, i1 = 500.0, 200.0, -50.0, 4000.0, 900.0, 1.5, 2.5
    w0, w1 = axle(cp, D, 40.0, 41.0, t0, t1, s0, s1, i0, i1)
    dw0, dw1 = w0 - 40.0, w1 - 41.0
    T0, T1 = t0 + s0 * dw0, t1 + s1 * dw1
    assert i0 * dw0 / DT == pytest.approx((D + T1 - T0) / 2 - T0, abs=1e-8)
    assert i1 * dw1 / DT == pytest.approx((D - T1 + T0) / 2 - T1, abs=1e-8)


@pytest.mark.parametrize("kind", ["FREE", "LIMITED SLIP", "SPOOL"])
def test_4wd_axle_takes_the_tyre_torques_fed_back_off_its_drive(kind):
    # a 4WD axle's input is the centre differential's net output: its share of the drive less
    # the axle's tyre torques over the centre ratio (fb = 1/ratio), then split as usual
    cp = diff_table(kind)
    D, t0, t1, fb, w = 900.0, 300.0, 100.0, 1.0 / 6.0, 40.0
    w0, w1 = axle(cp, D, w, w, t0, t1, fb=fb)
    d = D - fb * (t0 + t1)
    if kind == "SPOOL":
        assert w0 == w1 == pytest.approx(w + DT * (d - t0 - t1) / 4.0, rel=1e-14)
    else:
        assert w0 == pytest.approx(w + DT * ((d + t1 - t0) / 2 - t0) / 2.0, rel=1e-14)
        assert w1 == pytest.approx(w + DT * ((d - t1 + t0) / 2 - t1) / 2.0, rel=1e-14)
    # implicit in the fed-back torques too: the linearised equations hold at the new spins
    s0, s1 = 3000.0, 1000.0
    w0, w1 = axle(cp, D, w, w, t0, t1, s0, s1, fb=fb)
    T0, T1 = t0 + s0 * (w0 - w), t1 + s1 * (w1 - w)
    d = D - fb * (T0 + T1)
    if kind == "SPOOL":
        assert 4.0 * (w0 - w) / DT == pytest.approx(d - T0 - T1, abs=1e-8)
    else:
        assert 2.0 * (w0 - w) / DT == pytest.approx((d + T1 - T0) / 2 - T0, abs=1e-8)
        assert 2.0 * (w1 - w) / DT == pytest.approx((d - T1 + T0) / 2 - T1, abs=1e-8)


def test_spool_turns_both_wheels_as_one_body():
    cp = diff_table("SPOOL")
    w0, w1 = axle(cp, 600.0, 30.0, 35.0, 100.0, 300.0, i0=2.0, i1=3.0)
    assert w0 == w1 == pytest.approx(30.0 + DT * (600.0 - 400.0) / 5.0, rel=1e-14)


def test_limited_slip_clamps_the_speed_ratio_and_locks_above_its_torques():
    cp = diff_table("LIMITED SLIP", slip=0.03, lock=3000.0, lockb=1000.0)
    # no torque: ratio 0.1 clamped to 0.03 about the mean, nothing else changes
    w0, w1 = axle(cp, 0.0, 110.0, 90.0)
    assert (w0, w1) == pytest.approx((103.0, 97.0), rel=1e-14)
    # half the locking torque halves the allowed ratio; the excess biases the drive to the
    # slower wheel: d0 = (D (1 - excess) + t1 - t0) / 2 with wheel 0 the faster
    D = 1500.0
    w0, w1 = axle(cp, D, 110.0, 90.0)
    excess = 0.1 - 0.015
    assert w0 == pytest.approx(100.0 * 1.015 + DT * D * (1 - excess) / 2 / 2.0, rel=1e-13)
    assert w1 == pytest.approx(100.0 * 0.985 + DT * D * (1 + excess) / 2 / 2.0, rel=1e-13)
    # beyond the locking input torque, and beyond minus the brake locking torque: a spool
    for D in (3001.0, -1001.0):
        w0, w1 = axle(cp, D, 110.0, 90.0)
        assert w0 == w1 == pytest.approx(110.0 + DT * D / 4.0, rel=1e-14)


def test_viscous_axle_coupler_gives_the_slower_right_wheel_more():
    cp = diff_table("VISCOUS COUPLER", dmin=0.3, dmax=0.6, visc=0.5)
    w0, w1 = axle(cp, 1000.0, 50.0, 48.0)            # right not slower: min bias
    assert w0 == pytest.approx(50.0 + DT * 300.0 / 2.0, rel=1e-14)
    share = 0.3 + (1.0 - np.exp(-0.5 * 2.0)) * 0.3
    w0, w1 = axle(cp, 1000.0, 48.0, 50.0)
    assert w0 == pytest.approx(48.0 + DT * 1000.0 * share / 2.0, rel=1e-14)
    assert w1 == pytest.approx(50.0 + DT * 1000.0 * (1.0 - share) / 2.0, rel=1e-14)


def test_brakes_stop_each_wheel_but_never_reverse_it():
    cp = diff_table("NONE")           # a non-driven axle: two free wheels
    w0, w1 = axle(cp, 0.0, 0.5, 30.0, b0=5000.0, b1=5000.0)
    assert w0 == 0.0
    assert w1 == pytest.approx(30.0 - DT * 5000.0 / 2.0, rel=1e-14)
    w0, w1 = axle(diff_table("SPOOL"), 0.0, 0.5, 0.5, b0=5000.0, b1=5000.0)
    assert w0 == w1 == 0.0


def turning(ph, make_track, car, seconds=2.0, steer=0.15, accel=0.25):
    """A car turning left at ~15 m/s on a wide flat square: its World after `seconds`."""
    from trackfiles import segment
    track = make_track([segment("s", "str", lg=800.0)], width=80.0)
    w = ph.world_at(track, car, s=200.0, speed=15.0, gear=2)
    u = np.array([[steer, accel, 0.0, 2, 0.0]])
    for _ in range(int(seconds / 0.02)):
        w.step(u)
    return w


def test_free_rolling_wheels_each_roll_at_their_own_contact_speed(ph, make_track):
    # RWD sedan: the front wheels are free; with no drive or brake their tyre torque ~ 0, so
    # each one's spin x radius = its own contact point's speed along the wheel (outer faster)
    w = turning(ph, make_track, ph.sedan())
    st, car = w.state[0], ph.sedan()
    r, vx, vy, d = st[L.S_R], st[L.S_VX], st[L.S_VY], st[L.S_STEER]
    assert r > 0.2                                    # turning left, rad/s
    spin = w.wheel_spin[0]
    # Ackermann (spec 4.2): the inner (left) wheel turns by d, the outer by a smaller angle
    # (TORCS's wheel track: the mean of the front and rear tracks)
    track = 0.5 * (car.track_front + car.track_rear)
    outer = np.arctan(car.wheelbase * np.tan(d) / (car.wheelbase + track * np.tan(d)))
    for k, dk in ((0, outer), (1, d)):
        xk, yk = car.wheel_pos[k]
        vt = (vx - yk * r) * np.cos(dk) + (vy + xk * r) * np.sin(dk)
        assert spin[k] * car.wheel_radius[k] == pytest.approx(vt, rel=2e-3)
    # the right (outer) wheel faster than the left by ~ track x yaw rate
    gap = (spin[0] - spin[1]) * car.wheel_radius[0]
    assert gap == pytest.approx(car.track_front * r, rel=0.1)


@pytest.mark.parametrize("kind", ["SPOOL", "FREE", "LIMITED SLIP"])
def test_driven_rear_axle_follows_its_differential_in_a_turn(ph, make_track, kind):
    car = ph.sedan(differential_types=("NONE", kind, "NONE"),
                   diff_max_slip_bias=np.array([0.03, 0.003]))
    w = turning(ph, make_track, car)
    wr = w.wheel_spin[0, 2:]
    ratio = abs(wr[0] - wr[1]) / (abs(wr[0]) + abs(wr[1]))
    open_ratio = car.track_rear * w.state[0, L.S_R] / (2 * w.state[0, L.S_VX])   # rolling freely
    assert open_ratio > 0.01
    if kind == "SPOOL":
        assert wr[0] == wr[1]
    elif kind == "FREE":
        assert ratio == pytest.approx(open_ratio, rel=0.1)
    else:
        # clamped to 0.003 before each step; the step then lets each tyre pull its wheel back
        # (the tyre torques are the ones of the spins before the clamp, as in TORCS), and above
        # 3 m/s TORCS's spin average takes the mean with the last raw spin (itself from an
        # unclamped tyre pull): measured 0.0130 against 0.0200 open (before the average 0.0089
        # against 0.0195)
        assert ratio < 0.75 * open_ratio


def test_limited_slip_axle_locks_on_the_engine_torque_times_the_overall_ratio(ph, make_track):
    # TORCS 1.3.7 (SimTransmissionUpdate, simuv2.so): the differential's input is the engine
    # torque x the gear's overall ratio x min(3 x clutch transfer, 1), with no gear or
    # differential efficiency; the limited-slip axle is a spool while that input is above its
    # locking torque or below minus its locking brake torque. A turning sedan in 2nd gear with
    # 90 % gear efficiencies: at full throttle the input is T(we) x G (the curve's torque); a
    # lock 3 % below it makes the rear wheels one body (equal spins after two sub-steps: the
    # spin average then takes the mean of two equal pairs), 3 % above it leaves them apart.
    # Lifting off, the engine brakes with -k T(we) x G. Applying the efficiency would put the
    # input 10 % nearer 0, and neither lock would engage.
    import copy

    car = ph.sedan(differential_types=("NONE", "LIMITED SLIP", "NONE"), gear_efficiencies=(0.9,) * 7)
    w = turning(ph, make_track, car)
    we = float(w.engine_speed[0])
    k = car.engine_brake_coeff * (we - car.tickover) / (car.revs_maxi - car.tickover)
    for accel, d_in, column in ((1.0, car.torque_at(we) * car.overall_ratio(2), L.C_DLOCK + 1),
                                (0.0, -k * car.torque_at(we) * car.overall_ratio(2), L.C_DLOCKB + 1)):
        for scale, locked in ((0.97, True), (1.03, False)):
            c = copy.deepcopy(w)
            c._cp[0, L.C_DLOCK + 1] = c._cp[0, L.C_DLOCKB + 1] = 1e9
            c._cp[0, column] = scale * abs(d_in)
            for _ in range(2):
                c.step(np.array([[0.15, accel, 0.0, 2, 0.0]]), substeps=1)
            wr = c.wheel_spin[0, 2:]
            assert (wr[0] == wr[1]) == locked, (accel, scale, wr)
            if not locked:      # the clamp holds them near (0.03 x (1 - 1 / 1.03) at full throttle)
                assert abs(wr[0] - wr[1]) > 0.05


def test_car_files_give_each_axle_its_differential(need_torcs):
    from madsim.cars import load_car
    car = load_car("155-DTM")
    assert car.differential_types == ("LIMITED SLIP", "LIMITED SLIP", "VISCOUS COUPLER")
    assert list(car.diff_max_slip_bias) == pytest.approx([0.03, 0.03])
    assert list(car.diff_locking_torque) == pytest.approx([5000.0, 5000.0])
    assert list(car.diff_locking_brake_torque) == pytest.approx([1500.0, 1500.0])
    # the defaults: TORCS's, the brake locking torque a third of the locking torque
    sedan = load_car("madsim-sedan")
    assert list(sedan.diff_locking_brake_torque) == pytest.approx(0.33 * sedan.diff_locking_torque, rel=1e-6)
    rows = dataclasses.replace(sedan, differential_types=("SPOOL", "LIMITED SLIP", "NONE"))
    from madsim.physics.tables import car_table
    cp = car_table([rows], ["pro"])[0]
    # the front axle is not driven on a RWD car: two free wheels whatever its section says
    assert cp[0, L.C_DKIND] == L.DIFF_NONE and cp[0, L.C_DKIND + 1] == L.DIFF_LSD
