"""Egocentric image observations: what lies where in the picture.

Geometry used (madsim-road, from its XML): the first 350 m run due east (heading 0) with a
12 m road, a 1 m kerb and a 6 m grass side on both hands, the barrier 13 m from the centre
line. With the defaults (64 x 64 px over 48 m: 0.75 m per pixel, the car's centre at row 48,
column 32), pixel (i, j) covers forward [(48 - i - 1) 0.75, (48 - i) 0.75] m and left
[(31 - j) 0.75, (32 - j) 0.75] m of the car's centre. Pixels tested lie wholly inside one
material (all 2 x 2 samples agree), so their colour is exact.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from madsim.physics.sensors import SensorSuite
from madsim.agents.image_obs import (
    EGO_RGB,
    OTHER_RGB,
    ImageObservation,
    ImageObservationBuilder,
)
from madsim.raster.poses import poses_from_sensors
from madsim.raster.track_raster import (
    BACKGROUND,
    FIRST_SURFACE_LABEL,
    TrackRaster,
    palette,
    surface_colour,
)

S0 = 100.0   # on the start straight


@pytest.fixture(scope="module")
def obs(road):
    return ImageObservation(road)


def material_rgb(track, s, n):
    return tuple(palette(track)[FIRST_SURFACE_LABEL + int(track.surface_at(s, n))])


def test_space_is_uint8_box_of_the_configured_size(road, obs):
    assert obs.space.shape == (64, 64, 3) and obs.space.dtype == np.uint8
    wide = ImageObservation(road, (32, 96), 60.0, raster=obs.raster)
    assert wide.space.shape == (32, 96, 3)
    assert wide.m_per_px == pytest.approx(60.0 / 96)


def test_road_under_and_beside_the_car_grass_then_background_outside(road, obs, make_world):
    w = make_world([(S0, 0.0, 0.0)])
    img = obs.frame(w, 0)
    road_rgb = material_rgb(road, S0, 0.0)
    grass_rgb = material_rgb(road, S0, 10.0)
    assert road_rgb != grass_rgb
    # 21 m ahead, 3 m either side: road; 10 m either side: grass; 20 m: beyond the barrier
    for j, rgb in ((27, road_rgb), (36, road_rgb), (18, grass_rgb), (45, grass_rgb)):
        assert tuple(img[20, j]) == rgb, j
    bg = tuple(palette(road)[BACKGROUND])
    assert tuple(img[20, 5]) == bg and tuple(img[20, 58]) == bg
    # the car itself, at its centre pixel, in the ego colour
    assert tuple(img[47, 31]) == EGO_RGB and tuple(img[48, 32]) == EGO_RGB


def test_other_car_appears_ahead_and_left_where_it_is(road, obs, make_world):
    # car 1: 8 m ahead, 3 m left -> rows 35..39 and columns 27..28 lie wholly inside it
    w = make_world([(S0, 0.0, 0.0), (S0 + 8.0, 3.0, 0.0)])
    img = obs.frame(w, 0)
    for i in range(35, 40):
        for j in (27, 28):
            assert tuple(img[i, j]) == OTHER_RGB, (i, j)
    assert tuple(img[37, 25]) == material_rgb(road, S0 + 8.0, 4.9)   # road just left of it
    # seen from car 1 the roles swap: car 0 is 8 m behind and 3 m to the right
    img1 = obs.frame(w, 1)
    assert tuple(img1[48, 32]) == EGO_RGB
    for i in range(56, 61):
        for j in (35, 36):
            assert tuple(img1[i, j]) == OTHER_RGB, (i, j)


def test_a_car_across_the_road_is_wide_not_long(obs, make_world):
    w = make_world([(S0, 0.0, 0.0)])
    x, y, yaw = w.x[0], w.y[0], w.yaw[0]
    length, width = 4.78, 1.84
    # second car 8 m behind, turned 90 degrees: across the image
    xs, ys, yaws = [x, x - 8.0], [y, y], [yaw, yaw + math.pi / 2]
    alone = obs.frame_from_poses(xs[:1], ys[:1], yaws[:1], length, width, 0)
    both = obs.frame_from_poses(xs, ys, yaws, length, width, 0)
    rows, cols = np.nonzero(np.any(both != alone, axis=2))
    assert rows.size
    # extents in pixels: width 1.84 / 0.75 = 2.5 rows, length 4.78 / 0.75 = 6.4 columns (+1 partial)
    assert 2 <= np.ptp(rows) + 1 <= 4
    assert 6 <= np.ptp(cols) + 1 <= 8
    assert abs(rows.mean() - (48 + 8 / 0.75 - 0.5)) < 0.6 and abs(cols.mean() - 31.5) < 0.6


def test_the_picture_turns_with_the_car(road, obs, make_world):
    """Pointing north (across the road), the road runs left-right through the car."""
    w = make_world([(S0, 0.0, 0.0)])
    x, y = w.x[0], w.y[0]
    img = obs.frame_from_poses([x], [y], [math.pi / 2], 4.78, 1.84, 0)
    road_rgb = material_rgb(road, S0, 0.0)
    grass_rgb = material_rgb(road, S0, 10.0)
    # 3 m ahead (north) of the centre, 20 m west / east: road; 10 m north / south: grass
    assert tuple(img[43, 5]) == road_rgb and tuple(img[43, 58]) == road_rgb
    assert tuple(img[34, 5]) == grass_rgb and tuple(img[61, 5]) == grass_rgb


def test_sensors_rebuild_the_same_image(road, obs, make_world):
    w = make_world([(S0, 1.5, 5.0), (S0 + 20.0, -2.0, 5.0), (2900.0, 0.5, 5.0)])
    u = np.zeros((3, 5))
    u[:, 0], u[:, 1], u[:, 3] = 0.1, 0.5, 1.0
    for _ in range(40):
        w.step(u)
    frame = SensorSuite(w).frame()
    x, y, yaw = poses_from_sensors(road, frame)
    np.testing.assert_allclose(x, w.x, atol=2e-3)    # m
    np.testing.assert_allclose(y, w.y, atol=2e-3)
    np.testing.assert_allclose(np.angle(np.exp(1j * (yaw - w.yaw))), 0.0, atol=1e-6)
    for k in range(3):
        a = obs.frame(w, k).astype(int)
        b = obs.from_sensors(frame, k).astype(int)
        assert np.mean(np.any(a != b, axis=2)) < 0.01 and np.max(np.abs(a - b)) <= 64


def test_builder_follows_the_episode_track_and_cars(road, sedan, make_world):
    b = ImageObservationBuilder(size=32, metres=20.0)     # 0.625 m per pixel
    assert b.space.shape == (32, 32, 3)
    with pytest.raises(RuntimeError, match="reset"):
        b.from_frame(None, 0)
    w = make_world([(S0, 0.0, 0.0), (S0 + 8.0, 0.0, 0.0)])
    b.reset(road, [sedan, sedan])
    img = b.from_frame(SensorSuite(w).frame(), 0)
    assert img.shape == (32, 32, 3) and b.space.contains(img)
    assert tuple(img[23, 15]) == EGO_RGB          # forward [0, 0.625] m, left [0, 0.625] m
    assert tuple(img[11, 15]) == OTHER_RGB        # forward [7.5, 8.125] m


def test_bad_arguments_are_refused(road, obs, make_world):
    with pytest.raises(ValueError, match="size"):
        ImageObservation(road, 2, raster=obs.raster)
    with pytest.raises(ValueError, match="metres"):
        ImageObservation(road, 64, 0.0, raster=obs.raster)
    with pytest.raises(ValueError, match="ahead"):
        ImageObservation(road, 64, ahead=1.5, raster=obs.raster)
    w = make_world([(S0, 0.0, 0.0)])
    with pytest.raises(IndexError, match="car index 3"):
        obs.frame(w, 3)
    with pytest.raises(ValueError, match="state"):
        obs.frame(np.zeros((2, 3)), 0)


def test_raster_paints_road_kerb_grass_and_background(road):
    r = TrackRaster(road, 2.0)
    x, y, _, _ = road.pose([S0, S0, S0, S0], [0.0, 6.5, 10.0, 20.0])
    labels = r.label_at(x, y)
    names = [road.surfaces[k - FIRST_SURFACE_LABEL].name if k >= FIRST_SURFACE_LABEL else None
             for k in labels[:3]]
    assert names == [road.surfaces[int(road.surface_at(S0, n))].name for n in (0.0, 6.5, 10.0)]
    assert labels[3] == BACKGROUND
    assert surface_colour("curb-5cm-r") == surface_colour("kerb")
    assert surface_colour("grass3") != surface_colour("asphalt2")


def test_compiled_track_poses_equal_track_pose(road):
    from madsim.raster.kernels import track_poses

    rng = np.random.default_rng(0)
    s = rng.uniform(-100.0, 2 * road.length, 2000)      # wraps like Track.pose
    n = rng.uniform(-8.0, 8.0, 2000)
    x, y, _, h = road.pose(s, n)
    ox, oy, oh = np.empty(2000), np.empty(2000), np.empty(2000)
    track_poses(road.geo, road.length, s, n, ox, oy, oh)
    np.testing.assert_allclose(ox, x, atol=1e-9)
    np.testing.assert_allclose(oy, y, atol=1e-9)
    np.testing.assert_allclose(np.angle(np.exp(1j * (oh - h))), 0.0, atol=1e-12)
