"""`render_mode` for the envs, kept out of them: an `EnvView` draws a `MadrasCore`'s cars.

The envs hold one `EnvView` when a render mode is asked for and call `view.render(core)`:
"rgb_array" returns the frame, "human" shows it in a window at the env's real-time rate
(`fps(core)`: 50 ticks a second / ticks per step, times `speedup`) and returns None. Poses
come from the local World when there is one, else from the SCR sensors (UDP backend), so
rendering never touches the observation path.
"""

from __future__ import annotations

import numpy as np

from madsim.net.protocol import SNAKEOIL_ANGLES_DEG
from madsim.raster.poses import poses_from_sensors
from madsim.render.scene import CarPoses, Hud, Overlay, kinds_of_plan
from madsim.render.topdown import Camera, Renderer

RENDER_MODES = ("human", "rgb_array")
TICKS_PER_SECOND = 50.0


class EnvView:
    """Frames of an env's episode. render_mode: 'human' or 'rgb_array'; size (W, H) px;
    camera: Camera or mode name ('follow' by default: north up on the first live learner);
    speedup: 'human' plays this many times faster than real time (<= 0: as fast as it can);
    overlay: draw the followed car's rangefinders and opponent sectors."""

    def __init__(self, render_mode: str, *, size: tuple[int, int] = (800, 600),
                 camera: Camera | str = "follow", speedup: float = 1.0, overlay: bool = False):
        if render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode must be one of {RENDER_MODES} or None, got {render_mode!r}")
        self.render_mode = render_mode
        self.size = size
        self.camera = camera if isinstance(camera, Camera) else Camera(mode=camera)
        self.speedup = float(speedup)
        self.overlay = bool(overlay)
        self.renderer: Renderer | None = None

    @staticmethod
    def fps(core) -> float:
        """Env steps per simulated second: the real-time frame rate (RecordVideo's fps)."""
        return TICKS_PER_SECOND / core.ticks_per_step

    def render(self, core) -> np.ndarray | None:
        """Draw the core's current tick (None in 'human' mode, or before the first reset)."""
        plan = getattr(core, "plan", None)
        if plan is None:
            return None
        track = core.track
        if self.renderer is None or self.renderer.track is not track:
            if self.renderer is not None:
                self.renderer.close()
            self.renderer = Renderer(track, size=self.size, camera=self.camera)
        world = getattr(core.backend, "world", None)
        if world is not None:
            poses = CarPoses.from_world(world)
        else:
            cars = [core.assets.car(name) for name in plan.cars]
            poses = CarPoses(*poses_from_sensors(track, core.frame),
                             np.array([c.body_length for c in cars]), np.array([c.body_width for c in cars]))
        live = [plan.row(n) for n in core.live] or [plan.row(n) for n in plan.agents]
        k = live[0]
        ids = [f"T{j}" for j in range(plan.n_traffic)] + list(plan.agents)
        hud = Hud.from_world(world, k, ids[k]) if world is not None else _hud_from_sensors(core.frame, k, ids[k])
        overlay = None
        if self.overlay:
            suite = getattr(core.backend, "suite", None)
            angles = suite.angles_deg[k] if suite is not None else SNAKEOIL_ANGLES_DEG
            overlay = Overlay.from_sensors(core.frame, k, angles)
        img = self.renderer.frame(poses, ids, kinds_of_plan(plan), highlight=k, hud=hud, overlay=overlay)
        if self.render_mode == "rgb_array":
            return img
        fps = self.fps(core) * self.speedup if self.speedup > 0 else None
        self.renderer.show(fps)
        return None

    @property
    def window_closed(self) -> bool:
        """True once the user closed the 'human' window."""
        return self.renderer is not None and bool(getattr(self.renderer, "closed", False))

    def close(self) -> None:
        if self.renderer is not None:
            self.renderer.close()
            self.renderer = None


def _hud_from_sensors(frame, k: int, label: str) -> Hud:
    """HUD from SCR sensors (no World behind a UDP backend): SCR rpm is engine rad/s x 10;
    laps are not sent, so the HUD shows none."""
    row = frame.row(k)
    return Hud(speed_kmh=row["speedX"], gear=row["gear"], rpm=row["rpm"] / 10.0 * 60.0 / (2 * np.pi),
               lap=None, lap_time_s=row["curLapTime"], position=row["racePos"], n_cars=len(frame),
               time_s=0.0, label=label)
