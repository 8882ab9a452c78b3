"""Loading a script of benchmarks/ as a module, for the tests of its pure parts."""

import importlib.util
import sys
from pathlib import Path

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"


def load_script(name: str):
    """benchmarks/<name>.py as a module (its fidelity.py import left in sys.modules until
    `unload` is called)."""
    spec = importlib.util.spec_from_file_location(f"madsim_{name}", BENCHMARKS / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod          # a dataclass of the script looks its module up there
    spec.loader.exec_module(mod)
    return mod


def unload() -> None:
    """Forget the scripts' fidelity.py and slide_window imports (each test module loads afresh)."""
    for name in ("madsim_fidelity_bench", "slide_window"):
        sys.modules.pop(name, None)
    for name in [n for n in sys.modules if n.startswith("madsim_") and n != "madsim_fidelity_bench"]:
        sys.modules.pop(name, None)
