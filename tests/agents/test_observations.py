"""Observation modes: sizes, order and scalings of MADRaS (spec madras-features.md s. 5)."""

import math

import numpy as np
import pytest

from madsim.agents.observations import ObservationBuilder
from madsim.physics.sensors import N_VALUES, SENSOR_ORDER, SensorFrame


def scr_row(**kw):
    """One car's SCR row with recognisable values (SCR units)."""
    row = {"angle": math.pi / 4, "curLapTime": 12.0, "damage": 0.0, "distFromStart": 100.0,
           "distRaced": 120.0, "fuel": 90.0, "gear": 3, "lastLapTime": 0.0,
           "opponents": [200.0] * 36, "racePos": 2, "rpm": 5000.0, "speedX": 100.0,
           "speedY": -5.0, "speedZ": 0.5, "track": [10.0 * (i + 1) for i in range(19)],
           "trackPos": 0.3, "wheelSpinVel": [50.0, 51.0, 52.0, 53.0], "z": 0.3,
           "focus": [-1.0] * 5}
    row.update(kw)
    return row


@pytest.mark.parametrize("mode, size", [("TorcsObs", 29), ("SingleAgentSimpleLapObs", 24),
                                        ("SingleAgentInTrafficObs", 60)])
def test_madras_mode_sizes(mode, size):
    b = ObservationBuilder(mode)
    assert b.size == size and b.space.shape == (size,) and b.space.dtype == np.float32
    assert b(scr_row()).shape == (size,)


def test_simple_lap_order_and_scaling():
    track = [10.0 * (i + 1) for i in range(19)]
    track[0] = -1.0                                         # off-road sentinel -> 0
    obs = ObservationBuilder("SingleAgentSimpleLapObs")(scr_row(track=track))
    expected = [0.25] + [0.0] + [10.0 * (i + 1) / 200 for i in range(1, 19)] + [0.3, 2.0, -0.1, 0.01]
    assert obs == pytest.approx(np.array(expected, np.float32), abs=1e-7)
    assert obs.dtype == np.float32


def test_torcs_obs_tail_and_sentinel():
    obs = ObservationBuilder("TorcsObs")(scr_row(track=[-1.0] * 19))
    assert obs[1:20] == pytest.approx([-0.005] * 19)        # kept as gym_torcs scales it
    assert obs[24:28] == pytest.approx([0.5, 0.51, 0.52, 0.53])   # wheelSpinVel / 100
    assert obs[28] == pytest.approx(0.5)                    # rpm / 10000


def test_in_traffic_opponents_scaled_and_clipped():
    opp = [200.0] * 36
    opp[18], opp[3] = 20.0, 240.0                           # 240: a noisy reading above range
    obs = ObservationBuilder("SingleAgentInTrafficObs")(scr_row(opponents=opp))
    assert obs[24 + 18] == pytest.approx(0.1) and obs[24 + 3] == 1.0 and obs[24] == 1.0


def test_every_observation_lies_in_its_box_even_with_extreme_readings():
    rng = np.random.default_rng(3)
    for mode in ("TorcsObs", "SingleAgentSimpleLapObs", "SingleAgentInTrafficObs"):
        b = ObservationBuilder(mode)
        for _ in range(50):
            row = scr_row(angle=rng.uniform(-math.pi, math.pi),
                          track=list(rng.uniform(-1, 260, 19)), opponents=list(rng.uniform(0, 260, 36)),
                          trackPos=rng.uniform(-3, 3), speedX=rng.uniform(-50, 350),
                          rpm=rng.uniform(0, 12000))
            assert b.space.contains(b(row))


def test_fields_mode_takes_listed_fields_in_order():
    b = ObservationBuilder("Fields", ["speedX", "focus", "gear", "angle"])
    assert b.size == 1 + 5 + 1 + 1
    obs = b(scr_row(focus=[40.0, 60.0, -1.0, 0.0, 200.0]))
    assert obs == pytest.approx([2.0, 0.2, 0.3, -0.005, 0.0, 1.0, 3.0, 0.25], abs=1e-7)


def test_normalisation_maps_nominal_ranges_to_unit_box():
    b = ObservationBuilder("SingleAgentSimpleLapObs", normalise=True)
    assert (b.space.low == -1).all() and (b.space.high == 1).all()
    obs = b(scr_row(angle=math.pi / 2, track=[100.0] * 19, trackPos=0.5, speedX=100.0,
                    speedY=0.0, speedZ=300.0))
    # angle over [-pi, pi]; track over [0, 200] m; trackPos over [-1, 1];
    # speedX over [-100, 300] km/h -> 0.0; speedY over +-100 -> 0; speedZ beyond range -> 1
    assert obs == pytest.approx([0.5] + [0.0] * 19 + [0.5, 0.0, 0.0, 1.0], abs=1e-6)


def test_obs_min_max_override_in_raw_units():
    b = ObservationBuilder("SingleAgentSimpleLapObs", normalise=True,
                           obs_min={"angle": -math.pi / 2}, obs_max={"angle": math.pi / 2})
    assert b(scr_row(angle=math.pi / 4))[0] == pytest.approx(0.5, abs=1e-6)


def test_from_frame_equals_row_path():
    rows = [scr_row(), scr_row(angle=-0.3, speedX=42.0, trackPos=-0.7)]
    flat = np.array([np.concatenate([np.atleast_1d(np.asarray(row[n], float)) for n in SENSOR_ORDER])
                     for row in rows])
    frame = SensorFrame.from_flat(flat, np.arange(2))
    b = ObservationBuilder("SingleAgentInTrafficObs")
    for k in range(2):
        np.testing.assert_array_equal(b.from_frame(frame, k), b(frame.row(k)))
        np.testing.assert_array_equal(b(frame.row(k)), b(rows[k]))


def test_bad_modes_are_refused():
    with pytest.raises(ValueError, match="unknown observation mode"):
        ObservationBuilder("Pixels")
    with pytest.raises(ValueError, match="non-empty"):
        ObservationBuilder("Fields")
    with pytest.raises(ValueError, match="unknown SCR field"):
        ObservationBuilder("Fields", ["speed"])


@pytest.mark.parametrize("mode, normalise", [("TorcsObs", False), ("SingleAgentInTrafficObs", True),
                                             ("SingleAgentSimpleLapObs", False)])
def test_observe_rows_gives_from_wires_bits_for_many_rows(mode, normalise):
    """make_vec's compiled observation of many rows = from_wire row by row, to the bit, on
    values at and beyond the bounds, signed zeros, infinities and NaN (np.clip's rules)."""
    b = ObservationBuilder(mode, normalise=normalise)
    rng = np.random.default_rng(3)
    special = np.array([0.0, -0.0, 1.0, -1.0, 200.0, -200.0, math.pi, -math.pi, np.inf, -np.inf,
                        np.nan, 1e300, 0.5, -0.005])
    flat = rng.normal(0.0, 150.0, (64, N_VALUES))
    flat[::2] = rng.choice(special, size=flat[::2].shape)
    rows = rng.permutation(64)[:40]
    out_rows = rng.permutation(50)[:40]
    out = np.full((50, b.size), 7.0, dtype=np.float32)
    b.observe_rows(flat, rows, out, out_rows)
    with np.errstate(invalid="ignore", over="ignore"):     # inf * 0, 1e300 in float32
        want = np.stack([b.from_wire(flat[r]) for r in rows])
    assert out[out_rows].view(np.int32).tolist() == want.view(np.int32).tolist()
    untouched = np.setdiff1d(np.arange(50), out_rows)
    assert (out[untouched] == 7.0).all()
