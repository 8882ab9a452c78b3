"""Observation vectors of MADRaS (spec madras-features.md section 5) and an explicit-field mode.

Every value is first scaled as gym_torcs does (section 5.1): angle / pi, track, opponents and
focus / 200, speeds (km/h) / 50, rpm / 10000, everything else as sent. Modes:

| mode                     | size | vector, in order                                            |
|--------------------------|------|-------------------------------------------------------------|
| TorcsObs                 | 29   | angle, track[19], trackPos, speedX/Y/Z, wheelSpinVel[4]/100, rpm |
| SingleAgentSimpleLapObs  | 24   | angle, track[19] (negatives -> 0), trackPos, speedX/Y/Z     |
| SingleAgentInTrafficObs  | 60   | SimpleLap's 24, opponents[36]                               |
| Fields                   | any  | the listed SCR fields, each scaled as above                 |

Every vector is clipped into its Box (the bounds are physical: angle within [-1, 1], ranges
within [0, 1] (track keeps its -1 "off the road" reading as -0.005 in TorcsObs and Fields),
infinite where nothing bounds the value), so noisy readings stay inside the space.
With `normalise`, each entry is mapped linearly from a nominal range onto [-1, 1] and clipped;
ranges are given in raw SCR units (NOMINAL_RANGES, overridable per field by obs_min / obs_max,
as MADRaS's configs write them: angle +-3.142 rad, track 0-200 m, trackPos +-1).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import gymnasium
import numpy as np

from madsim.agents.learner_kernel import observe_rows
from madsim.physics.sensors import N_VALUES, SENSOR_OFFSETS, SENSOR_WIDTHS

_ROW0 = np.zeros(1, dtype=np.int64)

__all__ = [
    "FIELD_BOUNDS",
    "FIELD_SCALE",
    "FIELD_WIDTH",
    "NOMINAL_RANGES",
    "OBSERVATION_MODES",
    "SCR_FIELDS",
    "ObservationBuilder",
    "mode_fields",
]

# name -> number of values (one car's row), from the sensor layer
FIELD_WIDTH = dict(SENSOR_WIDTHS)
SCR_FIELDS = tuple(FIELD_WIDTH)

# gym_torcs's scaling of the raw SCR values (spec 5.1); fields not listed are used as sent
FIELD_SCALE = {"angle": 1.0 / math.pi, "track": 1.0 / 200.0, "opponents": 1.0 / 200.0,
               "focus": 1.0 / 200.0, "speedX": 1.0 / 50.0, "speedY": 1.0 / 50.0,
               "speedZ": 1.0 / 50.0, "rpm": 1.0 / 10000.0}

_INF = math.inf
# Bounds of the scaled values (what an observation may contain)
FIELD_BOUNDS = {"angle": (-1.0, 1.0), "track": (-1.0 / 200.0, 1.0), "opponents": (0.0, 1.0),
                "focus": (-1.0 / 200.0, 1.0), "rpm": (0.0, _INF), "damage": (0.0, _INF),
                "distFromStart": (0.0, _INF), "fuel": (0.0, _INF), "lastLapTime": (0.0, _INF),
                "racePos": (1.0, _INF), "gear": (-1.0, 10.0)}

# Nominal raw-SCR-unit ranges used by `normalise`
NOMINAL_RANGES = {"angle": (-math.pi, math.pi), "track": (0.0, 200.0), "opponents": (0.0, 200.0),
                  "focus": (0.0, 200.0), "trackPos": (-1.0, 1.0), "speedX": (-100.0, 300.0),
                  "speedY": (-100.0, 100.0), "speedZ": (-100.0, 100.0),
                  "wheelSpinVel": (-50.0, 300.0), "rpm": (0.0, 10000.0), "damage": (0.0, 10000.0),
                  "distFromStart": (0.0, 10000.0), "distRaced": (0.0, 25000.0),
                  "fuel": (0.0, 100.0), "gear": (-1.0, 7.0), "racePos": (1.0, 64.0),
                  "curLapTime": (0.0, 600.0), "lastLapTime": (0.0, 600.0), "z": (-20.0, 20.0)}

_SIMPLE_LAP = (("angle", None), ("track", (0.0, 1.0)), ("trackPos", None), ("speedX", None),
               ("speedY", None), ("speedZ", None))
# mode -> ((field, bounds override or None, extra scale), ...)
_MODES = {
    "TorcsObs": (("angle", None, 1.0), ("track", None, 1.0), ("trackPos", None, 1.0),
                 ("speedX", None, 1.0), ("speedY", None, 1.0), ("speedZ", None, 1.0),
                 ("wheelSpinVel", None, 0.01), ("rpm", None, 1.0)),
    "SingleAgentSimpleLapObs": tuple((f, b, 1.0) for f, b in _SIMPLE_LAP),
    "SingleAgentInTrafficObs": tuple((f, b, 1.0) for f, b in _SIMPLE_LAP)
    + (("opponents", None, 1.0),),
}
OBSERVATION_MODES = tuple(_MODES) + ("Fields", "Image")


def mode_fields(mode: str, fields: Sequence[str] = ()) -> tuple[str, ...]:
    """The SCR fields a mode reads, in order."""
    if mode == "Fields":
        return tuple(fields)
    return tuple(f for f, _, _ in _MODES[mode])


class ObservationBuilder:
    """One agent's observation: `space` (gymnasium Box, float32) and a call row -> vector.

    mode: one of OBSERVATION_MODES; fields: the SCR field names for mode "Fields";
    normalise: map onto [-1, 1]; obs_min / obs_max: per-field raw-unit range overrides.
    `builder(row)` takes one car's row (mapping SCR name -> number or sequence);
    `builder.from_frame(frame, k)` reads car row k of a SensorFrame without building a dict,
    `builder.from_wire(values)` one car's wire-order values (frame.flat[k]).
    """

    def __init__(self, mode: str = "SingleAgentSimpleLapObs", fields: Sequence[str] = (), *,
                 normalise: bool = False, obs_min: Mapping[str, float] | None = None,
                 obs_max: Mapping[str, float] | None = None):
        if mode == "Image":
            raise ValueError("mode 'Image' is built by ObservationBuilder.from_config "
                             "(madsim.agents.image_obs.ImageObservationBuilder)")
        if mode not in OBSERVATION_MODES:
            raise ValueError(f"unknown observation mode {mode!r}; one of {OBSERVATION_MODES}")
        if mode == "Fields":
            if not fields:
                raise ValueError("mode 'Fields' needs a non-empty list of fields")
            unknown = [f for f in fields if f not in FIELD_WIDTH]
            if unknown:
                raise ValueError(f"unknown SCR field(s) {unknown}; known: {SCR_FIELDS}")
            layout = tuple((f, None, 1.0) for f in fields)
        else:
            layout = _MODES[mode]
        self.mode = mode
        self.normalise = bool(normalise)
        self.slices: list[tuple[str, slice]] = []
        scale, low, high, nlo, nhi = [], [], [], [], []
        start = 0
        obs_min, obs_max = dict(obs_min or {}), dict(obs_max or {})
        for name, bounds, extra in layout:
            width = FIELD_WIDTH[name]
            self.slices.append((name, slice(start, start + width)))
            start += width
            s = FIELD_SCALE.get(name, 1.0) * extra
            lo, hi = bounds or FIELD_BOUNDS.get(name, (-_INF, _INF))
            rlo, rhi = NOMINAL_RANGES[name]
            rlo, rhi = obs_min.get(name, rlo), obs_max.get(name, rhi)
            if not rlo < rhi:
                raise ValueError(f"normalisation range of {name!r} is empty: [{rlo}, {rhi}]")
            scale += [s] * width
            low += [lo] * width
            high += [hi] * width
            nlo += [rlo * s] * width
            nhi += [rhi * s] * width
        self.size = start
        self.fields = tuple(name for name, _ in self.slices)
        self._scale = np.array(scale)
        self._low = np.array(low)
        self._high = np.array(high)
        nlo, nhi = np.array(nlo), np.array(nhi)
        self._gain = 2.0 / (nhi - nlo)
        self._offset = -1.0 - nlo * self._gain
        self._row = np.zeros(1, dtype=np.int64)     # from_frame's row, one compiled call
        self._wire_index = np.concatenate(        # positions in a SensorFrame's wire-order row
            [np.arange(SENSOR_OFFSETS[n][0], SENSOR_OFFSETS[n][0] + FIELD_WIDTH[n])
             for n, _ in self.slices])
        if self.normalise:
            self.space = gymnasium.spaces.Box(-1.0, 1.0, shape=(self.size,), dtype=np.float32)
        else:
            self.space = gymnasium.spaces.Box(self._low.astype(np.float32),
                                              self._high.astype(np.float32), dtype=np.float32)

    @classmethod
    def from_config(cls, obs) -> ObservationBuilder:
        """From a config's ObservationConfig."""
        if obs.mode == "Image":
            from madsim.agents.image_obs import ImageObservationBuilder

            return ImageObservationBuilder(obs.image_size, obs.image_metres)
        return cls(obs.mode, obs.fields, normalise=obs.normalised, obs_min=obs.obs_min,
                   obs_max=obs.obs_max)

    def __call__(self, row: Mapping) -> np.ndarray:
        """Observation (size,) float32 from one car's SCR row."""
        wire = np.zeros(N_VALUES)
        for name, sl in self.slices:
            o = SENSOR_OFFSETS[name][0]
            wire[o:o + sl.stop - sl.start] = row[name]
        return self.from_wire(wire)

    def from_frame(self, frame, k: int) -> np.ndarray:
        """Observation of car row k of a SensorFrame (same result as `self(frame.row(k))`)."""
        out = np.empty((1, self.size), dtype=np.float32)
        self._row[0] = k
        self.observe_rows(frame.flat, self._row, out, _ROW0)
        return out[0]

    def from_wire(self, values: np.ndarray) -> np.ndarray:
        """Observation from one car's 79 sensor values in wire order (a SensorFrame row)."""
        out = np.empty((1, self.size), dtype=np.float32)
        self.observe_rows(np.ascontiguousarray(values, dtype=np.float64)[None, :], _ROW0, out,
                          _ROW0)
        return out[0]

    def kernel_args(self) -> tuple:
        """`observe_rows`'s arrays: (wire_index, scale, low, high, gain, offset)."""
        return (self._wire_index, self._scale, self._low, self._high, self._gain, self._offset)

    def observe_rows(self, flat: np.ndarray, rows: np.ndarray, out: np.ndarray,
                     out_rows: np.ndarray) -> None:
        """out[out_rows[i]] = the observation of wire-order sensor row flat[rows[i]] (one
        compiled call, `learner_kernel.observe_rows`: the values at their wire positions,
        scaled, clipped into the bounds, normalised). out: (>= max(out_rows) + 1, size)
        float32."""
        observe_rows(flat, rows, self._wire_index, self._scale, self._low, self._high,
                     self.normalise, self._gain, self._offset, out, out_rows)
