"""The README's runnable snippets run as written (issue 5: gymnasium and PettingZoo examples)."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)
RUNNABLE = [b for b in BLOCKS if "gymnasium.make" in b or "MadrasParallelEnv" in b]


def test_readme_has_the_two_env_examples():
    assert len(RUNNABLE) >= 2
    assert all(len(b.strip().splitlines()) <= 14 for b in RUNNABLE)


@pytest.mark.parametrize("snippet", RUNNABLE, ids=["gymnasium", "pettingzoo"][: len(RUNNABLE)])
def test_readme_snippet_runs(snippet, tmp_path):
    proc = subprocess.run([sys.executable, "-c", snippet], capture_output=True, text=True, timeout=300,
                          cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
