"""`SensorRow`: one car's SCR sensors by name, read from its wire-order values."""

from __future__ import annotations

from collections.abc import Mapping

from madsim.physics.sensors import INT_FIELDS, SENSOR_OFFSETS

__all__ = ["SensorRow"]

_FIELDS = {name: (o, w, name in INT_FIELDS) for name, (o, w) in SENSOR_OFFSETS.items()}


class SensorRow(Mapping):
    """One car's SCR sensors by name, read from its wire-order values (a (79,) array or a list)
    without building a dict: scalars as float (damage, gear, racePos as int), arrays as lists;
    the same values as `SensorFrame.row(k)`. What user rewards, dones and traffic targets get."""

    __slots__ = ("values",)

    def __init__(self, values):
        self.values = values

    def __getitem__(self, name: str):
        o, w, is_int = _FIELDS[name]
        if w == 1:
            v = float(self.values[o])
            return int(v) if is_int else v
        return [float(x) for x in self.values[o:o + w]]

    def get(self, name: str, default=None):
        return self[name] if name in _FIELDS else default

    def __contains__(self, name) -> bool:
        return name in _FIELDS

    def __iter__(self):
        return iter(_FIELDS)

    def __len__(self) -> int:
        return len(_FIELDS)
