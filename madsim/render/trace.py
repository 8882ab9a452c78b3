"""Reading `madsim serve --log-csv` traces (one row per car per tick, `net.server.CSV_FIELDS`).

`read_trace(path)` returns a `Trace`: every column as a (T, N) array, tick-major, with the
countdown ticks (negative tick numbers) left out unless asked for. A file that is not such a
trace raises `TraceError` naming the file, the line and the column.
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass

import numpy as np

REQUIRED = ("tick", "time", "car", "x", "y", "yaw", "distFromStart", "trackPos", "speedX",
            "rpm", "gear", "laps", "curLapTime")


class TraceError(ValueError):
    """A trace file that cannot be read; the message names file, line and column."""


@dataclass(frozen=True)
class Trace:
    """A trace: `columns[name]` (T, N) float64 for every CSV column (T ticks, N cars)."""

    path: str
    columns: dict

    @property
    def n_ticks(self) -> int:
        return int(self.columns["tick"].shape[0])

    @property
    def n_cars(self) -> int:
        return int(self.columns["tick"].shape[1])

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.columns[name]
        except KeyError:
            raise KeyError(f"{self.path}: no column {name!r}; columns: {', '.join(self.columns)}") from None

    def race_positions(self, track_length: float) -> np.ndarray:
        """(T, N) race positions (1 = leading) from laps and distFromStart (the trace does
        not record them): distance = (laps - 1) L + s, as the grid starts behind the line."""
        dist = (self["laps"] - 1.0) * track_length + self["distFromStart"]
        order = np.argsort(-dist, axis=1, kind="stable")
        pos = np.empty_like(order)
        rows = np.arange(dist.shape[0])[:, None]
        pos[rows, order] = np.arange(1, dist.shape[1] + 1)
        return pos


def read_trace(path: str | os.PathLike, *, countdown: bool = False) -> Trace:
    """Read a serve trace (see the module docstring); countdown: keep the ticks before the start."""
    path = os.fspath(path)
    try:
        with open(path, newline="", encoding="utf-8") as f:
            return _parse(path, csv.reader(f), countdown)
    except OSError as exc:
        raise TraceError(f"{path}: cannot read the trace: {exc.strerror}") from None


def _parse(path: str, reader, countdown: bool) -> Trace:
    """The Trace of a csv reader positioned at the header (see read_trace)."""
    header = next(reader, None)
    if header is None:
        raise TraceError(f"{path}: empty file, not a madsim serve --log-csv trace")
    header = [h.strip() for h in header]
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise TraceError(f"{path}: line 1: missing column(s) {', '.join(missing)} "
                         "(is this a madsim serve --log-csv trace?)")
    rows = []
    for line, rec in enumerate(reader, start=2):
        if not rec:
            continue
        if len(rec) != len(header):
            raise TraceError(f"{path}: line {line}: {len(rec)} values, the header has {len(header)}")
        vals = []
        for name, text in zip(header, rec):
            try:
                v = float(text)
            except ValueError:
                raise TraceError(f"{path}: line {line}: column {name!r} is not a number: {text!r}") from None
            if not math.isfinite(v):
                raise TraceError(f"{path}: line {line}: column {name!r} is not finite: {text!r}")
            vals.append(v)
        rows.append(vals)
    if not rows:
        raise TraceError(f"{path}: the trace has a header but no rows")
    data = np.array(rows)
    col = {name: i for i, name in enumerate(header)}
    car = data[:, col["car"]].astype(np.int64)
    n = int(car.max()) + 1
    # a tick lists cars 0..n-1 in order, tick after tick
    bad = np.flatnonzero(car != np.resize(np.arange(n), car.shape))
    if bad.size or car.shape[0] % n:
        line = int(bad[0]) + 2 if bad.size else car.shape[0] + 1
        raise TraceError(f"{path}: line {line}: every tick must list cars 0..{n - 1} in order")
    cube = data.reshape(car.shape[0] // n, n, len(header))
    if not countdown:
        cube = cube[cube[:, 0, col["tick"]] >= 0]
        if cube.shape[0] == 0:
            raise TraceError(f"{path}: the trace holds only countdown ticks")
    return Trace(path, {name: np.ascontiguousarray(cube[:, :, i]) for name, i in col.items()})


def check_track(trace: Trace, track, *, tolerance_m: float = 2.0) -> None:
    """TraceError unless the trace's positions lie on `track` where its trackPos says
    (median lateral mismatch over a sample of rows below tolerance_m)."""
    x, y = trace["x"].ravel(), trace["y"].ravel()
    n_rec = trace["trackPos"].ravel() * track.width / 2
    pick = np.linspace(0, x.shape[0] - 1, min(200, x.shape[0])).astype(np.int64)
    _, n = track.locate(x[pick], y[pick])
    err = float(np.median(np.abs(n - n_rec[pick])))
    if not err < tolerance_m:
        raise TraceError(f"{trace.path}: the cars are not where trackPos puts them on track "
                         f"{track.name!r} (median mismatch {err:.1f} m): give the track the "
                         "trace was recorded on (--track)")
