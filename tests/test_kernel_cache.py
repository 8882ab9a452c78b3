"""numba's disk cache of madsim kernels follows edits of every kernel module, not only the
function's own file (a kernel compiles the kernels it calls from other modules into itself)."""

from __future__ import annotations

import shutil

from madsim import kernel_cache as KC
from madsim.physics.contact_kernels import advance_until_near
from madsim.physics.sensors import sensor_kernel


def test_madsim_kernels_are_stamped_with_every_kernel_module():
    for kernel in (advance_until_near, sensor_kernel):
        locator = kernel._cache._impl.locator
        assert getattr(type(locator), "madsim_kernels", False), type(locator)
        own, shared = locator.get_source_stamp()
        assert shared == KC.kernel_sources_digest()


def test_an_edit_of_a_called_kernel_module_changes_the_stamp(tmp_path):
    # the contact loop (contact_kernels.py) compiles physics/kernel.py's advance_car into itself
    package = tmp_path / "madsim"
    for rel in ("physics/kernel.py", "physics/contact_kernels.py", "cli.py"):
        (package / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(KC.PACKAGE_DIR / rel, package / rel)
    before = KC.sources_digest(package)
    with open(package / "cli.py", "a") as f:            # no numba there: no recompile
        f.write("\n# a comment\n")
    assert KC.sources_digest(package) == before
    with open(package / "physics" / "kernel.py", "a") as f:
        f.write("\n# a changed physics kernel\n")
    assert KC.sources_digest(package) != before


def test_functions_outside_madsim_keep_numbas_locators(tmp_path):
    from numba.core import caching

    ours = [c for c in caching.CacheImpl._locator_classes if getattr(c, "madsim_kernels", False)]
    assert len(ours) == 3
    outside = tmp_path / "user_module.py"
    outside.write_text("def f():\n    return 1\n")
    assert all(c.from_function(lambda: 1, str(outside)) is None for c in ours)
    KC.install()                                        # idempotent
    assert len([c for c in caching.CacheImpl._locator_classes
                if getattr(c, "madsim_kernels", False)]) == 3


def test_kernels_load_without_numbas_registries_and_compiling_still_loads_them():
    # start-up (issue 13): a madsim kernel loaded from the disk cache sets up only what its code
    # calls; the first compile in the process loads numba's registries, with the BLAS probe
    # looking for scipy's module instead of importing scipy.linalg (~0.25 s here), same answer
    import subprocess
    import sys

    code = """
import sys, numba, numpy as np
from madsim.tracks import load_track
track = load_track("madsim-oval")
x, y, _, _ = track.pose(np.array([100.0]), np.array([1.5]))
before = track.locate(x, y)                      # a cached kernel, loaded light
light = "numba.np.arraymath" not in sys.modules

@numba.njit
def twice(v):
    return 2.0 * v

compiled = twice(1.5) == 3.0                     # a compile: every registry loads now
from numba.np import arraymath, linalg
from madsim.kernel_cache import scipy_blas_present
after = track.locate(x, y)
print(light, compiled, "scipy.linalg" in sys.modules, arraymath._HAVE_BLAS == scipy_blas_present(),
      arraymath.ensure_blas is linalg.ensure_blas,
      all(np.array_equal(a, b) for a, b in zip(before, after)), abs(before[0][0] - 100.0) < 1e-6)
"""
    for _ in range(2):        # the first run compiles what a cold disk cache lacks
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                             check=True, timeout=600).stdout.split()
    light, compiled, linalg_imported, same_blas_answer, restored, same, right = out
    assert light == "True"
    assert compiled == "True"
    assert linalg_imported == "False"
    assert same_blas_answer == "True"
    assert restored == "True"
    assert same == "True" and right == "True"


def test_blas_calls_in_jitted_code_still_work():
    import numba
    import numpy as np
    import pytest

    if not KC.scipy_blas_present():
        pytest.skip("no scipy: numba has no BLAS to call")

    @numba.njit
    def dot(a, b):
        return np.dot(a, b)

    a = np.arange(6.0).reshape(2, 3)
    b = np.arange(12.0).reshape(3, 4)
    assert np.array_equal(dot(a, b), a @ b)   # small integers: exact in any summation order
