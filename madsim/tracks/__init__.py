"""Tracks: TORCS track XML -> immutable, sampled `Track` with vectorised queries."""

from madsim.tracks.build import Surface
from madsim.tracks.errors import TrackError
from madsim.tracks.library import (
    DEFAULT_TRACK,
    find_track,
    list_tracks,
    load_track,
    load_track_xml,
    torcs_data_dirs,
)
from madsim.tracks.track import Track

__all__ = [
    "DEFAULT_TRACK", "Surface", "Track", "TrackError", "find_track", "list_tracks", "load_track",
    "load_track_xml", "torcs_data_dirs",
]
