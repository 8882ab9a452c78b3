"""Issue 14 items 1 and 13: `madsim run` drives every shipped scenario (one learner or several,
T-S or S-A-B) with the built-in driver that fits it, in process and on a running SCR server."""

import math
import threading
from pathlib import Path

import numpy as np
import pytest
from udp import free_ports

from madsim.drivers import PedalDriver, TrackSpeedDriver, builtin_driver
from madsim.envs.config import load_config
from madsim.run import run

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = sorted((ROOT / "madsim" / "envs" / "configs").glob("*.yml")) + sorted((ROOT / "examples").glob("*.yml"))
TICKS = 300


@pytest.mark.parametrize("path", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_every_shipped_scenario_runs_with_the_builtin_driver(path):
    cfg = load_config(path)
    latency = max(a.pid.latency if a.action.space == "TS" else 1 for a in cfg.agents)
    lines = []
    stats = run(str(path), max_steps=math.ceil(TICKS / latency), progress=False, log=lines.append)[0]
    learners = [s for s in stats if s.kind == "learner"]
    assert [s.label for s in learners] == [a.name for a in cfg.agents]
    table = lines[-1].splitlines()
    assert "ended by" in table[0] and len(table) == 2 + len(stats)       # the table: header + one row per car
    assert "start-up (loading, compiling kernels)" in table[0]          # compile time apart from the run's
    for s in learners:
        assert s.ticks >= 100, (s.label, s.ticks)
        assert np.isfinite(s.speed).all() and np.isfinite(s.x).all()
        moved = max(s.dist) - min(s.dist)
        assert moved > 20.0, (s.label, moved)                            # it drives, it does not stall


def test_builtin_driver_fits_each_action_space():
    ts = load_config({"agents": [{"action": {"space": "TS", "normalised": True}}]}).agents[0]
    sab = load_config({"agents": [{"action": {"space": "SAB", "normalised": False}, "gear": "manual"}]}).agents[0]
    assert isinstance(builtin_driver(ts), TrackSpeedDriver)
    drv = builtin_driver(sab)
    assert isinstance(drv, PedalDriver)
    row = {"track": [60.0] * 19, "opponents": [200.0] * 36, "angle": 0.0, "trackPos": 0.5, "speedX": 10.0}
    steer, accel, brake, gear = drv(row)
    assert steer < 0 and accel > 0 and brake == 0 and gear == 1     # left of the lane: steer right; slow: throttle
    row["speedX"] = 150.0
    _, accel, brake, gear = drv(row)
    assert accel == 0 and brake > 0 and gear == 5                   # too fast for the target: brake


def test_run_drives_the_cars_of_a_running_scr_server():
    """The same command over UDP (ScrBackend) against madsim's own server: the table comes from
    the SCR sensors, the learner drives."""
    from madsim.cli import make_world_factory
    from madsim.net.server import ScrServer

    port = free_ports(1)
    server = ScrServer(make_world_factory("madsim-road", ["madsim-sedan"], 1), 1, port=port, countdown_ticks=0,
                       max_ticks=2000, log=lambda m: None)
    server.open()
    thread = threading.Thread(target=server.serve, daemon=True)
    thread.start()
    cfg = {"server": {"tracks": ["madsim-road"], "cars": ["madsim-sedan"], "max_steps": 400},
           "agents": [{"name": "driver", "action": {"space": "TS", "normalised": False}, "pid": {"latency": 1},
                       "target_speed": 25.0}]}
    lines = []
    try:
        stats = run(cfg, port=port, progress=False, log=lines.append)[0]
    finally:
        server.stop()
        thread.join(timeout=5)
    (driver,) = stats
    assert driver.ticks >= 300 and max(driver.speed) > 40.0 and driver.off_track_ticks == 0
    # the table is the first line after any "compiling the kernels" notice of a cold cache
    table = next(m for m in lines if m.startswith("madsim-road:")).splitlines()
    assert table[2].split()[0] == "driver"


def test_a_slow_start_says_that_kernels_are_compiling():
    """Issue 14 item 7: while the first step waits (numba compiling), one line says what it is."""
    import time

    from madsim.run import _slow_start_notice

    said = []
    timer = _slow_start_notice(said.append, after_s=0.05)
    time.sleep(0.5)
    timer.cancel()
    assert len(said) == 1 and "compiling" in said[0] and "cached" in said[0]
    said.clear()
    timer = _slow_start_notice(said.append, after_s=0.5)
    timer.cancel()                       # the first step came in time: nothing said
    time.sleep(0.7)
    assert said == []


def test_closing_the_window_ends_the_run_not_just_the_drawing(monkeypatch):
    """Issue 14 item 5: the window's close button ends `madsim run --render` (status 0)."""
    pygame = pytest.importorskip("pygame")
    from madsim.render.envview import EnvView
    from madsim.run import RunInterrupted

    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    calls = [0]
    draw = EnvView.render

    def render(self, state):
        calls[0] += 1
        if self.render_mode == "human" and calls[0] == 10:
            pygame.event.post(pygame.event.Event(pygame.QUIT))      # the user closes the window
        return draw(self, state)

    monkeypatch.setattr(EnvView, "render", render)
    with pytest.raises(RunInterrupted, match="window closed") as stopped:
        run(render=True, episodes=2, progress=False, log=lambda line: None)
    assert stopped.value.status == 0 and calls[0] <= 11


def test_run_writes_a_video_of_the_env_it_drives(tmp_path):
    """`madsim run --video out.gif` draws the env's view state every 0.2 s of simulated time
    (5 frames/s): 60 steps of 0.02 s (the bundled scenario, S-A-B) are 1.2 s, 6 frames."""
    pytest.importorskip("pygame")
    from PIL import Image

    out = tmp_path / "run.gif"
    run(video=str(out), max_steps=60, progress=False, log=lambda line: None)
    with Image.open(out) as gif:
        assert gif.size == (400, 300) and gif.n_frames == 6
