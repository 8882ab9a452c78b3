"""render_mode for the envs through `EnvView`, and gymnasium's RecordVideo on it.

`RenderingEnv` below is MadrasEnv with the render_mode lines proposed for it (issue 7):
the same few lines, applied in a subclass so the view can be tested before the env takes it.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
import pytest

pytest.importorskip("pygame", reason="the renderer needs pygame: pip install 'madsim[render]'")

from madsim.envs.madras_env import MadrasEnv
from madsim.physics import layout as L
from madsim.render.envview import EnvView
from madsim.render.topdown import KIND_COLOURS

CONFIG = {"server": {"tracks": ["madsim-road"], "max_steps": 40},
          "agents": [{"name": "me", "action": {"space": "SAB"}}]}


class RenderingEnv(MadrasEnv):
    metadata: ClassVar[dict] = {**MadrasEnv.metadata, "render_modes": ["human", "rgb_array"]}

    def __init__(self, config=None, *, render_mode=None, size=(320, 240)):
        super().__init__(config)
        self.render_mode = render_mode
        self._view = EnvView(render_mode, size=size) if render_mode is not None else None
        self.metadata = {**self.metadata, "render_fps": EnvView.fps(self.core.ticks_per_step)}

    def render(self):
        return None if self._view is None else self._view.render(self.core.view_state())

    def close(self):
        if self._view is not None:
            self._view.close()
        super().close()


def test_rgb_array_shows_the_learner_and_its_hud():
    env = RenderingEnv(CONFIG, render_mode="rgb_array")
    env.reset(seed=3)
    for _ in range(10):
        env.step(np.array([0.0, 1.0, 0.0], np.float32))
    img = env.render()
    assert img.shape == (240, 320, 3) and img.dtype == np.uint8
    view = env._view.renderer
    world = env.core.backend.world
    st = world.state
    assert view.last_hud[0] == "me"
    assert view.last_hud[1] == f"{st[0, L.S_VX] * 3.6:.0f} km/h"
    # the follow camera is centred on the learner: its body colour at the centre
    sx, sy = view.view.to_screen(st[0, L.S_X], st[0, L.S_Y])
    assert abs(sx - 160) <= 0.5 and abs(sy - 120) <= 0.5
    assert tuple(img[120, 158]) == KIND_COLOURS["learner"]
    env.close()


def test_render_before_reset_and_bad_mode():
    env = RenderingEnv(CONFIG, render_mode="rgb_array")
    assert env.render() is None
    with pytest.raises(ValueError, match="render_mode"):
        EnvView("pictures")
    env.close()


def test_human_mode_draws_into_a_window():
    env = RenderingEnv(CONFIG, render_mode="human")
    env._view.speedup = 0.0            # as fast as it goes
    env.reset(seed=0)
    env.step(np.array([0.0, 1.0, 0.0], np.float32))
    assert env.render() is None
    pg = env._view.renderer.pg
    assert pg.display.get_surface().get_size() == (320, 240)
    env.close()


def test_record_video_writes_a_playable_file(tmp_path):
    pytest.importorskip("moviepy", reason="gymnasium's RecordVideo needs moviepy: pip install 'madsim[render]'")
    ffmpeg = pytest.importorskip("imageio_ffmpeg")
    from gymnasium.wrappers import RecordVideo

    env = RecordVideo(RenderingEnv(CONFIG, render_mode="rgb_array"), str(tmp_path / "videos"),
                      episode_trigger=lambda e: True, disable_logger=True)
    env.reset(seed=1)
    steps = 0
    done = False
    while not done:
        _, _, term, trunc, _ = env.step(np.array([0.0, 1.0, 0.0], np.float32))
        steps += 1
        done = term or trunc
    env.close()
    files = sorted((tmp_path / "videos").glob("*.mp4"))
    assert len(files) == 1
    reader = ffmpeg.read_frames(str(files[0]))
    meta = next(reader)
    assert meta["size"] == (320, 240) and meta["fps"] == pytest.approx(50.0)
    assert sum(1 for _ in reader) == steps + 1          # the reset frame and one per step


def test_traffic_cars_get_their_kind_colours():
    pytest.importorskip("madsim.agents.traffic", reason="traffic behaviours not installed")
    cfg = {"server": {"tracks": ["madsim-road"], "traffic_count": [2, 2], "max_steps": 40},
           "agents": [{"name": "me", "action": {"space": "SAB"}}],
           "traffic": [{"behaviour": "ConstVel", "target_speed": 10.0, "lane": 0.0},
                       {"behaviour": "Parked", "initial_distance": [3000.0, 3000.0],
                        "initial_trackpos": [0.5, 0.5]}]}
    env = RenderingEnv(cfg, render_mode="rgb_array", size=(800, 600))
    env.reset(seed=0)
    img = env.render()
    view = env._view.renderer
    world = env.core.backend.world
    # rows: traffic first (ConstVel, Parked), then the learner; all within 30 m of each other
    for row, kind in ((0, "traffic"), (1, "parked"), (2, "learner")):
        sx, sy = view.view.to_screen(world.x[row], world.y[row])
        assert 0 <= sx < 800 and 0 <= sy < 600
        assert tuple(img[int(sy), int(sx)]) == KIND_COLOURS[kind], kind
    env.close()


def test_envview_draws_a_view_state_built_from_plain_parts():
    """EnvView reads only the ViewState it is handed (no env): here as over UDP, poses from
    the SCR sensors and bodies from body_m; the followed car is drawn in the learner colour at
    the centre of a follow camera, the other in its kind's colour where the world has it."""
    from madsim.cars.loader import load_car
    from madsim.physics.sensors import SensorSuite
    from madsim.physics.world import World
    from madsim.render.envview import ViewState
    from madsim.tracks.library import load_track

    track, car = load_track("madsim-road"), load_car("madsim-sedan")
    world = World(track, [car, car], np.random.default_rng(0), contact=False)
    world.reset(np.array([[40.0, 0.0, 0.0], [60.0, -3.0, 0.0]]))
    frame = SensorSuite(world).frame()
    state = ViewState(track=track, frame=frame, ids=("T0", "me"), kinds=("parked", "learner"),
                      focus=1, angles_deg=np.zeros(19), ticks_per_step=5,
                      body_m=np.array([[car.body_length, car.body_width]] * 2))
    view = EnvView("rgb_array", size=(320, 240))
    img = view.render(state)
    assert img.shape == (240, 320, 3)
    assert view.renderer.last_hud[0] == "me"
    assert tuple(img[120, 158]) == KIND_COLOURS["learner"]
    sx, sy = view.renderer.view.to_screen(world.x[0], world.y[0])
    assert tuple(img[int(sy), int(sx)]) == KIND_COLOURS["parked"]
    assert EnvView.fps(state.ticks_per_step) == 10.0
    assert view.render(None) is None
    view.close()
