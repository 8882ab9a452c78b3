"""What one episode is made of: MADRaS's domain randomisation (paper, Appendix C), as data.

`draw_plan(cfg, episode, rng)` chooses the track, each learning agent's car and the number of
traffic cars; `placements(cfg, plan, track, rng)` puts every car on the track. Both are pure
functions of their arguments, so an episode is fully determined by (config, episode index,
seed). Draws, in this order from the one generator:

1. track: order "fixed": `tracks[k mod len]`; "random": categorical, uniform over the list;
2. cars, one per agent without a fixed `car`, in agent order: fixed: `cars[(k + i) mod len]`;
   random: categorical, uniform;
3. traffic count: None: every traffic entry; fixed: `min + k mod (max - min + 1)`;
   random: discrete uniform on [min, max]; the first n traffic entries drive;
4. placements, car by car in row order (traffic first, then learners), each car: distance
   from the start line `s ~ U(initial_distance)` (m) if given, then track position
   `trackPos ~ U(initial_trackpos)` if given; otherwise the car's grid slot.

Row order is MADRaS's slot order: traffic cars take rows (and grid slots) 0..n-1, learning
agents follow in config order, so traffic starts ahead on the grid. The grid is TORCS's quick
race grid (`madsim.physics.tables.grid_positions`); `server.distance_to_start` applies unless
the track's own grid sets it (the track wins, as in TORCS). `server.grid` gives the race's own
grid values instead, as a TORCS race file (and `madsim serve --grid`) does.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from madsim.cars import CarSpec, load_car
from madsim.envs.config import ScenarioConfig, TrafficConfig, generated_track_args
from madsim.physics.tables import QUICKRACE_GRID, grid_positions
from madsim.tracks import Track, load_track, load_track_xml

__all__ = ["AssetCache", "EpisodePlan", "draw_plan", "placements"]


@dataclass(frozen=True)
class EpisodePlan:
    """The choices of one episode (see the module docstring for how they are drawn).

    seed: the episode seed (info["seed"]); episode: index k used by order "fixed";
    track: the server.tracks entry; agents: names of the learning agents (config order);
    agent_cars: their car names; traffic: the traffic entries driving; traffic_cars: theirs.
    """

    seed: int
    episode: int
    track: str
    agents: tuple[str, ...]
    agent_cars: tuple[str, ...]
    traffic: tuple[TrafficConfig, ...]
    traffic_cars: tuple[str, ...]

    @property
    def n_traffic(self) -> int:
        return len(self.traffic)

    @property
    def cars(self) -> tuple[str, ...]:
        """Car names in World row order: traffic first, then learners."""
        return self.traffic_cars + self.agent_cars

    def row(self, agent: str) -> int:
        """World row of a learning agent's car."""
        return self.n_traffic + self.agents.index(agent)

    @property
    def kinds(self) -> tuple[str, ...]:
        """Kind of each car in World row order: 'traffic' ('parked' for the Parked
        behaviour), then 'learner'."""
        traffic = tuple("parked" if t.behaviour == "Parked" else "traffic" for t in self.traffic)
        return traffic + ("learner",) * len(self.agents)


def draw_plan(cfg: ScenarioConfig, episode: int, seed: int,
              rng: np.random.Generator) -> EpisodePlan:
    """Track, cars and traffic of episode `episode` (draws 1-3 of the module docstring)."""
    s = cfg.server
    k = int(episode)
    if s.order == "fixed":
        track = s.tracks[k % len(s.tracks)]
    else:
        track = s.tracks[int(rng.integers(len(s.tracks)))]
    cars = []
    for i, agent in enumerate(cfg.agents):
        if agent.car is not None:
            cars.append(agent.car)
        elif s.order == "fixed":
            cars.append(s.cars[(k + i) % len(s.cars)])
        else:
            cars.append(s.cars[int(rng.integers(len(s.cars)))])
    if s.traffic_count is None:
        n = len(cfg.traffic)
    else:
        low, high = s.traffic_count
        n = low + k % (high - low + 1) if s.order == "fixed" else int(rng.integers(low, high + 1))
    traffic = tuple(cfg.traffic[:n])
    return EpisodePlan(seed=int(seed), episode=k, track=track, agents=cfg.agent_names,
                       agent_cars=tuple(cars), traffic=traffic,
                       traffic_cars=tuple(t.car or s.traffic_car for t in traffic))


def placements(cfg: ScenarioConfig, plan: EpisodePlan, track: Track,
               rng: np.random.Generator) -> np.ndarray:
    """(N, 3) of (s [m], n [m, left +], speed [m/s] = 0) per car in row order (draw 4)."""
    ranges = [(t.initial_distance, t.initial_trackpos) for t in plan.traffic]
    agents = {a.name: a for a in cfg.agents}
    ranges += [(agents[name].initial_distance, agents[name].initial_trackpos)
               for name in plan.agents]
    n_cars = len(ranges)
    grid = cfg.server.grid
    if grid is not None:                 # where `madsim serve --grid` puts them
        s, n = grid_positions(track, n_cars, grid.race_grid(cfg.server.distance_to_start))
    else:
        s, n = grid_positions(track, n_cars)
        if "distance to start" not in track.grid:
            s = np.mod(s + (QUICKRACE_GRID["distance to start"] - cfg.server.distance_to_start),
                       track.length)
    out = np.zeros((n_cars, 3))
    out[:, 0], out[:, 1] = s, n
    half_width = track.width / 2.0
    for i, (distance, trackpos) in enumerate(ranges):
        if distance is not None:
            out[i, 0] = np.mod(rng.uniform(*distance), track.length)
        if trackpos is not None:
            out[i, 1] = rng.uniform(*trackpos) * half_width
    return out


class AssetCache:
    """Tracks and cars loaded once per env: by name, path or "generated:<seed>[:len[:width]]"."""

    def __init__(self):
        self._tracks: dict[str, Track] = {}
        self._cars: dict[str, CarSpec] = {}

    def track(self, entry: str) -> Track:
        """The Track of a server.tracks entry (generated tracks are built on first use)."""
        track = self._tracks.get(entry)
        if track is None:
            args = generated_track_args(entry)
            track = load_track(entry) if args is None else _generated(**args)
            self._tracks[entry] = track
        return track

    def car(self, name: str) -> CarSpec:
        car = self._cars.get(name)
        if car is None:
            car = self._cars[name] = load_car(name)
        return car


def _generated(**args) -> Track:
    from madsim.tracks.generate import generate_track_xml

    text = generate_track_xml(**args)
    name = f"madsim-gen-{args['seed']}"
    with tempfile.TemporaryDirectory(prefix="madsim-track-") as folder:
        path = Path(folder) / name / f"{name}.xml"
        os.makedirs(path.parent)
        path.write_text(text)
        return load_track_xml(path)
