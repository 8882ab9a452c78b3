"""The generated references in docs/ match the code (regenerate: python -m madsim.docs write)."""

from pathlib import Path

import pytest

from madsim.docs import generate

DOCS = Path(__file__).resolve().parents[1] / "docs"


@pytest.mark.parametrize("name", ["configuration.md", "sensors.md", "cli.md"])
def test_reference_is_up_to_date(name):
    generated = generate()[name]
    assert (DOCS / name).read_text(encoding="utf-8") == generated, \
        f"docs/{name} is stale: run `python -m madsim.docs write`"


def test_references_cover_the_schema_and_the_commands():
    docs = generate()
    from madsim.envs import config as C
    for cls in (C.EpisodeConfig, C.AgentConfig, C.TrafficConfig):
        for f in cls.__dataclass_fields__:
            assert f"`{f}`" in docs["configuration.md"], f
    for command in ("madsim tracks list", "madsim serve", "madsim config check", "madsim convert track"):
        assert f"## `{command}`" in docs["cli.md"]
    assert "| `track` | 19 |" in docs["sensors.md"]


def test_howto_examples_register_and_run_in_an_env(tmp_path):
    """docs/howto.md's reward and done examples work in a real env (run in a fresh process so
    the registrations do not leak into other tests)."""
    import re
    import subprocess
    import sys

    blocks = re.findall(r"```python\n(.*?)```", (DOCS / "howto.md").read_text(), re.S)
    assert len(blocks) == 2
    code = "\n".join(blocks) + """
from madsim.envs import MadrasEnv
cfg = {"server": {"max_steps": 30}, "agents": [{"name": "d", "rewards": {"Progress2": {"scale": 1.0},
       "StayCentred": {"scale": 0.2, "tolerance": 0.3}}, "dones": ["TimeOut", "TooSlow"]}]}
env = MadrasEnv(cfg)
env.reset(seed=0)
for _ in range(30):
    _, _, terminated, truncated, info = env.step(env.action_space.sample())
    if terminated or truncated:
        break
assert set(info["reward_terms"]) == {"Progress2", "StayCentred"}, info["reward_terms"]
assert info["reward_terms"]["StayCentred"] >= 0
print("done", info["dones"])
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                          cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "TimeOut" in proc.stdout
