"""Where each car is, from its SCR sensors alone (behind the UDP backend there is no World)."""

from __future__ import annotations

import numpy as np

from madsim.raster import kernels
from madsim.tracks import Track

__all__ = ["poses_from_sensors"]


def poses_from_sensors(track: Track, frame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World x, y (m) and yaw (rad) of every car of a SensorFrame: the track point
    (distFromStart, trackPos * width / 2) and yaw = track tangent - angle (SCR's angle)."""
    s = np.ascontiguousarray(frame.distFromStart, dtype=np.float64)
    n = np.ascontiguousarray(frame.trackPos, dtype=np.float64) * (track.width / 2)
    x, y, heading = np.empty_like(s), np.empty_like(s), np.empty_like(s)
    kernels.track_poses(track.geo, track.length, s, n, x, y, heading)
    return x, y, heading - np.asarray(frame.angle, dtype=np.float64)
