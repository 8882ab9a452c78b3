"""Fixtures for track tests."""

from __future__ import annotations

import pytest
from trackfiles import torcs_installed


@pytest.fixture
def need_torcs():
    if not torcs_installed():
        pytest.skip("TORCS data not installed: apt-get install torcs-data")


@pytest.fixture
def write_track(tmp_path):
    """Write XML text as <tmp>/<name>/<name>.xml and return the path."""
    def _write(text: str, name: str = "t"):
        d = tmp_path / name
        d.mkdir(exist_ok=True)
        p = d / f"{name}.xml"
        p.write_text(text, encoding="utf-8")
        return p
    return _write
