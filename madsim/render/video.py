"""Frames to files: `VideoWriter` (MP4 through imageio-ffmpeg, GIF through Pillow) and
`render_trace`, which replays a `madsim serve --log-csv` trace with the top-down renderer."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from madsim.render.scene import CarPoses, Hud
from madsim.render.topdown import Camera, Renderer
from madsim.render.trace import check_track, read_trace

GIF_FPS = 10.0          # GIFs are for short clips: fewer, smaller frames
VIDEO_SUFFIXES = (".mp4", ".gif", ".webm", ".mkv", ".avi", ".mov")


class VideoWriter:
    """Append (H, W, 3) uint8 frames of one size, then `close()`. MP4 (and the other ffmpeg
    containers) are written as they come (imageio-ffmpeg, H.264, yuv420p; odd sizes are padded
    by one pixel); a GIF keeps its frames (palette images) in memory until `close()`."""

    def __init__(self, path: str | os.PathLike, fps: float = 50.0):
        self.path = Path(path)
        suffix = self.path.suffix.lower()
        if suffix not in VIDEO_SUFFIXES:
            raise ValueError(f"{self.path}: unknown video type {suffix!r}; use one of {VIDEO_SUFFIXES}")
        if not fps > 0:
            raise ValueError(f"fps must be > 0, got {fps}")
        self.fps = float(fps)
        self.gif = suffix == ".gif"
        self.frames = 0
        self._size = None
        self._gif_frames: list = []
        self._ffmpeg = None

    def append(self, frame: np.ndarray) -> None:
        frame = np.asarray(frame)
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
            raise ValueError(f"frames must be (H, W, 3) uint8, got {frame.shape} {frame.dtype}")
        if self._size is None:
            self._size = frame.shape[:2]
            if not self.gif:
                self._open_ffmpeg()
        elif frame.shape[:2] != self._size:
            raise ValueError(f"frame size changed from {self._size} to {frame.shape[:2]}")
        if self.gif:
            from PIL import Image

            self._gif_frames.append(Image.fromarray(frame).quantize(colors=255, method=Image.Quantize.FASTOCTREE))
        else:
            h, w = self._size
            ph, pw = h + h % 2, w + w % 2
            if (ph, pw) != (h, w):
                frame = np.pad(frame, ((0, ph - h), (0, pw - w), (0, 0)), mode="edge")
            self._ffmpeg.send(np.ascontiguousarray(frame).tobytes())
        self.frames += 1

    def _open_ffmpeg(self) -> None:
        try:
            import imageio_ffmpeg
        except ModuleNotFoundError:
            raise ModuleNotFoundError(f"{self.path}: writing {self.path.suffix} needs imageio-ffmpeg: "
                                      "pip install 'madsim[render]' (or write a .gif)") from None
        h, w = self._size
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._ffmpeg = imageio_ffmpeg.write_frames(
            str(self.path), (w + w % 2, h + h % 2), fps=self.fps, codec="libx264", pix_fmt_in="rgb24",
            pix_fmt_out="yuv420p", macro_block_size=2, ffmpeg_log_level="error", quality=7)
        self._ffmpeg.send(None)

    def close(self) -> None:
        """Finish the file (nothing is written for zero frames: ValueError)."""
        if self.frames == 0:
            raise ValueError(f"{self.path}: no frames to write")
        if self.gif:
            if self._gif_frames:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                first, rest = self._gif_frames[0], self._gif_frames[1:]
                first.save(self.path, save_all=True, append_images=rest, loop=0,
                           duration=max(20, round(1000.0 / self.fps)), optimize=False)
                self._gif_frames = []
        elif self._ffmpeg is not None:
            self._ffmpeg.close()
            self._ffmpeg = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if exc[0] is None:
            self.close()
        elif self._ffmpeg is not None:
            self._ffmpeg.close()


def write_video(frames, path: str | os.PathLike, fps: float = 50.0) -> int:
    """Write an iterable of (H, W, 3) uint8 frames; returns the number written."""
    with VideoWriter(path, fps) as w:
        for f in frames:
            w.append(f)
    return w.frames


def render_trace(csv_path: str | os.PathLike, out_path: str | os.PathLike, *,
                 track: str = "madsim-road", cars: list[str] | None = None, car: int = 0,
                 camera: Camera | str = "follow", size: tuple[int, int] = (800, 600),
                 fps: float | None = None, every: int | None = None, progress=None, stop=None) -> int:
    """Replay a serve trace into a video; returns the number of frames.

    track: the track it was recorded on (the trace does not say; checked against trackPos);
    cars: car names per row for their body sizes (repeating the last; default madsim-sedan);
    car: the row the camera follows and the HUD shows; every: draw every k-th tick (default
    1 for videos, 50 / GIF_FPS for GIFs); fps: playback rate (default real time, 50 / every);
    progress: a callable(done, total) or None; stop: anything whose truth ends the replay
    early (e.g. a `madsim.interrupts.StopRequest`): the frames so far make a playable file.
    """
    from madsim.cars import load_car
    from madsim.tracks import load_track

    trace = read_trace(csv_path)
    tr = load_track(track)
    check_track(trace, tr)
    n = trace.n_cars
    if not 0 <= car < n:
        raise ValueError(f"car {car} is not in the trace (cars 0..{n - 1})")
    names = list(cars) if cars else ["madsim-sedan"]
    specs = {name: load_car(name) for name in set(names)}
    names = (names + [names[-1]] * n)[:n]
    length = np.array([specs[m].body_length for m in names])
    width = np.array([specs[m].body_width for m in names])
    gif = Path(out_path).suffix.lower() == ".gif"
    if every is None:
        every = max(1, round(50.0 / GIF_FPS)) if gif else 1
    every = max(1, int(every))
    fps = fps if fps is not None else 50.0 / every
    renderer = Renderer(tr, size=size, camera=camera)
    pos = trace["racePos"] if "racePos" in trace.columns else trace.race_positions(tr.length)
    ids = [f"{i}:{m}" if cars else str(i) for i, m in enumerate(names)]
    kinds = ["learner"] * n
    steps = range(0, trace.n_ticks, every)
    with VideoWriter(out_path, fps) as writer:
        for done, t in enumerate(steps):
            if stop:
                break
            poses = CarPoses(trace["x"][t], trace["y"][t], trace["yaw"][t], length, width)
            hud = Hud(speed_kmh=float(trace["speedX"][t, car]), gear=int(trace["gear"][t, car]),
                      rpm=float(trace["rpm"][t, car]) / 10.0 * 60.0 / (2 * np.pi),
                      lap=int(trace["laps"][t, car]), lap_time_s=float(trace["curLapTime"][t, car]),
                      position=int(pos[t, car]), n_cars=n, time_s=float(trace["time"][t, car]),
                      label=f"car {ids[car]}")
            writer.append(renderer.frame(poses, ids, kinds, highlight=car, hud=hud))
            if progress is not None:
                progress(done + 1, len(steps))
    renderer.close()
    return writer.frames


__all__ = ["GIF_FPS", "VideoWriter", "render_trace", "write_video"]
