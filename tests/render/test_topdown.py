"""The pygame top-down view, headless (SDL dummy driver): cars where they are, HUD = state.

Cars sit on madsim-road's start straight (due east, s 0..350 m). With the north-up follow
camera a world offset (dx, dy) m from the followed car appears at (dx ppm, -dy ppm) px from
the screen centre (within half a pixel: the view snaps to the tile grid); with the rotating
camera the followed car points up and sits at (W/2, 0.65 H).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("pygame", reason="the renderer needs pygame: pip install 'madsim[render]'")

from madsim.physics import layout as L
from madsim.raster.track_raster import FIRST_SURFACE_LABEL, palette
from madsim.render.scene import CarPoses, Hud, Overlay, hud_lines
from madsim.render.topdown import HUD_BG, KIND_COLOURS, Camera, Renderer

S0 = 100.0
W, H = 400, 300
PPM = 6.0


@pytest.fixture(scope="module")
def follow(road):
    r = Renderer(road, size=(W, H), camera=Camera("follow", ppm=PPM))
    yield r
    r.close()


def colour_at(img, x_px, y_px):
    return tuple(int(v) for v in img[math.floor(y_px), math.floor(x_px)])


def test_frame_is_an_rgb_array_of_the_window_size(follow, make_world):
    w = make_world([(S0, 0.0, 0.0)])
    img = follow.frame(CarPoses.from_world(w))
    assert img.shape == (H, W, 3) and img.dtype == np.uint8


def test_cars_are_drawn_where_they_are_in_their_kind_colour(follow, make_world):
    w = make_world([(S0, 0.0, 0.0), (S0 + 12.0, 3.0, 0.0), (S0 - 15.0, -3.5, 0.0)])
    img = follow.frame(CarPoses.from_world(w), kinds=["learner", "traffic", "parked"])
    assert abs(follow.view.to_screen(w.x[0], w.y[0])[0] - W / 2) <= 0.5
    for k, kind in ((0, "learner"), (1, "traffic"), (2, "parked")):
        dx, dy = w.x[k] - w.x[0], w.y[k] - w.y[0]
        cx, cy = W / 2 + dx * PPM, H / 2 - dy * PPM
        # the body's centre and a point 1.5 m behind it (the windscreen is ahead of the centre)
        assert colour_at(img, cx, cy) == KIND_COLOURS[kind], kind
        assert colour_at(img, cx - 1.5 * PPM, cy) == KIND_COLOURS[kind], kind


def test_a_car_covers_its_real_size(road, make_world, sedan):
    # the camera follows car 1; car 0 is 20 m behind it, then moved far away
    r = Renderer(road, size=(W, H), camera=Camera("follow", ppm=PPM, car=1), ids=False)
    w = make_world([(S0, 0.0, 0.0), (S0 + 20.0, 0.0, 0.0)])
    poses = CarPoses.from_world(w)
    img = r.frame(poses, kinds=["traffic", "traffic"])
    poses.x[0] += 5000.0
    alone = r.frame(poses, kinds=["traffic", "traffic"])
    r.close()
    footprint = np.any(img != alone, axis=2)
    rows, cols = np.nonzero(footprint)
    # 4.78 m x 1.84 m at 6 px/m: 28.7 x 11.0 px, plus at most a pixel of anti-aliasing per side
    assert 28 <= np.ptp(cols) + 1 <= 31
    assert 11 <= np.ptp(rows) + 1 <= 13
    area = sedan.body_length * sedan.body_width * PPM ** 2
    ringed = (sedan.body_length * PPM + 2.5) * (sedan.body_width * PPM + 2.5)
    assert 0.9 * area <= footprint.sum() <= ringed


def test_road_around_the_cars_has_the_road_colour(road, follow, make_world):
    w = make_world([(S0, 0.0, 0.0)])
    img = follow.frame(CarPoses.from_world(w))
    road_rgb = tuple(int(v) for v in palette(road)[FIRST_SURFACE_LABEL + int(road.surface_at(S0, 0.0))])
    grass_rgb = tuple(int(v) for v in palette(road)[FIRST_SURFACE_LABEL + int(road.surface_at(S0, 10.0))])
    assert colour_at(img, W / 2 + 20 * PPM, H / 2 - 3 * PPM) == road_rgb     # 20 m ahead, 3 m left
    assert colour_at(img, W / 2 - 20 * PPM, H / 2 + 10 * PPM) == grass_rgb   # 20 m behind, 10 m right


def test_rotating_camera_puts_the_car_up_and_the_car_ahead_above_it(road, make_world):
    w = make_world([(S0, 0.0, 0.0), (S0 + 15.0, 0.0, 0.0)])
    r = Renderer(road, size=(W, H), camera=Camera("rotate", ppm=PPM))
    poses = CarPoses.from_world(w)
    img = r.frame(poses, kinds=["learner", "traffic"])
    ax, ay = W / 2, 0.65 * H
    assert colour_at(img, ax, ay) == KIND_COLOURS["learner"]
    assert colour_at(img, ax, ay - 15 * PPM) == KIND_COLOURS["traffic"]
    # turned by 30 degrees the world turns, the cars stay in the same screen places
    turned = CarPoses(poses.x, poses.y, poses.yaw + math.radians(30), poses.length, poses.width)
    d = 15.0
    turned.x[1] = poses.x[0] + d * math.cos(math.radians(30))
    turned.y[1] = poses.y[0] + d * math.sin(math.radians(30))
    img2 = r.frame(turned, kinds=["learner", "traffic"])
    assert colour_at(img2, ax, ay - 15 * PPM) == KIND_COLOURS["traffic"]
    r.close()


def test_track_camera_shows_the_whole_track_with_car_markers(road, make_world):
    w = make_world([(S0, 0.0, 0.0), (1500.0, 0.0, 0.0)])
    r = Renderer(road, size=(W, H), camera="track")
    img = r.frame(CarPoses.from_world(w), kinds=["learner", "traffic"])
    xmin, ymin, xmax, ymax = road.bounding_box
    for x, y in ((xmin, ymin), (xmax, ymax)):
        sx, sy = r.view.to_screen(x, y)
        assert 0 <= sx < W and 0 <= sy < H
    for k, kind in ((0, "learner"), (1, "traffic")):
        sx, sy = r.view.to_screen(w.x[k], w.y[k])
        assert colour_at(img, sx, sy) == KIND_COLOURS[kind]
    r.close()


def test_hud_shows_the_state_of_the_highlighted_car(follow, make_world):
    w = make_world([(S0, 0.0, 20.0), (S0 + 30.0, 0.0, 30.0)])
    u = np.zeros((2, 5))
    u[:, 1], u[:, 3] = 1.0, 2.0
    for _ in range(50):
        w.step(u)
    st = w.state
    k = 0
    img = follow.frame(CarPoses.from_world(w), highlight=k, hud=Hud.from_world(w, k, "car 0"))
    expected = ["car 0",
                f"{st[k, L.S_VX] * 3.6:.0f} km/h",
                f"gear 2  {st[k, L.S_WE] * 60 / (2 * math.pi):.0f} rpm",
                f"lap {int(st[k, L.S_LAPS])}  0:{st[k, L.S_CURLAP]:05.2f}",
                f"pos 2/2  t {st[k, L.S_TIME]:.1f} s"]
    assert follow.last_hud == expected == hud_lines(Hud.from_world(w, k, "car 0"))
    # the HUD's pixels are exactly these lines, drawn on the panel
    rect = follow.hud_rect
    pg = follow.pg
    panel = pg.Surface((rect.w, rect.h))
    panel.fill(HUD_BG)
    y = 6
    for line in expected:
        t = follow.hud_text(line)
        panel.blit(t, (6, y))
        y += t.get_height()
    want = pg.surfarray.array3d(panel).transpose(1, 0, 2)
    np.testing.assert_array_equal(img[rect.y:rect.y + rect.h, rect.x:rect.x + rect.w], want)


def test_hud_text_formats():
    hud = Hud(speed_kmh=123.4, gear=-1, rpm=5012.0, lap=3, lap_time_s=75.456, position=1, n_cars=4,
              time_s=300.04)
    assert hud_lines(hud) == ["123 km/h", "gear R  5012 rpm", "lap 3  1:15.46", "pos 1/4  t 300.0 s"]
    assert hud_lines(Hud(0.0, 0, 800.0, None, -0.2, 2, 2))[1:3] == ["gear N  800 rpm", "lap -  -0.20"]


def test_rangefinder_overlay_reaches_the_road_edge(follow, make_world):
    w = make_world([(S0, 0.0, 0.0)])
    poses = CarPoses.from_world(w)
    plain = follow.frame(poses)
    # one ray straight to the left (SCR -90 deg) of 6 m: ends at the left road edge, 36 px up
    ov = Overlay(np.array([-90.0]), np.array([6.0]), None)
    img = follow.frame(poses, highlight=0, overlay=ov)
    changed = np.any(img != plain, axis=2)
    column = changed[:, W // 2 - 1:W // 2 + 1].any(axis=1)
    rows = np.flatnonzero(column)
    assert rows.min() <= H / 2 - 6 * PPM + 1 and rows.min() >= H / 2 - 6 * PPM - 2


def test_window_shows_the_last_frame(road, make_world):
    w = make_world([(S0, 0.0, 0.0)])
    r = Renderer(road, size=(W, H), camera="follow")
    img = r.frame(CarPoses.from_world(w))
    assert r.show() is True
    shown = r.pg.surfarray.array3d(r.pg.display.get_surface()).transpose(1, 0, 2)
    np.testing.assert_array_equal(shown, img)
    r.close()
    assert r.show() is False


def test_bad_arguments_are_refused(road, follow, make_world):
    w = make_world([(S0, 0.0, 0.0)])
    with pytest.raises(ValueError, match="camera mode"):
        Camera("chase")
    with pytest.raises(ValueError, match="kind"):
        follow.frame(CarPoses.from_world(w), kinds=["bus"])
    with pytest.raises(ValueError, match="one entry per car"):
        follow.frame(CarPoses.from_world(w), ids=["a", "b"])
    with pytest.raises(IndexError, match="camera car"):
        follow.frame(CarPoses.from_world(w), highlight=4)


def test_pit_walls_are_drawn_solid_in_the_barrier_colour(tmp_path, sedan):
    """A straight with a 1 m wall-style left border and a side beyond it (a pit wall), then the
    same border in style `plan`: the follow camera shows the barrier colour across the pit
    wall's strip and road-side colours on the plain border at the same offset."""
    from trackfiles import segment, track_xml

    from madsim.physics.world import World
    from madsim.render.topdown import BARRIER_RGB
    from madsim.tracks import load_track

    def seg(name, style):
        sub = (f'<section name="Left Border"><attnum name="width" val="1"/>'
               f'<attnum name="height" val="1"/><attstr name="style" val="{style}"/></section>'
               f'<section name="Left Side"><attnum name="start width" val="5"/>'
               f'<attnum name="end width" val="5"/></section>')
        text = segment(name, "str", lg=200.0)
        return text[: -len("</section>")] + sub + "</section>"

    path = tmp_path / "pit.xml"
    path.write_text(track_xml([seg("a", "wall"), seg("b", "plan")], width=10.0, name="pit"),
                    encoding="utf-8")
    track = load_track(path)
    assert track.pit_wall_quads()[0].shape[0] > 0
    r = Renderer(track, size=(W, H), camera=Camera("follow", ppm=PPM), ids=False)
    try:
        for s, want_wall in ((100.0, True), (300.0, False)):
            w = World(track, [sedan], np.random.default_rng(0), contact=False)
            w.reset(np.array([[s, 0.0, 0.0]]))
            img = r.frame(CarPoses.from_world(w))
            for n in (5.3, 5.5, 5.7):          # inside the border strip, 5-6 m left of centre
                x, y, _, _ = (float(v) for v in track.pose(s, n))
                px, py = r.view.to_screen(x, y)
                got = colour_at(img, px, py)
                assert (got == BARRIER_RGB) == want_wall, (s, n, got)
    finally:
        r.close()
