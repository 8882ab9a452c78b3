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
