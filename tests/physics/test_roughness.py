"""Road roughness (docs/physics.md, "Road roughness"): TORCS 1.3.7's RtTrackHeightL adds
a sin(k t) sin(k l) to the road height on the road, its plain borders and sides (a = half the
surface's roughness, k = 2 pi / its wavelength, t from the zone's right edge, l along the zone's
own centre line), a sin(k l) (depth into the curb / curb width) on a curb border; the wheels ride
on it. Closed-form checks of the height, and the jitter it puts into a driven axle's spins."""

from __future__ import annotations

import math

import numpy as np
import pytest
from trackfiles import segment, track_xml

from madsim.physics import layout as L
from madsim.physics.suspension import relief
from madsim.physics.tables import piece_table
from madsim.tracks import load_track

W, BW, SW = 12.0, 1.5, 4.0           # road, border and side widths, m
REL = 1e-4          # the file's numbers are float32 (as TORCS reads them): phase errors ~1e-5


def _surface(name, rough, wavelength):
    return (f'<section name="{name}"><attnum name="friction" val="1.0"/>'
            f'<attnum name="roughness" unit="m" val="{rough}"/>'
            f'<attnum name="roughness wavelength" unit="m" val="{wavelength}"/></section>')


def _track(tmp_path, segs, left_style="plan", rough_road=0.01, right_style="plan", heights=(0.0, 0.0),
           rough_rb=0.02):
    """Road `tar` (roughness rough_road, wavelength 0.8 m), right border `rb` (rough_rb, 2 m) of
    style right_style and side `rs` (0.04, 5 m), left border `lb` (0.03, 1.2 m) of style
    left_style, left side `ls` (0); the borders' heights (right, left), m."""
    surfaces = (_surface("tar", rough_road, 0.8) + _surface("rb", rough_rb, 2.0) + _surface("rs", 0.04, 5.0)
                + _surface("lb", 0.03, 1.2) + _surface("ls", 0.0, 1.0))
    extra = ('<attstr name="surface" val="tar"/>'
             f'<section name="Right Border"><attnum name="width" unit="m" val="{BW}"/>'
             f'<attnum name="height" unit="m" val="{heights[0]}"/>'
             f'<attstr name="surface" val="rb"/><attstr name="style" val="{right_style}"/></section>'
             f'<section name="Right Side"><attnum name="width" unit="m" val="{SW}"/>'
             '<attstr name="surface" val="rs"/></section>'
             f'<section name="Left Border"><attnum name="width" unit="m" val="{BW}"/>'
             f'<attnum name="height" unit="m" val="{heights[1]}"/>'
             f'<attstr name="surface" val="lb"/><attstr name="style" val="{left_style}"/></section>'
             f'<section name="Left Side"><attnum name="width" unit="m" val="{SW}"/>'
             '<attstr name="surface" val="ls"/></section>')
    p = tmp_path / "rough" / "rough.xml"
    p.parent.mkdir(exist_ok=True)
    p.write_text(track_xml(segs, width=W, surfaces=surfaces, name="rough", main_extra=extra), encoding="utf-8")
    return piece_table(load_track(p))


def test_height_on_the_road_its_borders_and_sides(tmp_path):
    pt, surf, tsc = _track(tmp_path, [segment("s", "str", lg=200.0)])
    assert surf.shape[1] == 6      # friction, rolling, roughness a, k; rebound, dammage (bottoming)
    k = lambda wl: 2.0 * math.pi / wl  # noqa: E731
    for q, n in ((3.3, 0.3), (17.05, 4.1), (41.3, -5.9)):            # on the road: t = n + W / 2
        want = 0.005 * math.sin(k(0.8) * (n + W / 2)) * math.sin(k(0.8) * q)
        assert relief(pt, surf, tsc, 0, q, n, False) == pytest.approx(want, rel=REL)
    q = 12.7
    # right border: t from its own right edge; then the right side, from its outer edge
    n = -W / 2 - 0.4
    assert relief(pt, surf, tsc, 0, q, n, False) == pytest.approx(
        0.01 * math.sin(k(2.0) * (BW - 0.4)) * math.sin(k(2.0) * q), rel=REL)
    n = -W / 2 - BW - 1.1
    assert relief(pt, surf, tsc, 0, q, n, False) == pytest.approx(
        0.02 * math.sin(k(5.0) * (SW - 1.1)) * math.sin(k(5.0) * q), rel=REL)
    # left border (plain) from the road's left edge; the left side is smooth
    assert relief(pt, surf, tsc, 0, q, W / 2 + 0.9, False) == pytest.approx(
        0.015 * math.sin(k(1.2) * 0.9) * math.sin(k(1.2) * q), rel=REL)
    assert relief(pt, surf, tsc, 0, q, W / 2 + BW + 1.0, False) == 0.0


