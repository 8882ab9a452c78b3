"""The layering rule of ARCHITECTURE.md for pictures: `render` draws what it is handed and
imports neither envs, agents nor train; agents and envs never import render (image
observations draw with `madsim.raster`, which imports none of them either). Every import
statement counts, including those inside functions."""

import ast
from pathlib import Path

import pytest

import madsim

PACKAGE = Path(madsim.__file__).parent


def madsim_imports(path: Path) -> set[str]:
    """The madsim modules a source file imports (absolute names, any nesting)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
            names.update(f"{node.module}.{a.name}" for a in node.names)
    return {n for n in names if n == "madsim" or n.startswith("madsim.")}


def offending(folder: str, banned: tuple[str, ...]) -> dict[str, list[str]]:
    found = {}
    for path in sorted((PACKAGE / folder).glob("*.py")):
        bad = sorted(n for n in madsim_imports(path)
                     if any(n == b or n.startswith(b + ".") for b in banned))
        if bad:
            found[path.name] = bad
    return found


@pytest.mark.parametrize("folder, banned", [
    ("render", ("madsim.envs", "madsim.agents", "madsim.train")),
    ("raster", ("madsim.envs", "madsim.agents", "madsim.train", "madsim.render")),
    ("agents", ("madsim.render", "madsim.envs", "madsim.train")),
    ("envs", ("madsim.train",)),
])
def test_layers_import_only_downwards(folder, banned):
    assert offending(folder, banned) == {}


def test_envs_reach_render_only_through_the_view_for_render_mode():
    used = {n for path in (PACKAGE / "envs").glob("*.py") for n in madsim_imports(path)
            if n.startswith("madsim.render")}
    assert used <= {"madsim.render.envview", "madsim.render.envview.EnvView",
                    "madsim.render.envview.ViewState"}, used


def test_the_rule_sees_imports_inside_functions(tmp_path):
    src = tmp_path / "m.py"
    src.write_text("def f():\n    from madsim.envs.backends import X\n    import madsim.train.sb3\n")
    assert madsim_imports(src) == {"madsim.envs.backends", "madsim.envs.backends.X",
                                   "madsim.train.sb3"}
