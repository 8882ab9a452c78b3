"""Egocentric top-down image observations (TORCS vision mode's 64x64 image, seen from above).

`ImageObservation(track, size=64, metres=48)` paints the track once into a label raster
(`TrackRaster`) and then, per frame, samples it rotated into the car's frame (the car points
up, `ahead` of the image height in front of it) and draws every car as a box of its real size:
the observing car in `EGO_RGB`, the others in `OTHER_RGB`. No pygame, no window: one compiled
kernel per frame (`madsim.raster.kernels.egocentric_frame`).

Poses come from a World (`frame(world, k)`), its state array (`frame(state, k)` with car
sizes from `car_sizes`), plain arrays (`frame_from_poses`), or an SCR SensorFrame
(`from_sensors`: distFromStart, trackPos and angle locate each car on the track, so it also
works behind the UDP backend). `ImageObservationBuilder` has the ObservationBuilder interface
the envs use (`space`, `from_frame(frame, k)`) and keeps one raster per track.
"""

from __future__ import annotations

import numpy as np

from madsim.physics import layout as L
from madsim.raster import kernels
from madsim.raster.poses import poses_from_sensors
from madsim.raster.track_raster import BACKGROUND, TrackRaster
from madsim.tracks import Track

EGO_RGB = (230, 40, 40)
OTHER_RGB = (40, 110, 235)
DEFAULT_CAR_SIZE_M = (4.78, 1.84)   # madsim-sedan, length x width
SAMPLES_PER_SIDE = 2                 # 2 x 2 samples per pixel: smooth edges at 64 x 64


def _space(h: int, w: int):
    import gymnasium

    return gymnasium.spaces.Box(0, 255, shape=(h, w, 3), dtype=np.uint8)