def test_curb_border_and_turns(tmp_path):
    segs = [segment("s", "str", lg=100.0), segment("t", "lft", radius=80.0, arc=90.0)]
    pt, surf, tsc = _track(tmp_path, segs, left_style="curb", rough_road=0.0)
    assert relief(pt, surf, tsc, 0, 20.0, 1.0, False) == 0.0            # a smooth road
    k = 2.0 * math.pi / 1.2
    # a curb: a sin(k l) x depth into it / its width, whatever the lateral wave
    assert relief(pt, surf, tsc, 0, 20.0, W / 2 + 0.6, False) == pytest.approx(
        0.015 * math.sin(k * 20.0) * 0.6 / BW, rel=REL)
    # in the left turn the curb's centre line runs at radius 80 - (W + BW) / 2: l is scaled by it
    p = int(np.flatnonzero(pt[:, L.P_KIND] == 1)[0])
    scale = (80.0 - 0.5 * (W + BW)) / 80.0
    assert relief(pt, surf, tsc, p, 9.0, W / 2 + 0.6, False) == pytest.approx(
        0.015 * math.sin(k * 9.0 * scale) * 0.6 / BW, rel=REL)
    # the right border (plain, outside the turn) runs at radius 80 + (W + BW) / 2
    kr = 2.0 * math.pi / 2.0
    assert relief(pt, surf, tsc, p, 9.0, -W / 2 - 0.5, False) == pytest.approx(
        0.01 * math.sin(kr * (BW - 0.5)) * math.sin(kr * 9.0 * (80.0 + 0.5 * (W + BW)) / 80.0), rel=REL)


def test_curb_heights(tmp_path):
    """A curb of height h and width w rises from the road's edge by atan2(h, w) per metre into
    it (TORCS 1.3.7's RtTrackHeightL: an angle used as a slope, so its outer edge stands
    w atan(h / w), a little under h); the side beyond is back on the road's plane. A plain
    border of the same height stays flat. A rough curb adds a sin(k l) d / w (left: 15 mm,
    1.2 m; l along its centre line, outside the right turn)."""
    segs = [segment("s", "str", lg=100.0), segment("t", "rgt", radius=60.0, arc=45.0)]
    hr, hl = 0.05, 0.12
    pt, surf, tsc = _track(tmp_path, segs, left_style="curb", rough_road=0.0, right_style="curb",
                           heights=(hr, hl), rough_rb=0.0)
    k = 2.0 * math.pi / 1.2
    for p, l_per_q in ((0, 1.0), (1, 1.0 + 0.5 * (W + BW) / 60.0)):
        q = 7.5
        assert relief(pt, surf, tsc, p, q, 1.0, False) == 0.0
        for d in (0.1, 0.75, 1.4):
            assert relief(pt, surf, tsc, p, q, W / 2 + d, False) == pytest.approx(
                d * math.atan2(hl, BW) + 0.015 * math.sin(k * q * l_per_q) * d / BW, rel=REL)
            assert relief(pt, surf, tsc, p, q, -W / 2 - d, False) == pytest.approx(d * math.atan2(hr, BW), rel=1e-6)
        assert relief(pt, surf, tsc, p, q, W / 2 + BW + 0.5, False) == 0.0     # the smooth left side
    # at the right curb's outer edge: 1.5 atan(0.05 / 1.5) = 0.04998 m, not 0.05
    assert relief(pt, surf, tsc, 0, 20.0, -W / 2 - BW + 1e-9, False) == pytest.approx(0.049981, abs=1e-6)
    # a plain border keeps its height off the road
    pt2, surf2, tsc2 = _track(tmp_path, segs, rough_road=0.0, heights=(hr, hl), rough_rb=0.0)
    assert relief(pt2, surf2, tsc2, 0, 20.0, -W / 2 - 0.75, False) == 0.0


@pytest.mark.usefixtures("need_torcs")
def test_rough_road_shakes_the_driven_axle_as_in_torcs(ph):
    """michigan's asphalt has roughness 5 mm, wavelength 1 m. In TORCS's trace (car1-trb1 at 98 km/h
    in third, michigan__car1-trb1__100, 8-25 s) each message's rear right-minus-left spin jumps
    by 0.52 rad/s RMS from its neighbours' mean (second difference / 2, 20-22 ms apart), the
    front's by 0.008; on b-speedway's smooth asphalt the rear's by 0.010. madsim on the same road
    at the same speed (measured 0.50 and 0.006): the rear within 25 % of TORCS's, the front under
    0.03, and none without the roughness. b-speedway's road (concrete4) is not quite smooth: 0.5 mm
    at a 1 cm wavelength, which a 2 ms step samples at random phases. Since session 14 each wheel
    sits at its exact place on a curve (`suspension.wheel_at`), so the two rear wheels sample it
    at different phases, as TORCS's do: madsim's rear jumps by 0.022 there (0.006 before, when both
    wheels sat at the same phase). The bound there is 0.03, three times TORCS's figure, against
    michigan's 0.5."""
    from madsim.cars import load_car

    def jitter(track, smooth=False):
        w = ph.world_at(track, load_car("car1-trb1"), s=300.0, speed=27.2, gear=3)
        if smooth:
            w._surf[:, 2] = 0.0
        u = np.zeros((1, 5))
        u[0, 3] = 3
        rl, fl = [], []
        for tick in range(100):
            u[0, 0] = ph.hold_line(w)[0]
            u[0, 1] = float(np.clip((27.2 - w.vx[0]) * 0.36, 0.0, 1.0))
            w.step(u)
            spin = w.wheel_spin[0]
            rl.append(spin[2] - spin[3])
            fl.append(spin[0] - spin[1])
        d2 = lambda x: float(np.sqrt(np.mean(np.diff(np.array(x[40:]), 2) ** 2)) / 2)  # noqa: E731
        return d2(rl), d2(fl)

    michigan = load_track("michigan")
    rear, front = jitter(michigan)
    assert rear == pytest.approx(0.52, rel=0.25)
    assert front < 0.03
    assert jitter(michigan, smooth=True)[0] < 0.02
    assert jitter(load_track("b-speedway"))[0] < 0.03


