"""TrafficFleet: all traffic cars in one compiled call drive exactly as each behaviour alone."""

from __future__ import annotations

import numpy as np
import yaml

from madsim.agents.traffic import (
    RandomStopping,
    TrafficBehaviour,
    draw_traffic_placements,
    make_behaviour,
)
from madsim.agents.traffic_fleet import TrafficFleet
from madsim.cars import load_car
from madsim.envs.config import load_config
from madsim.physics.sensors import N_VALUES, O_CURLAP, O_SX, O_TPOS, O_TRACK, SensorSuite
from madsim.physics.world import World
from madsim.tracks import load_track
from test_traffic import MIXED_STREET_YAML, TICK_S


class Weaving(TrafficBehaviour):
    """A user behaviour (Python target): lane +-0.5, switching every 2 s, 9 m/s."""

    def target(self, row, t_s):
        return (0.5 if int(t_s / 2.0) % 2 else -0.5), 9.0


class Foreign:
    """A traffic_factory object that is no TrafficBehaviour: creeps straight on."""

    def reset(self, rng, info):
        pass

    def act(self, row):
        return 0.0, 0.2 if row["speedX"] < 10.0 else 0.0, 0.0, 1


def _episode(seed: int):
    cfg = load_config(yaml.safe_load(MIXED_STREET_YAML))
    track = load_track("madsim-street")
    rng = np.random.default_rng(seed)
    used, pl = draw_traffic_placements(cfg.traffic, cfg.server.traffic_count, rng, track)
    behaviours = [make_behaviour(e) for e in used] + [Weaving(), Foreign()]
    pl = np.vstack([pl, [[420.0, 0.0, 0.0], [470.0, 0.0, 0.0]]])
    world = World(track, [load_car(cfg.server.traffic_car)] * len(behaviours),
                  np.random.default_rng(seed))
    world.reset(pl)
    infos = []
    for k, b in enumerate(behaviours):
        info = {"track_length": track.length, "track_width": track.width, "tick_s": TICK_S,
                "car": cfg.server.traffic_car}
        b.reset(np.random.default_rng([seed, k]), info)
        infos.append(info)
    return world, SensorSuite(world), behaviours, infos


def test_a_fleet_drives_every_car_bit_identically_to_each_behaviour_alone():
    """8 mixed built-in cars (lane switches, random stops, parking), a user behaviour and a
    foreign object: one fleet call per tick == one act per car, for 20 s (the random draws
    of RandomStopping cross several 64-draw refills)."""
    ticks = 1000
    world, suite, behaviours, infos_a = _episode(3)
    u = np.zeros((len(behaviours), 5))
    controls_a = []
    for _ in range(ticks):
        frame = suite.frame()
        for k, b in enumerate(behaviours):
            u[k, :4] = b.act(frame.row(k))
        controls_a.append(u.copy())
        world.step(u)
    world, suite, behaviours, infos_b = _episode(3)
    fleet = TrafficFleet(len(behaviours))
    for k, b in enumerate(behaviours):
        fleet.put(k, b)
    rows = np.arange(len(behaviours))
    u = np.zeros((len(behaviours), 5))
    controls_b = []
    for _ in range(ticks):
        fleet.act(suite.frame().flat, u, rows)
        controls_b.append(u.copy())
        world.step(u)
    assert np.array_equal(np.array(controls_a), np.array(controls_b))
    assert infos_a == infos_b
    assert sum(len(i.get("lane_draws", ())) for i in infos_b) > 4     # draws were recorded
    assert behaviours[0].travelled > 100.0                           # state read from the fleet


def test_random_stopping_consumes_its_generator_draw_by_draw():
    """A car standing still (speed 0): each tick it drives it draws u1 and halts if u1 < p,
    for max (1 - u2) s; the stops recorded equal that rule applied to rng.random() draws of the
    same seed, over 300 ticks (several refills of the 64-draw buffer)."""
    p, max_s = 0.3, 0.1
    b = RandomStopping(stop_probability=p, max_stop_duration=max_s)
    info = {"track_width": 10.0}
    b.reset(np.random.default_rng(7), info)
    row = np.zeros(N_VALUES)
    row[O_TRACK:O_TRACK + 19] = 5.0
    row[O_CURLAP], row[O_SX], row[O_TPOS] = 1.0, 0.0, 0.0
    fleet, u = b._own, np.zeros((1, 4))
    for _ in range(300):
        fleet.act(row[None, :], u, np.zeros(1, dtype=np.int64))
    ref, stand, expected = np.random.default_rng(7), None, []
    for tick in range(300):
        if stand is None and ref.random() < p:
            stand = max_s * (1.0 - ref.random())
            expected.append((tick * TICK_S, stand))
        if stand is not None:
            stand -= TICK_S
            if stand <= 0.0:
                stand = None
    assert len(expected) > 20
    assert info["stops"] == expected
