"""The README's runnable snippets run as written (issue 5: gymnasium and PettingZoo examples)."""

import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(), re.S)
RUNNABLE = [b for b in BLOCKS if "gymnasium.make" in b or "MadrasParallelEnv" in b]


def test_readme_has_the_two_env_examples():
    assert len(RUNNABLE) >= 2
    assert all(len(b.strip().splitlines()) <= 14 for b in RUNNABLE)

# The snippets themselves run in tests/test_commands_as_written.py (all README python blocks).
