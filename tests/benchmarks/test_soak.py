"""The cheap version of benchmarks/soak.py (issue 14): 20,000 ticks through MadrasEnv with random
actions and resets, traffic on: no NaN or inf in any observation or World state, and resident
memory flat (one track and a fixed traffic count here, so the one World is built before the
first reading; the full run, 10 million ticks over three tracks, is in benchmarks/RESULTS.md)."""

import importlib.util
from pathlib import Path

SOAK = Path(__file__).resolve().parents[2] / "benchmarks" / "soak.py"


def test_soak_20k_ticks_finite_and_flat_memory():
    spec = importlib.util.spec_from_file_location("madsim_soak", SOAK)
    soak = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(soak)
    config = {**soak.CONFIG, "server": {**soak.CONFIG["server"], "tracks": ["madsim-road"], "traffic_count": [4, 4]}}
    r = soak.soak(20_000, 4_000, seed=1, log=lambda *a, **k: None, config=config)
    assert r["ticks"] >= 20_000 and r["episodes"] >= 5       # resets happened
    assert r["nonfinite"] == 0
    assert r["growth_mb"] < soak.GROWTH_LIMIT_MB, r["rss_mb"]
