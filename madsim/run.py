"""`madsim run`: drive a scenario with a built-in, random or trained driver, print a table per car,
optionally write a plot and a video or open a window.

Any scenario runs: one learning agent or several (MadrasParallelEnv), each driven by the driver
asked for (`pid`: the built-in driver fitting its action space, `madsim.drivers`; `random`;
or a saved policy). The cars drive in this process or, with `port`, on a running SCR server
(`ScrBackend`: `madsim serve` or TORCS). Per-car statistics come from the cars' SCR sensor
rows after every step (the same in both cases; contact flags when the backend has them, else
damage increments), weighted by the ticks the step took.
A SIGINT or SIGTERM ends the step, finishes the files of what was done and raises
`RunInterrupted` (one line for the CLI); closing the window ends the run the same way.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from madsim.drivers import TrackSpeedDriver, builtin_driver  # noqa: F401 (TrackSpeedDriver: public)
from madsim.interrupts import StopRequest

DEFAULT_CONFIG = "run_default.yml"
TICK_S = 0.02
GIF_SIZE = (400, 300)       # a GIF worth sharing (a lap in a few MB): small frames, few of them
GIF_FPS = 5.0
VIDEO_SIZE = (800, 600)


class RunInterrupted(Exception):
    """The run was stopped (signal or closed window) after writing what was done; `status` is
    the exit status to return (130 SIGINT, 143 SIGTERM, 0 for a closed window)."""

    def __init__(self, message: str, status: int):
        super().__init__(message)
        self.status = status


def default_config_path() -> Path:
    return Path(str(resources.files("madsim.envs") / "configs" / DEFAULT_CONFIG))


@dataclass
class CarStats:
    """Running statistics of one car over a run."""

    label: str
    kind: str
    ticks: int = 0
    speed_sum: float = 0.0
    top_speed_kmh: float = 0.0
    collisions: int = 0
    off_track_ticks: int = 0
    lap_times: list = field(default_factory=list)
    last_lap_s: float = 0.0
    damage: float = 0.0
    x: list = field(default_factory=list)
    y: list = field(default_factory=list)
    speed: list = field(default_factory=list)
    dist: list = field(default_factory=list)
    track_pos: list = field(default_factory=list)


def check_run_options(*, episodes: int, seed: int, port: int | None = None, max_steps: int | None = None) -> None:
    """ValueError (one line) for options `run` cannot use."""
    if max_steps is not None and max_steps < 1:
        raise ValueError(f"--max-steps must be at least 1, got {max_steps}")
    if episodes < 1:
        raise ValueError(f"--episodes must be at least 1, got {episodes}")
    if seed < 0:
        raise ValueError(f"--seed must be >= 0 (numpy seeds are non-negative), got {seed}")
    if port is not None and not 1 <= port <= 65535:
        raise ValueError(f"--port must be a UDP port, 1..65535, got {port}")


def _drivers_for(name: str, env, agents: list) -> dict:
    """agent name -> callable(obs, row) -> action."""
    if name == "random":
        return {a.name: (lambda obs, row, s=env.action_space(a.name): s.sample()) for a in agents}
    if name == "pid":
        out = {}
        for a in agents:
            drv = builtin_driver(a)
            out[a.name] = lambda obs, row, d=drv: d(row)
        return out
    path = Path(name)
    if not path.exists():
        raise ValueError(f"--driver must be pid, random or the path of a saved policy; {name!r} does not exist")
    try:
        from madsim.train import load_policy
    except ImportError as exc:
        raise ValueError(f"--driver {name} needs the train extra ({exc.name} missing): "
                         f"pip install 'madsim[train]'") from None
    policy = load_policy(path)
    return {a.name: (lambda obs, row: policy(obs)) for a in agents}


def run(config=None, *, episodes: int = 1, driver: str = "pid", seed: int = 0, video: str | None = None,
        plot: str | None = None, render: bool = False, progress: bool = True, host: str = "127.0.0.1",
        port: int | None = None, max_steps: int | None = None, log=None) -> list[list[CarStats]]:
    """Run `episodes` episodes; returns the statistics per episode and car (traffic first).
    port: drive the cars of the SCR server there (host) instead of in this process;
    max_steps: end each episode after this many env steps at most (ended by 'max-steps')."""
    from tqdm import tqdm

    from madsim.envs import MadrasParallelEnv

    check_run_options(episodes=episodes, seed=seed, port=port, max_steps=max_steps)
    log = log or (lambda line: print(line, flush=True))
    t0 = time.perf_counter()
    if config is None and driver not in ("pid", "random"):
        config = _policy_config(driver)   # a policy drives the scenario it learned on
    config = config or str(default_config_path())
    if render:
        _need_display()
    if video or render:
        _need_render_extra("--video" if video else "--render")
    backend = None
    if port is not None:
        from madsim.envs.backends import ScrBackend

        backend = ScrBackend(host, port)
    notice = _slow_start_notice(log)
    try:
        env = MadrasParallelEnv(config, backend=backend)
    except BaseException:
        notice.cancel()
        raise
    core = env.core
    try:
        act = _drivers_for(driver, env, list(core.config.agents))
    except BaseException:
        notice.cancel()
        env.close()
        raise
    view = writer = window = None
    if video:
        from madsim.render.envview import EnvView
        from madsim.render.video import VideoWriter

        gif = Path(video).suffix.lower() == ".gif"
        view = EnvView("rgb_array", size=GIF_SIZE if gif else VIDEO_SIZE, camera="follow")
        writer = VideoWriter(video, fps=GIF_FPS if gif else 25.0)
        frame_every_s = 1.0 / writer.fps
    if render:
        from madsim.render.envview import EnvView

        window = EnvView("human", size=VIDEO_SIZE, camera="follow")
    all_stats = []
    startup_s = 0.0
    ticks_done = 0
    ep = 0
    closed = False      # the user closed the window
    with StopRequest() as stop:
        try:
            for ep in range(episodes):
                obs, _ = env.reset(seed=seed + ep)
                plan = core.plan
                kinds = _kinds(plan)
                labels = [f"traffic {j} ({plan.traffic[j].behaviour})" for j in range(plan.n_traffic)] + \
                    list(plan.agents)
                stats = [CarStats(labels[k], kinds[k]) for k in range(len(core.rows))]
                _record(stats, core, 0)
                limit = min(core.stage.cfg.server.max_steps or 100000, max_steps or 100000)
                bar = tqdm(total=limit * core.ticks_per_step, desc=f"episode {ep + 1}/{episodes} {plan.track}",
                           unit="tick", disable=not progress, leave=False)
                start, sim0 = time.perf_counter(), core.tick
                first_step = True
                next_frame_s = 0.0
                dones: set = set()
                steps = 0
                while env.agents and not stop:
                    if max_steps is not None and steps >= max_steps:
                        dones.add("max-steps")
                        break
                    steps += 1
                    actions = {a: act[a](obs[a], core.rows[plan.row(a)]) for a in env.agents}
                    obs, _, _, _, infos = env.step(actions)
                    if first_step:   # kernels compile (or load from the cache) up to here: time from now
                        first_step = False
                        start, sim0 = time.perf_counter(), core.tick
                        if ep == 0:
                            notice.cancel()
                            startup_s = start - t0
                    ticks = max(i.get("ticks", 1) for i in infos.values()) if infos else 1
                    for i in infos.values():
                        dones.update(i.get("dones", ()))
                    _record(stats, core, ticks)
                    ticks_done += ticks
                    bar.update(ticks)
                    sim_s = (core.tick - sim0) * TICK_S
                    if writer is not None and sim_s >= next_frame_s:
                        frame = view.render(core.view_state())
                        while sim_s >= next_frame_s:     # a step longer than a frame: the video keeps time
                            writer.append(frame)
                            next_frame_s += frame_every_s
                    if window is not None:
                        window.render(core.view_state())
                        closed = window.window_closed
                        if closed:
                            break
                bar.close()
                if stop or closed:
                    break
                wall = time.perf_counter() - start
                log(_table(stats, (core.tick - sim0) * TICK_S, wall, plan.track, sorted(dones),
                           startup_s if ep == 0 else None))
                if plot:
                    out = plot if episodes == 1 else _numbered(plot, ep)
                    _plot(core.track, stats, out)
                    log(f"wrote {out}")
                all_stats.append(stats)
        finally:
            notice.cancel()
            written = _finish(writer, view, window, env)
    if stop or closed:
        why = f"interrupted by {stop.signal_name}" if stop else "window closed"
        files = f"wrote {video} ({written} frames, playable)" if written else "no video written"
        if video is None:
            files = "nothing written"
        raise RunInterrupted(f"{why} in episode {ep + 1}/{episodes} after {ticks_done} ticks; {files}",
                             stop.exit_status if stop else 0)
    if video:
        gif = Path(video).suffix.lower() == ".gif"
        log(f"wrote {video} ({written} frames" + (f", {GIF_SIZE[0]}x{GIF_SIZE[1]} at {GIF_FPS:g} frames/s: "
                                                  "an .mp4 has full size and rate)" if gif else ")"))
    return all_stats


def _finish(writer, view, window, env) -> int:
    """Close everything; returns the frames written to the video (0: none, no file)."""
    written = 0
    try:
        if writer is not None and writer.frames:
            writer.close()
            written = writer.frames
    finally:
        for thing in (view, window, env):
            if thing is not None:
                thing.close()
    return written


def _slow_start_notice(log, after_s: float = 3.0):
    """A started timer that says, if the first step has not come within `after_s`, what the
    wait is: numba compiling the kernels (the first run after an install; cached after)."""
    import threading

    timer = threading.Timer(after_s, lambda: log("madsim run: compiling the simulator's kernels (first run "
                                                  "after an install, ~15-40 s; cached for later runs) ..."))
    timer.daemon = True
    timer.start()
    return timer


def _policy_config(driver: str) -> str | None:
    """The config.yml that `madsim train` wrote beside a policy (DIR or DIR/policy.zip)."""
    path = Path(driver)
    run_dir = path if path.is_dir() else path.parent
    cfg = run_dir / "config.yml"
    return str(cfg) if cfg.is_file() else None


def _need_render_extra(option: str) -> None:
    import importlib.util

    missing = [m for m in ("pygame", "imageio_ffmpeg") if importlib.util.find_spec(m) is None]
    if missing:
        raise ValueError(f"{option} needs the render extra ({', '.join(missing)} missing): "
                         f"pip install 'madsim[render]'")


def _need_display() -> None:
    import os
    import sys

    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
                                                 or os.environ.get("SDL_VIDEODRIVER")):
        raise ValueError("--render needs a display (DISPLAY is not set); write a video instead: --video out.mp4")


def _kinds(plan) -> list[str]:
    return list(plan.kinds)


def _record(stats: list[CarStats], core, ticks: int) -> None:
    """Add one step of `ticks` ticks (0: the starting grid, positions only) from the sensor rows."""
    half_width = core.track.width / 2
    hits = core.backend.collisions() if ticks else None
    for k, cs in enumerate(stats):
        row = core.rows[k]
        speed = row["speedX"]
        pos = row["trackPos"]
        if ticks:
            cs.ticks += ticks
            cs.speed_sum += speed * ticks
            cs.top_speed_kmh = max(cs.top_speed_kmh, speed)
            damage = row["damage"]
            cs.collisions += int(hits[k]) if hits is not None else int(damage > cs.damage)
            cs.damage = damage
            cs.off_track_ticks += ticks * (abs(pos) > 1.0)
            last = row["lastLapTime"]
            if last > 0 and last != cs.last_lap_s:
                cs.lap_times.append(last)
            cs.last_lap_s = last
        else:
            cs.last_lap_s, cs.damage = row["lastLapTime"], row["damage"]
        cs.speed.append(speed)
        cs.dist.append(row["distFromStart"])
        cs.track_pos.append(pos)
    x, y, _, _ = core.track.pose(np.array([cs.dist[-1] for cs in stats]),
                                 np.array([cs.track_pos[-1] for cs in stats]) * half_width)
    for k, cs in enumerate(stats):
        cs.x.append(float(x[k]))
        cs.y.append(float(y[k]))


def _table(stats: list[CarStats], sim_s: float, wall_s: float, track: str, dones: list[str],
           startup_s: float | None = None) -> str:
    startup = f" after {startup_s:.1f} s start-up (loading, compiling kernels)" if startup_s is not None else ""
    lines = [f"{track}: {sim_s:.1f} s simulated in {wall_s:.1f} s wall "
             f"({sim_s / max(wall_s, 1e-9):.0f} sim s per wall s){startup}; ended by {', '.join(dones) or '-'}",
             f"{'car':30s} {'laps':>4s} {'lap times (s)':>16s} {'avg km/h':>8s} {'top km/h':>8s} "
             f"{'collisions':>10s} {'off track (s)':>13s}"]
    for cs in stats:
        laps = "  ".join(f"{t:.2f}" for t in cs.lap_times) or "-"
        avg = cs.speed_sum / max(cs.ticks, 1)
        lines.append(f"{cs.label:30s} {len(cs.lap_times):>4d} {laps:>16s} {_kmh(avg):>8.1f} "
                     f"{_kmh(cs.top_speed_kmh):>8.1f} {cs.collisions:>10d} {cs.off_track_ticks * TICK_S:>13.1f}")
    return "\n".join(lines)


def _kmh(v: float) -> float:
    """A speed for display: a parked car's -0.0004 km/h shows as 0.0, not -0.0."""
    return 0.0 if abs(v) < 0.05 else v


def _plot(track, stats: list[CarStats], out: str) -> None:
    from madsim.render.plots import Run, plot_runs, unwrap_distance

    runs = [Run(cs.label, np.array(cs.x), np.array(cs.y), np.array(cs.speed),
                unwrap_distance(np.array(cs.dist), track.length), np.array(cs.track_pos)) for cs in stats]
    plot_runs(track, runs, out)


def _numbered(path: str, ep: int) -> str:
    p = Path(path)
    return str(p.with_name(f"{p.stem}-{ep + 1}{p.suffix}"))
