"""`render_mode` for the envs, kept out of them: an `EnvView` draws a `ViewState`.

An env holds one `EnvView` when a render mode is asked for and calls
`view.render(state)` with a `ViewState` it builds of the current tick (the track, the SCR
sensors, the local World if there is one, labels, kinds, the car to follow): render reads
nothing else of the env and imports none of it. "rgb_array" returns the frame, "human" shows
it in a window at the env's real-time rate (`fps(ticks_per_step)`: 50 ticks a second / ticks
per step, times `speedup`) and returns None. Poses come from the World when there is one,
else from the SCR sensors (UDP backend), so rendering never touches the observation path.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from madsim.raster.poses import poses_from_sensors
from madsim.render.scene import CarPoses, Hud, Overlay
from madsim.render.topdown import Camera, Renderer

if TYPE_CHECKING:
    from madsim.physics.sensors import SensorFrame
    from madsim.physics.world import World
    from madsim.tracks.track import Track

RENDER_MODES = ("human", "rgb_array")
TICKS_PER_SECOND = 50.0


@dataclass(frozen=True)
class ViewState:
    """One tick as an env hands it to `EnvView.render`, cars in World row order (N cars).

    track: the episode's Track; frame: the SCR sensors of every car (SensorFrame); ids,
    kinds: (N,) label and kind ('traffic', 'parked', 'learner') of each car; focus: the row
    followed and highlighted; angles_deg: (19,) its rangefinder angles (the overlay);
    ticks_per_step: ticks per env step (the real-time rate); world: the local World (poses
    and the HUD from its state) or None (over UDP: poses and HUD from the sensors, bodies
    from body_m (N, 2): length, width m)."""

    track: Track
    frame: SensorFrame
    ids: tuple[str, ...]
    kinds: tuple[str, ...]
    focus: int
    angles_deg: np.ndarray
    ticks_per_step: int = 1
    world: World | None = None
    body_m: np.ndarray | None = None


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
    def fps(ticks_per_step: int) -> float:
        """Env steps per simulated second: the real-time frame rate (RecordVideo's fps)."""
        return TICKS_PER_SECOND / ticks_per_step

    def render(self, state: ViewState | None) -> np.ndarray | None:
        """Draw the tick `state` describes (None in 'human' mode, or for no state: before the
        env's first reset)."""
        if state is None:
            return None
        track = state.track
        if self.renderer is None or self.renderer.track is not track:
            if self.renderer is not None:
                self.renderer.close()
            self.renderer = Renderer(track, size=self.size, camera=self.camera)
        world, frame, k = state.world, state.frame, state.focus
        if world is not None:
            poses = CarPoses.from_world(world)
            hud = Hud.from_world(world, k, state.ids[k])
        else:
            body = np.asarray(state.body_m, dtype=np.float64)
            poses = CarPoses(*poses_from_sensors(track, frame), body[:, 0], body[:, 1])
            hud = _hud_from_sensors(frame, k, state.ids[k])
        overlay = Overlay.from_sensors(frame, k, state.angles_deg) if self.overlay else None
        img = self.renderer.frame(poses, list(state.ids), state.kinds, highlight=k, hud=hud,
                                  overlay=overlay)
        if self.render_mode == "rgb_array":
            return img
        fps = self.fps(state.ticks_per_step) * self.speedup if self.speedup > 0 else None
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
