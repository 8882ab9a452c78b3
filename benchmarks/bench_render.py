"""Rendering speed: image observations and full top-down frames.

Run: python benchmarks/bench_render.py [TRACK] [--frames 5000] [--repeats 5]

One line per figure, best of --repeats runs after a warm-up (kernels compiled, tiles painted):
- `image_obs SxS`: ImageObservation.frame of one car among 10, frames/s (target >= 2,000 at
  64 x 64, issue 7), also through `from_sensors` (poses rebuilt from SCR sensors);
- `raster`: painting the track once (ImageObservation construction), ms;
- `topdown CAMERA`: Renderer.frame at 800 x 600 with 10 cars, ids and the HUD, ms per frame;
- `mp4 encode`: VideoWriter.append of 800 x 600 frames (H.264), ms per frame (if installed).
"""

from __future__ import annotations

import argparse
import importlib.util
import tempfile
import time
from pathlib import Path

import numpy as np

from madsim.cars import load_car
from madsim.physics.sensors import SensorSuite
from madsim.physics.world import World
from madsim.agents.image_obs import ImageObservation
from madsim.tracks import load_track


def best(fn, n: int, repeats: int) -> float:
    """Best seconds per call over `repeats` runs of n calls."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        times.append((time.perf_counter() - t0) / n)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("track", nargs="?", default="madsim-road")
    ap.add_argument("--frames", type=int, default=5000)
    ap.add_argument("--repeats", type=int, default=5)
    a = ap.parse_args()
    track = load_track(a.track)
    world = World(track, [load_car("madsim-sedan")] * 10, np.random.default_rng(0), contact=False)
    world.reset()
    u = np.zeros((10, 5))
    u[:, 1], u[:, 3] = 0.5, 1.0
    for _ in range(200):
        world.step(u)
    frame = SensorSuite(world).frame()

    t0 = time.perf_counter()
    ImageObservation(track)
    ImageObservation(track)
    print(f"raster ({a.track}, default 64x64 obs): {(time.perf_counter() - t0) / 2 * 1e3:.1f} ms to paint once")
    for size in (64, 84, 128):
        obs = ImageObservation(track, size)
        out = np.empty(obs.shape, np.uint8)
        dt = best(lambda obs=obs, out=out: obs.frame(world, 9, out), a.frames, a.repeats)
        ds = best(lambda obs=obs, out=out: obs.from_sensors(frame, 9, out), a.frames, a.repeats)
        print(f"image_obs {size}x{size}: {1 / dt:,.0f} frames/s from the World, "
              f"{1 / ds:,.0f} frames/s from SCR sensors")

    if importlib.util.find_spec("pygame") is None:
        print("topdown: skipped (pygame not installed)")
        return
    from madsim.render.scene import CarPoses, Hud
    from madsim.render.topdown import Camera, Renderer

    kinds = ["traffic"] * 8 + ["parked", "learner"]
    frames = max(20, a.frames // 100)
    last = None
    for mode in ("track", "follow", "rotate"):
        r = Renderer(track, size=(800, 600), camera=Camera(mode))

        def draw(r=r):
            return r.frame(CarPoses.from_world(world), kinds=kinds, highlight=9,
                           hud=Hud.from_world(world, 9, "car 9"))
        t0 = time.perf_counter()
        draw()
        first = time.perf_counter() - t0
        dt = best(draw, frames, a.repeats)
        print(f"topdown {mode} 800x600: {dt * 1e3:.2f} ms per frame ({1 / dt:,.0f} frames/s); "
              f"first frame (tiles painted) {first * 1e3:.0f} ms")
        last = draw()
        r.close()
    if importlib.util.find_spec("imageio_ffmpeg") is not None:
        from madsim.render.video import VideoWriter

        with tempfile.TemporaryDirectory() as tmp:
            w = VideoWriter(Path(tmp) / "b.mp4", 50)
            dt = best(lambda: w.append(last), frames, 1)
            w.close()
        print(f"mp4 encode 800x600: {dt * 1e3:.2f} ms per frame")


if __name__ == "__main__":
    main()
