"""`madsim run`: drive a scenario with a built-in, random or trained driver, print a table per car,
optionally write a plot and a video or open a window.

The learner's driver sees either its car's full SCR sensor row (`pid`, the built-in
track-position/speed driver) or the env's observation (`random`, a trained policy). Per-car
statistics come from the World every step; the default scenario runs one tick per step.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from madsim.physics import layout as L

DEFAULT_CONFIG = "run_default.yml"
SAFE_DECEL_MS2 = 5.0        # braking rate the built-in driver plans with, m/s^2
MIN_SPEED_KMH = 30.0
FRONT_SECTORS = (16, 17, 18, 19)   # opponents sectors within +-20 degrees of the nose
SIDE_SECTORS = tuple(range(6, 30))  # -120..+120 degrees: alongside or ahead
LEFT_SECTORS = tuple(range(7, 16))  # -110..-20 degrees: alongside on the left
RIGHT_SECTORS = tuple(range(20, 29))  # +20..+110 degrees: alongside on the right
PASS_LANE = 0.6
RECOVERY_SPEED_KMH = 20.0


def default_config_path() -> Path:
    return Path(str(resources.files("madsim.envs") / "configs" / DEFAULT_CONFIG))


class TrackSpeedDriver:
    """The built-in driver for a T-S action space: speed from the free road ahead
    (v <= sqrt(2 a d), a = SAFE_DECEL_MS2, d = longest of the three forward rangefinders), lane
    0 unless a car is close ahead, then the side with more room. Output: (trackPos, km/h)."""

    def __init__(self, top_speed_kmh: float, normalised: bool, target_speed_ms: float):
        self.top_speed_kmh = top_speed_kmh
        self.normalised = normalised
        self.target_speed_ms = target_speed_ms
        self.lane = 0.0

    def __call__(self, row) -> np.ndarray:
        rays = row["track"]
        on_road = min(rays) >= 0
        ahead = max(rays[8], rays[9], rays[10]) if on_road else 0.0
        speed = min(self.top_speed_kmh, max(MIN_SPEED_KMH, 3.6 * math.sqrt(2 * SAFE_DECEL_MS2 * ahead)))
        opp = row["opponents"]
        left_clear = min(opp[k] for k in LEFT_SECTORS) > 8.0
        right_clear = min(opp[k] for k in RIGHT_SECTORS) > 8.0
        j = min(FRONT_SECTORS, key=lambda k: opp[k])
        close = opp[j]
        if not on_road:
            self.lane, speed = 0.0, RECOVERY_SPEED_KMH      # back onto the road, gently
        elif close < 50.0:
            # pass on the side away from the car ahead (sectors 16-17 are left of the nose),
            # if nobody is alongside there; otherwise wait behind it
            want = -PASS_LANE if j in (16, 17) else PASS_LANE
            if (want > 0 and left_clear) or (want < 0 and right_clear):
                self.lane = want
            if close < 20.0 and j in (17, 18):               # right behind it: do not run into it
                speed = min(speed, max(MIN_SPEED_KMH, 2.5 * close))
        elif min(opp[k] for k in SIDE_SECTORS) > 15.0:
            self.lane = 0.0                                   # nobody alongside: back to the centre
        if not left_clear and right_clear:                    # someone squeezing from the left
            self.lane = min(self.lane, 0.0) - 0.2
        elif not right_clear and left_clear:
            self.lane = max(self.lane, 0.0) + 0.2
        self.lane = max(-0.8, min(0.8, self.lane))
        if self.normalised:   # [-1, 1] over track limits (-1, 1) and +-target speed
            return np.array([self.lane, speed / 3.6 / self.target_speed_ms], dtype=np.float32)
        return np.array([self.lane, speed], dtype=np.float32)


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
    laps_seen: int = 0
    x: list = field(default_factory=list)
    y: list = field(default_factory=list)
    speed: list = field(default_factory=list)
    dist: list = field(default_factory=list)
    track_pos: list = field(default_factory=list)


def _driver_for(name: str, env, config):
    agent = env.unwrapped.core.config.agents[0]
    if name == "random":
        space = env.action_space
        return lambda obs, row: space.sample()
    if name == "pid":
        if agent.action.space != "TS":
            raise ValueError(f"--driver pid drives a T-S action space; agent {agent.name!r} uses "
                             f"{agent.action.space}")
        drv = TrackSpeedDriver(min(agent.action.max_speed_kmh, agent.target_speed * 3.6),
                               agent.action.normalised, agent.target_speed)
        return lambda obs, row: drv(row)
    path = Path(name)
    if not path.exists():
        raise ValueError(f"--driver must be pid, random or the path of a saved policy; {name!r} does not exist")
    try:
        from madsim.train import load_policy
    except ImportError as exc:
        raise ValueError(f"--driver {name} needs the train extra ({exc.name} missing): "
                         f"pip install 'madsim[train]'") from None

    policy = load_policy(path)
    return lambda obs, row: policy(obs)


def run(config=None, *, episodes: int = 1, driver: str = "pid", seed: int = 0, video: str | None = None,
        plot: str | None = None, render: bool = False, progress: bool = True, log=print) -> list[list[CarStats]]:
    """Run `episodes` episodes; returns the statistics per episode and car."""
    from tqdm import tqdm

    from madsim.envs import MadrasEnv

    if config is None and driver not in ("pid", "random"):
        config = _policy_config(driver)      # a trained policy drives the scenario it learned on
    config = config or str(default_config_path())
    if video or render:
        _need_render_extra("--video" if video else "--render")
    env = MadrasEnv(config, render_mode="human" if render else None)
    act = _driver_for(driver, env, config)
    core = env.unwrapped.core
    view = writer = None
    if video:
        from madsim.render.envview import EnvView
        from madsim.render.video import VideoWriter

        view = EnvView("rgb_array", size=(800, 600), camera="follow")
        writer = VideoWriter(video, fps=25.0)
    all_stats = []
    try:
        for ep in range(episodes):
            obs, info = env.reset(seed=seed + ep)
            plan, world = core.plan, core.backend.world
            me = plan.row(plan.agents[0])
            kinds = _kinds(plan)
            labels = [f"traffic {j} ({plan.traffic[j].behaviour})" for j in range(plan.n_traffic)] + list(plan.agents)
            stats = [CarStats(labels[k], kinds[k], laps_seen=int(world.state[k, L.S_LAPS]))
                     for k in range(world.n_cars)]
            max_steps = core.stage.cfg.server.max_steps or 100000
            bar = tqdm(total=max_steps, desc=f"episode {ep + 1}/{episodes} {plan.track}", unit="tick",
                       disable=not progress, leave=False)
            start, sim0 = time.perf_counter(), world.time
            step = 0
            while True:
                row = core.rows[me]
                obs, reward, terminated, truncated, info = env.step(act(obs, row))
                if step == 0:   # the first step may compile numba kernels: time from here
                    start, sim0 = time.perf_counter(), world.time
                _record(stats, world, core.track.width)
                step += 1
                if writer is not None and step % 2 == 0:
                    writer.append(view.render(core))
                bar.update(info.get("ticks", 1))
                if terminated or truncated:
                    break
            bar.close()
            wall = time.perf_counter() - start
            log(_table(stats, world.time - sim0, wall, plan.track, info))
            if plot:
                _plot(core.track, stats, plot if episodes == 1 else _numbered(plot, ep))
                log(f"wrote {plot if episodes == 1 else _numbered(plot, ep)}")
            all_stats.append(stats)
    finally:
        if writer is not None:
            writer.close()
            log(f"wrote {video}")
        if view is not None:
            view.close()
        env.close()
    return all_stats


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


def _kinds(plan) -> list[str]:
    from madsim.render.scene import kinds_of_plan

    return list(kinds_of_plan(plan))


def _record(stats: list[CarStats], world, width: float) -> None:
    st = world.state
    speed = st[:, L.S_VX] * 3.6
    off = np.abs(st[:, L.S_N]) > width / 2
    hits = np.asarray(world.contact_wall) | np.asarray(world.contact_car)
    for k, cs in enumerate(stats):
        cs.ticks += 1
        cs.speed_sum += float(speed[k])
        cs.top_speed_kmh = max(cs.top_speed_kmh, float(speed[k]))
        cs.collisions += int(hits[k])
        cs.off_track_ticks += int(off[k])
        laps = int(st[k, L.S_LAPS])
        if laps > cs.laps_seen:
            if laps >= 2:
                cs.lap_times.append(float(st[k, L.S_LASTLAP]))
            cs.laps_seen = laps
        cs.x.append(float(st[k, L.S_X]))
        cs.y.append(float(st[k, L.S_Y]))
        cs.speed.append(float(speed[k]))
        cs.dist.append(float(st[k, L.S_S]))
        cs.track_pos.append(float(st[k, L.S_N]) / (width / 2))


def _table(stats: list[CarStats], sim_s: float, wall_s: float, track: str, info: dict) -> str:
    dt = 0.02
    lines = [f"{track}: {sim_s:.1f} s simulated in {wall_s:.1f} s wall "
             f"({sim_s / max(wall_s, 1e-9):.0f} sim s per wall s); ended by {', '.join(info.get('dones', ())) or '-'}",
             f"{'car':30s} {'laps':>4s} {'lap times (s)':>16s} {'avg km/h':>8s} {'top km/h':>8s} "
             f"{'collisions':>10s} {'off track (s)':>13s}"]
    for cs in stats:
        laps = "  ".join(f"{t:.2f}" for t in cs.lap_times) or "-"
        avg = cs.speed_sum / max(cs.ticks, 1)
        lines.append(f"{cs.label:30s} {len(cs.lap_times):>4d} {laps:>16s} {avg:>8.1f} {cs.top_speed_kmh:>8.1f} "
                     f"{cs.collisions:>10d} {cs.off_track_ticks * dt:>13.1f}")
    return "\n".join(lines)


def _plot(track, stats: list[CarStats], out: str) -> None:
    from madsim.render.plots import Run, plot_runs

    from madsim.render.plots import unwrap_distance

    runs = [Run(cs.label, np.array(cs.x), np.array(cs.y), np.array(cs.speed),
                unwrap_distance(np.array(cs.dist), track.length), np.array(cs.track_pos)) for cs in stats]
    plot_runs(track, runs, out)


def _numbered(path: str, ep: int) -> str:
    p = Path(path)
    return str(p.with_name(f"{p.stem}-{ep + 1}{p.suffix}"))