@pytest.mark.usefixtures("need_torcs")
@pytest.mark.parametrize("smooth", [False, True])
def test_driven_wheels_at_rest_on_a_rough_road_take_up_the_drive_together(smooth):
    """The trace's start on michigan: 49 ticks held in neutral (full throttle, full brake), then
    the clutch takes up the drive in second and first. The road under the four wheels differs
    by millimetres, so the rear loads differ (2730 / 3120 N) and the limited-slip axle's speed
    ratio exceeds its clamp on the first hundredths of a rad/s. Its implicit (slow) step took
    the tyre torques of the unclamped spins and held the rear wheels at -5.5 / +5.6 rad/s with
    the car standing; with torques that follow the clamp they turn together (within 0.1 rad/s)
    and the car is as fast after 0.8 s as on the smooth road (within 1 %; 2.25 m/s against 2.35
    before)."""
    from madsim.cars import load_car
    from madsim.physics.world import World

    w = World(load_track("michigan"), [load_car("car1-trb1")], np.random.default_rng(0), contact=False)
    if smooth:
        w._surf[:, 2] = 0.0
    w.reset(grid={"rows": 1, "distance to start": 100.0})
    u = np.zeros((1, 5))
    for _ in range(49):
        u[0] = (0.0, 1.0, 1.0, 0.0, 0.0)
        w.step(u)
    split = []
    for tick in range(40):
        u[0] = (0.0, 1.0, 0.0, 2.0 if tick < 5 else 1.0, 0.0)
        w.step(u)
        split.append(w.wheel_spin[0][2] - w.wheel_spin[0][3])
    assert np.max(np.abs(split)) < 0.1
    assert w.vx[0] == pytest.approx(2.3454, rel=0.01)     # m/s: the smooth road's (rough: 2.3453)


def test_z_sensor_on_a_widening_right_side_without_border(tmp_path):
    """TORCS locates the car itself on the main road (the `z` sensor's RtTrackHeightL) and steps
    onto a right side with no border by the side's narrower width, while the side's plane starts
    at its start width: on a side that widens from w0 to w1 and continues a constant cross slope
    b, the car reads a ground u (w0 - w1) tan(b) higher u of the way along each piece (a slice
    of the segment, its widths w0, w1). A wheel (located on the side itself) reads the plane.
    Closed form on the first piece of a 100 m straight whose side widens from 4 m to 8 m."""
    bank = -5.0
    side = ('<section name="Right Side"><attnum name="start width" unit="m" val="4.0"/>'
            '<attnum name="end width" unit="m" val="8.0"/></section>')
    seg = segment("s", "str", lg=100.0, banking_start=bank, banking_end=bank,
                  profil_steps_length=100.0).replace("</section>", side + "</section>", 1)
    surfaces = _surface("tar", 0.0, 1.0) + _surface("sand", 0.0, 1.0)
    extra = ('<attstr name="surface" val="tar"/>'
             '<section name="Right Side"><attnum name="width" unit="m" val="4.0"/>'
             '<attstr name="surface" val="sand"/><attstr name="banking type" val="tangent"/></section>'
             '<section name="Left Side"><attnum name="width" unit="m" val="4.0"/>'
             '<attstr name="surface" val="sand"/></section>')
    p = tmp_path / "saw" / "saw.xml"
    p.parent.mkdir()
    p.write_text(track_xml([seg, segment("t", "lft", radius=100.0, arc=360.0 - 1e-6)], width=W,
                           surfaces=surfaces, name="saw", main_extra=extra), encoding="utf-8")
    pt, surf, tsc = piece_table(load_track(p))
    ln = pt[0, L.P_LEN]
    w0, w1 = 4.0, 4.0 + 4.0 * ln / 100.0
    assert ln < 100.0 and pt[0, L.P_BW_R] == 0.0 and pt[0, L.P_SW1_R] == pytest.approx(w1)
    for u in (0.1, 0.5, 0.9):
        n = -W / 2 - 1.0
        assert relief(pt, surf, tsc, 0, u * ln, n, True) == pytest.approx(
            u * (w0 - w1) * math.tan(math.radians(bank)), rel=1e-4)
        assert relief(pt, surf, tsc, 0, u * ln, n, False) == 0.0