class ImageObservation:
    """Egocentric RGB images of one track.

    size: image side in pixels (int) or (height, width); metres: width of the view on the
    ground, m (height follows the pixel aspect); ahead: share of the image height in front of
    the car's centre (0.5 = centred, 0.75 = looks ahead); car_sizes: (N, 2) length, width in m
    used when `frame` gets a bare state array (default: madsim-sedan's size for every car);
    ppm: resolution of the pre-rendered raster, pixels per metre (default: 2 samples per
    image sample).
    """

    def __init__(self, track: Track, size: int | tuple[int, int] = 64, metres: float = 48.0, *,
                 ahead: float = 0.75, car_sizes=None, ppm: float | None = None,
                 raster: TrackRaster | None = None):
        h, w = (size, size) if np.isscalar(size) else (int(size[0]), int(size[1]))
        if h < 4 or w < 4:
            raise ValueError(f"image size must be at least 4 x 4 pixels, got {h} x {w}")
        if not metres > 0:
            raise ValueError(f"metres must be > 0, got {metres}")
        if not 0.0 < ahead <= 1.0:
            raise ValueError(f"ahead must be in (0, 1], got {ahead}")
        self.track = track
        self.shape = (h, w, 3)
        self.metres = float(metres)
        self.m_per_px = float(metres) / w
        self.row0 = h * float(ahead)
        self.col0 = w / 2.0
        if raster is None:
            ppm = ppm if ppm is not None else 2.0 * SAMPLES_PER_SIDE / self.m_per_px
            raster = TrackRaster(track, ppm)
        self.raster = raster
        self.space = _space(h, w)
        self.car_sizes = None if car_sizes is None else np.asarray(car_sizes, dtype=np.float64)
        self._ego = np.array(EGO_RGB, dtype=np.float64)
        self._other = np.array(OTHER_RGB, dtype=np.float64)

    def frame_from_poses(self, x, y, yaw, length, width, car: int,
                         out: np.ndarray | None = None) -> np.ndarray:
        """(H, W, 3) uint8 image around car `car` from per-car arrays (N,): x, y (m), yaw
        (rad), length, width (m)."""
        xs = np.ascontiguousarray(x, dtype=np.float64)
        ys = np.ascontiguousarray(y, dtype=np.float64)
        yaws = np.ascontiguousarray(yaw, dtype=np.float64)
        hl = np.ascontiguousarray(np.broadcast_to(length, xs.shape), dtype=np.float64) * 0.5
        hw = np.ascontiguousarray(np.broadcast_to(width, xs.shape), dtype=np.float64) * 0.5
        car = int(car)
        if not 0 <= car < xs.shape[0]:
            raise IndexError(f"car index {car} out of range for {xs.shape[0]} cars")
        if out is None:
            out = np.empty(self.shape, dtype=np.uint8)
        r = self.raster
        kernels.egocentric_frame(out, r.labels, r.palette, r.x0, r.y_top, r.ppm, BACKGROUND,
                                 xs[car], ys[car], yaws[car], self.m_per_px, self.row0, self.col0,
                                 SAMPLES_PER_SIDE, xs, ys, yaws, hl, hw, car, self._ego, self._other)
        return out

    def frame(self, state, car: int, out: np.ndarray | None = None) -> np.ndarray:
        """(H, W, 3) uint8 image around car row `car` of a World or of a World state array
        (N, len(STATE_COLUMNS)); car sizes from the World, else `car_sizes`."""
        cars = getattr(state, "cars", None)
        st = getattr(state, "state", state)
        st = np.asarray(st)
        if st.ndim != 2 or st.shape[1] != L.N_STATE:
            raise ValueError(f"state must be a World or an (N, {L.N_STATE}) state array, "
                             f"got shape {st.shape}")
        if cars is not None:
            length = np.array([c.body_length for c in cars])
            width = np.array([c.body_width for c in cars])
        else:
            length, width = self._sizes(st.shape[0])
        return self.frame_from_poses(st[:, L.S_X], st[:, L.S_Y], st[:, L.S_YAW], length, width,
                                     car, out)

    def from_sensors(self, frame, car: int, out: np.ndarray | None = None, *,
                     length=None, width=None) -> np.ndarray:
        """(H, W, 3) uint8 image around row `car` of an SCR SensorFrame (poses rebuilt from
        distFromStart, trackPos, angle); length, width (N,) m default to `car_sizes`."""
        x, y, yaw = poses_from_sensors(self.track, frame)
        if length is None or width is None:
            length, width = self._sizes(x.shape[0])
        return self.frame_from_poses(x, y, yaw, length, width, car, out)

    def _sizes(self, n: int):
        if self.car_sizes is None:
            return np.full(n, DEFAULT_CAR_SIZE_M[0]), np.full(n, DEFAULT_CAR_SIZE_M[1])
        if self.car_sizes.shape != (n, 2):
            raise ValueError(f"car_sizes has shape {self.car_sizes.shape}, expected ({n}, 2)")
        return self.car_sizes[:, 0], self.car_sizes[:, 1]


class ImageObservationBuilder:
    """The env-facing side: an ObservationBuilder-like object for image observations.

    `space`: Box uint8 (H, W, 3); `reset(track, car_specs)` at every episode start (keeps one
    ImageObservation per track, so a multi-track scenario paints each track once);
    `from_frame(frame, k)` the image of row k of the episode's SensorFrames.
    """

    mode = "Image"

    def __init__(self, size: int | tuple[int, int] = 64, metres: float = 48.0, *,
                 ahead: float = 0.75):
        h, w = (size, size) if np.isscalar(size) else (int(size[0]), int(size[1]))
        self.size, self.metres, self.ahead = (h, w), float(metres), float(ahead)
        self.space = _space(h, w)
        self._per_track: dict[int, ImageObservation] = {}
        self._obs: ImageObservation | None = None
        self._length = self._width = None

    def reset(self, track: Track, car_specs) -> None:
        """Select the episode's track and car sizes (CarSpecs in World row order)."""
        obs = self._per_track.get(id(track))
        if obs is None or obs.track is not track:
            obs = ImageObservation(track, self.size, self.metres, ahead=self.ahead)
            self._per_track[id(track)] = obs
        self._obs = obs
        self._length = np.array([c.body_length for c in car_specs], dtype=np.float64)
        self._width = np.array([c.body_width for c in car_specs], dtype=np.float64)

    def from_frame(self, frame, k: int) -> np.ndarray:
        if self._obs is None:
            raise RuntimeError("ImageObservationBuilder.reset(track, cars) must come first")
        return self._obs.from_sensors(frame, k, length=self._length, width=self._width)
